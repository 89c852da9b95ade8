//! The square Newton system of the inverse solve: `J dX = -r` with a sparse LU factorisation of
//! `J` itself (the one-ring pattern), with six unknowns pinned and six equations dropped for the
//! rigid motions (`docs/design.md`, D10).
//!
//! `J` is singular in two ways that the pinning removes. Every elastic force field sums to
//! zero and has zero moment about the origin at the fixed target `x*` (the energy does not change
//! when `x*` moves rigidly), and so does the pressure load of a closed mesh: the rows of `J`
//! satisfy `L J = 0` with `L` the six rigid motions at `x*` (translations `e_k`, rotations
//! `e_k × x*_v`), and `r` stays in the range. For an isotropic wall the forces do not change
//! when the rest shape moves rigidly either: `J R = 0` with `R` the six rigid motions at `X`.
//! Pinning six unknowns that fix the rigid motions of `X` (their columns replaced by unit
//! columns) and dropping the same six equations (implied by the others through `L r = 0`)
//!
//! ```text
//! J_PD dX_P = -r_D,    dX at the pinned unknowns = 0                                 (D10)
//! ```
//!
//! leaves a square system on the one-ring pattern that is regular when `J` has no other null
//! directions; its solution is the Newton step that keeps the pinned unknowns.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use nalgebra::{Matrix3, Vector3};

use crate::normal::NormalPattern;

/// Where the value at each stored position of the Newton matrix comes from.
#[derive(Clone, Copy)]
enum Source {
    /// Entry `(k, l)` of block `slot` of `J`: `9 slot + 3 k + l`.
    J(u32),
    /// A pinned column's unit entry at its dropped row.
    Unit,
    /// A pinned column's other entries.
    Zero,
}

/// The pinned Newton matrix on a fixed pattern (the one-ring pattern of `J`), and its LU
/// factor.
pub(crate) struct PinnedLu {
    n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    sources: Vec<Source>,
    values: Vec<f64>,
    /// Slot in `J` of each vertex's diagonal block.
    diagonal: Vec<usize>,
    /// The six pinned unknowns (and dropped equations).
    pinned: [usize; 6],
    symbolic: Option<SymbolicLu<usize>>,
    lu: Option<Lu<usize, f64>>,
}

/// The six unknowns `3 v + k` that fix the six rigid motions of the points `x` (flat): all
/// three of a vertex `a`, the two components of the vertex `b` farthest from `a` across the
/// line `ab`, and the component of the vertex `c` farthest from the line `ab` that the rotation
/// about `ab` moves most. The same six equations are implied by the others (module docs).
pub(crate) fn pinned_unknowns(x: &[f64]) -> [usize; 6] {
    let p = |v: usize| Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
    let nv = x.len() / 3;
    let mut c = Vector3::zeros();
    for v in 0..nv {
        c += p(v);
    }
    c /= nv as f64;
    let farthest = |f: &dyn Fn(usize) -> f64| {
        (0..nv)
            .max_by(|&u, &v| f(u).total_cmp(&f(v)))
            .expect("a mesh has vertices")
    };
    let a = farthest(&|v| (p(v) - c).norm());
    let b = farthest(&|v| (p(v) - p(a)).norm());
    let d = (p(b) - p(a)).normalize();
    let c_v = farthest(&|v| (p(v) - p(a)).cross(&d).norm());
    // b: pin the two components other than d's largest one.
    let kb = d.iamax();
    let [b1, b2] = match kb {
        0 => [1, 2],
        1 => [0, 2],
        _ => [0, 1],
    };
    let kc = d.cross(&(p(c_v) - p(a))).iamax();
    [
        3 * a,
        3 * a + 1,
        3 * a + 2,
        3 * b + b1,
        3 * b + b2,
        3 * c_v + kc,
    ]
}

