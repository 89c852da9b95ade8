//! The Gauss-Newton normal equations `J^T J + D` of the inverse solve on a pattern fixed by the
//! mesh's connectivity: `J = dr/dX` in 3x3 vertex blocks (the one-ring, and with the wall's
//! bending hinges the two corners opposite each hinge's edge, which no triangle couples),
//! `J^T J` in vertex blocks (the two-ring) and its scalar CSR form for the sparse Cholesky, all laid out once so
//! that every iteration only rewrites values and the factorisation's symbolic analysis is
//! reused (`docs/design.md`, Speed).

use balloon_linalg::CsrMatrix;
use nalgebra::{Matrix3, SMatrix, Vector3};

/// The block layouts of `J` and `J^T J` of one mesh.
pub(crate) struct NormalPattern {
    /// Vertices.
    nv: usize,
    /// Block-row pointers of `J` (row block `v`, column blocks the one-ring of `v` and `v`).
    j_ptr: Vec<usize>,
    /// Column block of each block of `J`.
    j_col: Vec<usize>,
    /// Per triangle, the slot in `J` of its corner pair `(a, b)` at `3 a + b`.
    element_slots: Vec<[usize; 9]>,
    /// Per bending hinge, the slot in `J` of its corner pair `(a, b)` at `4 a + b`.
    hinge_slots: Vec<[usize; 16]>,
    /// Block-row pointers of `J^T J`.
    a_ptr: Vec<usize>,
    /// Column block of each block of `J^T J`.
    a_col: Vec<usize>,
    /// Slot in `J^T J` of each vertex's diagonal block.
    a_diag: Vec<usize>,
    /// The products of `J^T J = sum_v J_va^T J_vb`: `(slot of J_va, slot of J_vb, slot of A_ab)`.
    products: Vec<[u32; 3]>,
    /// The scalar CSR layout of `J^T J` (values rewritten by [`NormalPattern::write_csr`]).
    csr: CsrMatrix,
}

/// Position of `c` in the sorted slice `cols` (which holds it).
fn find(cols: &[usize], c: usize) -> usize {
    cols.binary_search(&c)
        .expect("the pattern holds every coupled block")
}

impl NormalPattern {
    /// The layout for `nv` vertices and the triangles `triangles`, with the bending hinges of
    /// corners `hinges` (`[x0, x1, x2, x3]`, edge `x0 x1`; none without the wall's bending
    /// stiffness): each couples its opposite corners `x2` and `x3`, which the one-ring does not.
    pub(crate) fn new(nv: usize, triangles: &[[usize; 3]], hinges: &[[usize; 4]]) -> Self {
        // One-rings (with the vertex itself) and the hinges' opposite corners, sorted.
        let mut ring: Vec<Vec<usize>> = (0..nv).map(|v| vec![v]).collect();
        for t in triangles {
            for &a in t {
                ring[a].extend_from_slice(t);
            }
        }
        for c in hinges {
            for &a in c {
                ring[a].extend_from_slice(c);
            }
        }
        for r in &mut ring {
            r.sort_unstable();
            r.dedup();
        }
        let mut j_ptr = Vec::with_capacity(nv + 1);
        let mut j_col = Vec::new();
        j_ptr.push(0);
        for r in &ring {
            j_col.extend_from_slice(r);
            j_ptr.push(j_col.len());
        }
        let j_row = |v: usize| &j_col[j_ptr[v]..j_ptr[v + 1]];
        let element_slots = triangles
            .iter()
            .map(|t| {
                std::array::from_fn(|ab| {
                    let (a, b) = (t[ab / 3], t[ab % 3]);
                    j_ptr[a] + find(j_row(a), b)
                })
            })
            .collect();
        let hinge_slots = hinges
            .iter()
            .map(|c| {
                std::array::from_fn(|ab| {
                    let (a, b) = (c[ab / 4], c[ab % 4]);
                    j_ptr[a] + find(j_row(a), b)
                })
            })
            .collect();
        // J^T J couples a and b when both lie in the one-ring of some vertex v: row a is the
        // union of the rings of a's ring (the two-ring).
        let mut a_ptr = Vec::with_capacity(nv + 1);
        let mut a_col = Vec::new();
        let mut a_diag = Vec::with_capacity(nv);
        a_ptr.push(0);
        let mut row = Vec::new();
        for a in 0..nv {
            row.clear();
            for &v in &ring[a] {
                row.extend_from_slice(&ring[v]);
            }
            row.sort_unstable();
            row.dedup();
            a_diag.push(a_col.len() + find(&row, a));
            a_col.extend_from_slice(&row);
            a_ptr.push(a_col.len());
        }
        let a_row = |a: usize| &a_col[a_ptr[a]..a_ptr[a + 1]];
        let mut products = Vec::new();
        for v in 0..nv {
            for (ia, &a) in j_row(v).iter().enumerate() {
                for (ib, &b) in j_row(v).iter().enumerate() {
                    let slot = |s: usize| u32::try_from(s).expect("fewer than 2^32 blocks");
                    products.push([
                        slot(j_ptr[v] + ia),
                        slot(j_ptr[v] + ib),
                        slot(a_ptr[a] + find(a_row(a), b)),
                    ]);
                }
            }
        }
        // Scalar CSR: row 3a+k holds, block by block of row a, the columns 3b..3b+3.
        let n = 3 * nv;
        let mut row_ptr = Vec::with_capacity(n + 1);
        let mut col_idx = Vec::with_capacity(9 * a_col.len());
        row_ptr.push(0);
        for a in 0..nv {
            for _k in 0..3 {
                for &b in a_row(a) {
                    col_idx.extend([3 * b, 3 * b + 1, 3 * b + 2]);
                }
                row_ptr.push(col_idx.len());
            }
        }
        let values = vec![0.0; col_idx.len()];
        Self {
            nv,
            j_ptr,
            j_col,
            element_slots,
            hinge_slots,
            a_ptr,
            a_col,
            a_diag,
            products,
            csr: CsrMatrix {
                n,
                row_ptr,
                col_idx,
                values,
            },
        }
    }

    /// Vertices.
    pub(crate) fn vertices(&self) -> usize {
        self.nv
    }

    /// The column blocks of block row `v` of `J` (the one-ring of `v` and `v`, sorted).
    pub(crate) fn j_row(&self, v: usize) -> &[usize] {
        &self.j_col[self.j_ptr[v]..self.j_ptr[v + 1]]
    }

    /// The slot in `J` of block `(a, b)` (`b` in the one-ring of `a`).
    pub(crate) fn j_slot(&self, a: usize, b: usize) -> usize {
        self.j_ptr[a] + find(self.j_row(a), b)
    }

    /// Blocks of `J`.
    pub(crate) fn j_blocks(&self) -> usize {
        self.j_col.len()
    }

    /// Adds the rest Jacobian `jac` of triangle `e` (rows and columns `3 a + k` over its corners)
    /// into the blocks `j` of `J`.
    pub(crate) fn add_element(&self, e: usize, jac: &SMatrix<f64, 9, 9>, j: &mut [Matrix3<f64>]) {
        for (ab, &slot) in self.element_slots[e].iter().enumerate() {
            let (a, b) = (ab / 3, ab % 3);
            j[slot] += jac.fixed_view::<3, 3>(3 * a, 3 * b);
        }
    }

    /// Adds the rest Jacobian `jac` of bending hinge `k` (rows and columns `3 a + k` over its
    /// corners `[x0, x1, x2, x3]`) into the blocks `j` of `J`.
    pub(crate) fn add_hinge(&self, k: usize, jac: &SMatrix<f64, 12, 12>, j: &mut [Matrix3<f64>]) {
        for (ab, &slot) in self.hinge_slots[k].iter().enumerate() {
            let (a, b) = (ab / 4, ab % 4);
            j[slot] += jac.fixed_view::<3, 3>(3 * a, 3 * b);
        }
    }

    /// `J^T J` into `a` (one block per slot) and `J^T r` into `g`.
    pub(crate) fn normal(
        &self,
        j: &[Matrix3<f64>],
        r: &[f64],
        a: &mut Vec<Matrix3<f64>>,
        g: &mut [f64],
    ) {
        a.clear();
        a.resize(self.a_col.len(), Matrix3::zeros());
        for &[va, vb, ab] in &self.products {
            a[ab as usize] += j[va as usize].tr_mul(&j[vb as usize]);
        }
        self.transpose_apply(j, r, g);
    }

    /// `J x` into `out`, from the blocks `j` of `J`.
    pub(crate) fn apply(&self, j: &[Matrix3<f64>], x: &[f64], out: &mut [f64]) {
        for v in 0..self.nv {
            let mut s = Vector3::zeros();
            for k in self.j_ptr[v]..self.j_ptr[v + 1] {
                let c = self.j_col[k];
                s += j[k] * Vector3::new(x[3 * c], x[3 * c + 1], x[3 * c + 2]);
            }
            out[3 * v..3 * v + 3].copy_from_slice(s.as_slice());
        }
    }

    /// `J^T r` into `g`, from the blocks `j` of `J`.
    pub(crate) fn transpose_apply(&self, j: &[Matrix3<f64>], r: &[f64], g: &mut [f64]) {
        g.fill(0.0);
        for v in 0..self.nv {
            let rv = Vector3::new(r[3 * v], r[3 * v + 1], r[3 * v + 2]);
            for s in self.j_ptr[v]..self.j_ptr[v + 1] {
                let c = self.j_col[s];
                let ga = j[s].tr_mul(&rv);
                for k in 0..3 {
                    g[3 * c + k] += ga[k];
                }
            }
        }
    }