impl PinnedLu {
    /// The pattern of the Newton matrix of the mesh laid out by `pattern`, pinning the six
    /// rigid motions of the target `target` (flat).
    pub(crate) fn new(pattern: &NormalPattern, target: &[f64]) -> Self {
        let nv = pattern.vertices();
        let n = 3 * nv;
        let pinned = pinned_unknowns(target);
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        let mut sources = Vec::new();
        col_ptr.push(0);
        // J's block pattern is structurally symmetric (the one-ring): column block c holds the
        // row blocks of row block c's columns.
        for c in 0..nv {
            let ring = pattern.j_row(c);
            for l in 0..3 {
                let col = 3 * c + l;
                let pin = pinned.contains(&col);
                for &a in ring {
                    let slot = pattern.j_slot(a, c);
                    for k in 0..3 {
                        let row = 3 * a + k;
                        row_idx.push(row);
                        sources.push(if !pin {
                            Source::J(
                                u32::try_from(9 * slot + 3 * k + l)
                                    .expect("fewer than 2^32 entries"),
                            )
                        } else if row == col {
                            Source::Unit
                        } else {
                            Source::Zero
                        });
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        let values = vec![0.0; row_idx.len()];
        Self {
            n,
            col_ptr,
            row_idx,
            sources,
            values,
            diagonal: (0..nv).map(|v| pattern.j_slot(v, v)).collect(),
            pinned,
            symbolic: None,
            lu: None,
        }
    }

    /// Factorises the Newton matrix of the blocks `j` of `J`. Returns `false` when the
    /// factorisation fails (a structurally singular matrix).
    pub(crate) fn factorize(&mut self, j: &[Matrix3<f64>]) -> bool {
        self.lu = None;
        // The pinned columns' unit entries at the mean diagonal's scale.
        let s = self
            .diagonal
            .iter()
            .map(|&d| j[d].diagonal().abs().sum())
            .sum::<f64>()
            / (3.0 * self.diagonal.len() as f64);
        let s = s.max(f64::MIN_POSITIVE);
        for (v, src) in self.values.iter_mut().zip(&self.sources) {
            *v = match *src {
                Source::J(e) => {
                    let e = e as usize;
                    j[e / 9][((e % 9) / 3, e % 3)]
                }
                Source::Unit => s,
                Source::Zero => 0.0,
            };
        }
        let sym = SymbolicSparseColMatRef::new_checked(
            self.n,
            self.n,
            &self.col_ptr,
            None,
            &self.row_idx,
        );
        if self.symbolic.is_none() {
            match SymbolicLu::try_new(sym) {
                Ok(s) => self.symbolic = Some(s),
                Err(_) => return false,
            }
        }
        let Some(symbolic) = &self.symbolic else {
            return false;
        };
        match Lu::try_new_with_symbolic(symbolic.clone(), SparseColMatRef::new(sym, &self.values)) {
            Ok(lu) => {
                self.lu = Some(lu);
                true
            }
            Err(_) => false,
        }
    }

    /// The Newton step `dX` for the residual `r` (zero in the pinned unknowns), or `None` when
    /// there is no factor or the step is not finite.
    pub(crate) fn step(&self, r: &[f64]) -> Option<Vec<f64>> {
        let lu = self.lu.as_ref()?;
        let mut dx: Vec<f64> = r.iter().map(|a| -a).collect();
        lu.solve_in_place(faer::MatMut::from_column_major_slice_mut(
            &mut dx, self.n, 1,
        ));
        for &p in &self.pinned {
            dx[p] = 0.0;
        }
        dx.iter().all(|v| v.is_finite()).then_some(dx)
    }

    /// The solution `y` of the transposed pinned system, `J^T_{~P,~P} y_{~P} = z_{~P}`,
    /// `y_P = 0` (the transpose of the factorised matrix has the pinned rows replaced by unit
    /// rows, so zeroing `z_P` pins `y_P`); `None` when there is no factor or it is not finite.
    /// The dropped equations hold when `z` is orthogonal to the rigid motions `L`.
    pub(crate) fn transpose_solve(&self, z: &[f64]) -> Option<Vec<f64>> {
        let lu = self.lu.as_ref()?;
        let mut y = z.to_vec();
        for &p in &self.pinned {
            y[p] = 0.0;
        }
        lu.solve_transpose_in_place(faer::MatMut::from_column_major_slice_mut(&mut y, self.n, 1));
        for &p in &self.pinned {
            y[p] = 0.0;
        }
        y.iter().all(|v| v.is_finite()).then_some(y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::DesignProblem;
    use balloon_material::membrane::{MembraneModel, MembraneNeoHookean};
    use balloon_shell::ShellMaterialModel;

    /// The pinned step solves `J dX = -r` in every equation (the dropped ones too, which
    /// `L r = 0` implies) and keeps the pinned unknowns, on an ellipsoid whose rest shape is
    /// not the target (a non-trivial `J`).
    #[test]
    fn pinned_step_solves_the_full_newton_system() {
        let mut target = balloon_mesh::generate::icosphere(0.05, 2).unwrap();
        for v in &mut target.vertices {
            v.y *= 0.8;
            v.z *= 0.6;
        }
        let rubber = ShellMaterialModel::from(MembraneModel::from(
            MembraneNeoHookean::try_new(4e5).unwrap(),
        ));
        let problem =
            DesignProblem::try_new(&target, vec![1e-3; target.num_triangles()], rubber, 3e3)
                .unwrap();
        let pattern = problem.pattern();
        let rest: Vec<f64> = problem.target().iter().map(|x| 0.9 * x).collect();
        let n = rest.len();
        let mut r = vec![0.0; n];
        let mut j = vec![Matrix3::zeros(); pattern.j_blocks()];
        problem
            .evaluate_blocks(&rest, 1.0, &pattern, &mut r, &mut j)
            .unwrap();
        let mut lu = PinnedLu::new(&pattern, problem.target());
        assert!(lu.factorize(&j));
        let dx = lu.step(&r).unwrap();
        for &p in &lu.pinned {
            assert_eq!(dx[p], 0.0);
        }
        let mut jdx = vec![0.0; n];
        pattern.apply(&j, &dx, &mut jdx);
        let norm = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>().sqrt();
        let rel = norm(&jdx.iter().zip(&r).map(|(a, b)| a + b).collect::<Vec<_>>()) / norm(&r);
        assert!(rel < 1e-8, "|J dX + r| / |r| = {rel:e}");
        assert!(norm(&dx) > 0.0);
    }
}