    /// The slot in `J^T J` of block `(a, b)` (`b` within two rings of `a`).
    pub(crate) fn a_slot(&self, a: usize, b: usize) -> usize {
        self.a_ptr[a] + find(&self.a_col[self.a_ptr[a]..self.a_ptr[a + 1]], b)
    }

    /// Sum of the diagonal of `J^T J` from its blocks `a`.
    pub(crate) fn trace(&self, a: &[Matrix3<f64>]) -> f64 {
        self.a_diag.iter().map(|&s| a[s].trace()).sum()
    }

    /// `J^T J + diag_v(D_v)` as the scalar CSR matrix (same layout every call), `D_v` the
    /// vertex blocks `diagonal(v)`.
    pub(crate) fn write_csr(
        &mut self,
        a: &[Matrix3<f64>],
        diagonal: impl Fn(usize) -> Matrix3<f64>,
    ) -> &CsrMatrix {
        let values = &mut self.csr.values;
        let mut p = 0;
        for v in 0..self.nv {
            let (lo, hi) = (self.a_ptr[v], self.a_ptr[v + 1]);
            let d = diagonal(v);
            for k in 0..3 {
                for s in lo..hi {
                    let mut block = a[s];
                    if s == self.a_diag[v] {
                        block += d;
                    }
                    values[p..p + 3].copy_from_slice(&[
                        block[(k, 0)],
                        block[(k, 1)],
                        block[(k, 2)],
                    ]);
                    p += 3;
                }
            }
        }
        &self.csr
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fixed-pattern `J^T J` and `J^T r` against dense products on a small closed mesh,
    /// with and without the bending hinges' blocks (which couple each hinge's opposite
    /// corners, outside the one-ring).
    #[test]
    fn normal_equations_match_dense_products() {
        let mesh = balloon_mesh::generate::icosphere(1.0, 1).unwrap();
        let hinges: Vec<[usize; 4]> = balloon_mesh::topology::hinges(&mesh.triangles)
            .iter()
            .map(|h| h.corners)
            .collect();
        assert!(!hinges.is_empty());
        check_normal_equations(&mesh, &[]);
        check_normal_equations(&mesh, &hinges);
    }

    fn check_normal_equations(mesh: &balloon_mesh::TriMesh, hinges: &[[usize; 4]]) {
        let nv = mesh.num_vertices();
        let mut pattern = NormalPattern::new(nv, &mesh.triangles, hinges);
        let n = 3 * nv;
        let mut dense = nalgebra::DMatrix::<f64>::zeros(n, n);
        let mut j = vec![Matrix3::zeros(); pattern.j_blocks()];
        for (e, t) in mesh.triangles.iter().enumerate() {
            let jac = SMatrix::<f64, 9, 9>::from_fn(|r, c| ((e * 81 + r * 9 + c) as f64).sin());
            pattern.add_element(e, &jac, &mut j);
            for r in 0..9 {
                for c in 0..9 {
                    dense[(3 * t[r / 3] + r % 3, 3 * t[c / 3] + c % 3)] += jac[(r, c)];
                }
            }
        }
        for (k, h) in hinges.iter().enumerate() {
            let jac = SMatrix::<f64, 12, 12>::from_fn(|r, c| ((k * 144 + r * 12 + c) as f64).cos());
            pattern.add_hinge(k, &jac, &mut j);
            for r in 0..12 {
                for c in 0..12 {
                    dense[(3 * h[r / 3] + r % 3, 3 * h[c / 3] + c % 3)] += jac[(r, c)];
                }
            }
        }
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
        let mut jx = vec![0.0; n];
        pattern.apply(&j, &x, &mut jx);
        let want = &dense * nalgebra::DVector::from_column_slice(&x);
        assert!(
            (nalgebra::DVector::from_column_slice(&jx) - want)
                .abs()
                .max()
                < 1e-9
        );
        let r: Vec<f64> = (0..n).map(|i| (i as f64).cos()).collect();
        let mut a = Vec::new();
        let mut g = vec![0.0; n];
        pattern.normal(&j, &r, &mut a, &mut g);
        let jtj = dense.transpose() * &dense;
        let jtr = dense.transpose() * nalgebra::DVector::from_column_slice(&r);
        assert!((pattern.trace(&a) - jtj.trace()).abs() < 1e-9 * jtj.trace().abs());
        let csr = pattern.write_csr(&a, |v| Matrix3::identity() * v as f64);
        csr.check().unwrap();
        let mut stored = nalgebra::DMatrix::<f64>::zeros(n, n);
        for row in 0..n {
            for k in csr.row_ptr[row]..csr.row_ptr[row + 1] {
                stored[(row, csr.col_idx[k])] = csr.values[k];
            }
        }
        let mut want = jtj;
        for i in 0..n {
            want[(i, i)] += (i / 3) as f64;
        }
        assert!((stored - want).abs().max() < 1e-9);
        assert!((nalgebra::DVector::from_column_slice(&g) - jtr).abs().max() < 1e-9);
    }
}
