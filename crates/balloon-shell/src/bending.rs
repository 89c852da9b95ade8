//! The optional bending stiffness of the wall: one discrete-shell hinge per interior edge
//! (Grinspun et al. 2003, "Discrete Shells", Eq. 3; [`balloon_element::Hinge`]) with the
//! bending modulus of a plate of the wall's material and thickness,
//! `D = s Y h^3 / (12 (1 - nu^2))` (`s` the user's factor, `h` the mean current thickness of
//! the hinge's two triangles, `Y / (1 - nu^2)` the material's [`ShellMaterial::plate_modulus`]).
//!
//! The three-prism element of Wang et al. 2015 (Eq. 1-4) extrudes each triangle along its own
//! normal, so the wall it models has no bending stiffness: a real rubber wall of thickness `h`
//! has `D` above. The term is off by default (the paper's model); `docs/elements.md` says what
//! it changes.

use crate::ShellMaterial;
use crate::error::ShellSystemError;
use balloon_element::Hinge;
use balloon_mesh::parallel::prelude::*;
use nalgebra::{Matrix3, SMatrixView, Vector3};

/// What [`WallBending::evaluate`] computes besides the forces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Pass {
    /// The forces and the Hessians (a linearisation).
    Stiffness,
    /// The forces alone (a line-search trial).
    Forces,
    /// The forces and the energy (a line-search trial that needs both).
    ForcesAndEnergy,
}

/// Below this many hinges the loops run serially.
const PARALLEL_HINGES: usize = 4096;

/// The hinges of a closed mesh, their caches and the modulus.
#[derive(Clone, Debug)]
pub(crate) struct WallBending {
    /// The factor `s` on the plate's bending modulus (> 0).
    factor: f64,
    /// `Y / (1 - nu^2)`, Pa.
    plate_modulus: f64,
    hinges: Vec<Hinge>,
    /// The corners `[x0, x1, x2, x3]` of each hinge (edge `x0 x1`, wings `x2`, `x3`).
    corners: Vec<[usize; 4]>,
    /// The two triangles of each hinge (their thickness sets its modulus).
    faces: Vec<[usize; 2]>,
    /// `w / |E|^2 = 3 / (A_A + A_B)` of each rest hinge, 1/m^2.
    inverse_area: Vec<f64>,
    /// Where the hinge's corners sit in its triangles: `[x0, x1, x2]` in `A` and `[x1, x0, x3]`
    /// in `B` (corner indices 0-2), for folding the Hessian into the triangle blocks.
    local: Vec<[[usize; 3]; 2]>,
    forces: Vec<[Vector3<f64>; 4]>,
    /// 12x12 column-major hinge Hessians at the last linearisation.
    stiffness: Vec<[f64; 144]>,
    /// With a split stiffness ([`WallBending::compensate`]): per hinge the 3x3 blocks
    /// `P2 = U S U^T` and `P3 = V S V^T` (column-major, one after the other) of the opposite
    /// corners' coupling `C = K_23 = U S V^T`; empty without a split.
    compensation: Vec<[f64; 18]>,
}

impl WallBending {
    /// The hinges of `triangles` at the rest positions `rest` (flat, m): every edge shared by
    /// two triangles that run along it in opposite directions. Edges of a non-manifold or open
    /// mesh have no hinge.
    ///
    /// # Errors
    /// [`ShellSystemError::InvalidParameter`] for a factor that is not finite and positive;
    /// [`ShellSystemError::Element`] (naming a triangle of the hinge) for a degenerate rest
    /// hinge.
    pub(crate) fn new<M: ShellMaterial>(
        rest: &[f64],
        triangles: &[[usize; 3]],
        material: &M,
        factor: f64,
    ) -> Result<Self, ShellSystemError> {
        if !(factor.is_finite() && factor > 0.0) {
            return Err(ShellSystemError::InvalidParameter {
                name: "bending",
                value: factor,
                allowed: "a finite factor > 0 (0 switches the term off)",
            });
        }
        let point = |v: usize| Vector3::new(rest[3 * v], rest[3 * v + 1], rest[3 * v + 2]);
        let found = balloon_mesh::topology::hinges(triangles);
        let mut hinges = Vec::with_capacity(found.len());
        let mut corners = Vec::with_capacity(found.len());
        let mut faces = Vec::with_capacity(found.len());
        let mut inverse_area = Vec::with_capacity(found.len());
        let mut local = Vec::with_capacity(found.len());
        let at = |t: &[usize; 3], v: usize| t.iter().position(|&u| u == v).unwrap_or(0);
        for h in found {
            let hinge = Hinge::try_new(&h.corners.map(point)).map_err(|source| {
                ShellSystemError::Element {
                    element: h.faces[0],
                    source,
                }
            })?;
            inverse_area
                .push(hinge.weight() / (point(h.corners[1]) - point(h.corners[0])).norm_squared());
            hinges.push(hinge);
            corners.push(h.corners);
            faces.push(h.faces);
            let [a, b, c, d] = h.corners;
            let (ta, tb) = (&triangles[h.faces[0]], &triangles[h.faces[1]]);
            local.push([
                [at(ta, a), at(ta, b), at(ta, c)],
                [at(tb, b), at(tb, a), at(tb, d)],
            ]);
        }
        let n = hinges.len();
        Ok(Self {
            factor,
            plate_modulus: material.plate_modulus(),
            hinges,
            corners,
            faces,
            inverse_area,
            local,
            forces: vec![[Vector3::zeros(); 4]; n],
            stiffness: vec![[0.0; 144]; n],
            compensation: Vec::new(),
        })
    }

    /// The factor `s` on the plate's bending modulus.
    pub(crate) fn factor(&self) -> f64 {
        self.factor
    }

    /// The number of hinges.
    pub(crate) fn len(&self) -> usize {
        self.hinges.len()
    }

    /// How stiff the hinges are against the stretching of the wall at the mesh's scale: the
    /// mean over the hinges of `D w / (Y' h |E|^2) = s h^2 (w / |E|^2) / 12` (`Y'` the plate
    /// modulus, `h` the hinge's thickness), about `(h / l)^2 / 3` for a mesh of edge length
    /// `l`. Dimensionless; 0 without hinges.
    pub(crate) fn stiffness_ratio(&self, thickness: &[f64]) -> f64 {
        if self.hinges.is_empty() {
            return 0.0;
        }
        let sum: f64 = self
            .faces
            .iter()
            .zip(&self.inverse_area)
            .map(|(f, inv)| {
                let h = 0.5 * (thickness[f[0]] + thickness[f[1]]);
                h * h * inv
            })
            .sum();
        self.factor * sum / (12.0 * self.hinges.len() as f64)
    }

    fn corners_at(x: &[f64], c: &[usize; 4]) -> [Vector3<f64>; 4] {
        c.map(|v| Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]))
    }

    /// The bending energy at `x`, J.
    pub(crate) fn energy(&self, x: &[f64], thickness: &[f64]) -> f64 {
        let (factor, plate) = (self.factor, self.plate_modulus);
        let one = |((hinge, c), faces): ((&Hinge, &[usize; 4]), &[usize; 2])| {
            hinge.energy(
                &Self::corners_at(x, c),
                plate_bending_modulus(factor, plate, *faces, thickness),
            )
        };
        if self.len() >= PARALLEL_HINGES {
            self.hinges
                .par_iter()
                .zip(self.corners.par_iter())
                .zip(self.faces.par_iter())
                .map(one)
                .sum()
        } else {
            self.hinges
                .iter()
                .zip(&self.corners)
                .zip(&self.faces)
                .map(one)
                .sum()
        }
    }

    /// Fills the force cache at `x` and what `pass` asks for besides: the Hessian cache
    /// ([`Pass::Stiffness`]) or the bending energy of the same pass, returned
    /// ([`Pass::ForcesAndEnergy`]; 0 otherwise).
    pub(crate) fn evaluate(&mut self, x: &[f64], thickness: &[f64], pass: Pass) -> f64 {
        let (factor, plate, faces) = (self.factor, self.plate_modulus, &self.faces);
        let hinges = &self.hinges;
        let corners = &self.corners;
        let work = |(k, (f, s)): (usize, (&mut [Vector3<f64>; 4], &mut [f64; 144]))| {
            let xs = Self::corners_at(x, &corners[k]);
            let modulus = plate_bending_modulus(factor, plate, faces[k], thickness);
            match pass {
                Pass::Stiffness => {
                    let (fk, kk) = hinges[k].forces_and_stiffness(&xs, modulus);
                    *f = fk;
                    s.copy_from_slice(kk.as_slice());
                    0.0
                }
                Pass::ForcesAndEnergy => {
                    let (fk, e) = hinges[k].forces_and_energy(&xs, modulus);
                    *f = fk;
                    e
                }
                Pass::Forces => {
                    *f = hinges[k].forces(&xs, modulus);
                    0.0
                }
            }
        };
        if hinges.len() >= PARALLEL_HINGES {
            self.forces
                .par_iter_mut()
                .zip(self.stiffness.par_iter_mut())
                .enumerate()
                .map(work)
                .sum()
        } else {
            self.forces
                .iter_mut()
                .zip(self.stiffness.iter_mut())
                .enumerate()
                .map(work)
                .sum()
        }
    }

    /// The first hinge whose cached forces are not finite.
    pub(crate) fn non_finite(&self) -> Option<usize> {
        self.forces
            .iter()
            .position(|f| f.iter().any(|c| !c.iter().all(|v| v.is_finite())))
    }

    /// The first triangle of hinge `k`.
    pub(crate) fn face(&self, k: usize) -> usize {
        self.faces[k][0]
    }

    /// Adds the cached forces to `f`.
    pub(crate) fn add_forces(&self, f: &mut [f64]) {
        for (c, fk) in self.corners.iter().zip(&self.forces) {
            for (v, fv) in c.iter().zip(fk) {
                f[3 * v] += fv.x;
                f[3 * v + 1] += fv.y;
                f[3 * v + 2] += fv.z;
            }
        }
    }

    /// Adds each hinge's Hessian to the 9x9 blocks of its two triangles (`blocks`, one per
    /// triangle, column-major in the triangle's corner order): the couplings among `x0, x1, x2`
    /// to triangle `A`, the remaining ones among `x0, x1, x3` to triangle `B`. What is left
    /// is the coupling of the two opposite corners `x2` and `x3`, which no triangle holds:
    /// [`WallBending::add_differential`] and [`WallBending::add_triplets`] add that part.
    pub(crate) fn fold_into_blocks(&self, blocks: &mut [[f64; 81]]) {
        for ((k, faces), local) in self.stiffness.iter().zip(&self.faces).zip(&self.local) {
            let k = SMatrixView::<f64, 12, 12>::from_slice(k);
            // Hinge corner -> (triangle, corner in it), per triangle.
            let in_a = [local[0][0], local[0][1], local[0][2]];
            let in_b = [local[1][1], local[1][0], usize::MAX, local[1][2]];
            for q in 0..4 {
                for p in 0..4 {
                    let (block, r, c) = if p < 3 && q < 3 {
                        (&mut blocks[faces[0]], in_a[p], in_a[q])
                    } else if p != 2 && q != 2 {
                        (&mut blocks[faces[1]], in_b[p], in_b[q])
                    } else {
                        continue; // x2-x3: not in a triangle
                    };
                    for j in 0..3 {
                        for i in 0..3 {
                            block[(3 * c + j) * 9 + 3 * r + i] += k[(3 * p + i, 3 * q + j)];
                        }
                    }
                }
            }
        }
    }

    /// `df += -K_23 dx`: the part of the hinges' Hessians that couples the two opposite
    /// corners `x2` and `x3` (the rest is in the triangle blocks,
    /// [`WallBending::fold_into_blocks`]).
    pub(crate) fn add_differential(&self, dx: &[f64], df: &mut [f64]) {
        for (c, k) in self.corners.iter().zip(&self.stiffness) {
            let k = SMatrixView::<f64, 12, 12>::from_slice(k);
            for (p, q) in [(2, 3), (3, 2)] {
                let (vp, vq) = (c[p], c[q]);
                for i in 0..3 {
                    let mut acc = 0.0;
                    for j in 0..3 {
                        acc += k[(3 * p + i, 3 * q + j)] * dx[3 * vq + j];
                    }
                    df[3 * vp + i] -= acc;
                }
            }
        }
    }

    /// Appends the `x2`-`x3` couplings of the hinges' Hessians as triplets (18 per hinge; the
    /// rest is in the triangle blocks).
    pub(crate) fn add_triplets(&self, triplets: &mut Vec<(usize, usize, f64)>) {
        triplets.reserve(18 * self.len());
        for (c, k) in self.corners.iter().zip(&self.stiffness) {
            let k = SMatrixView::<f64, 12, 12>::from_slice(k);
            for (p, q) in [(2, 3), (3, 2)] {
                for i in 0..3 {
                    for j in 0..3 {
                        triplets.push((3 * c[p] + i, 3 * c[q] + j, k[(3 * p + i, 3 * q + j)]));
                    }
                }
            }
        }
    }
}

impl WallBending {
    /// The coupling `C = K_23` of hinge Hessian `k` (rows `x2`, columns `x3`).
    fn coupling(k: &[f64; 144]) -> Matrix3<f64> {
        let k = SMatrixView::<f64, 12, 12>::from_slice(k);
        k.fixed_view::<3, 3>(6, 9).into_owned()
    }

    /// Computes, from the Hessians of the last linearisation, the diagonal blocks that replace
    /// each hinge's opposite-corner coupling in a preconditioning matrix (a split stiffness,
    /// `ShellSystem::set_stiffness_split`): with `C = K_23 = U S V^T`, the coupling
    /// `[[0, C], [C^T, 0]]` of `x2` and `x3` is replaced by `[[U S U^T, 0], [0, V S V^T]]`.
    /// The difference `sum_i s_i (u_i, -v_i)(u_i, -v_i)^T` is positive semidefinite, so the
    /// preconditioning matrix bounds the exact one from above (it is positive definite
    /// wherever the exact one is) and has the triangles' sparsity: no fill from the couplings.
    /// The discrete-shell angle's gradient at `x2` depends on `x0, x1, x2` only and at `x3`
    /// on `x0, x1, x3` only (Bridson et al. 2003), so `C = D w g_2 g_3^T` has rank one and the
    /// blocks are `D w |g_2| |g_3|` times the projectors on `g_2` and `g_3`.
    pub(crate) fn compensate(&mut self) {
        let work = |(k, c): (&[f64; 144], &mut [f64; 18])| {
            let (p2, p3) = compensation_blocks(&Self::coupling(k));
            c[..9].copy_from_slice(p2.as_slice());
            c[9..].copy_from_slice(p3.as_slice());
        };
        self.compensation.resize(self.hinges.len(), [0.0; 18]);
        if self.len() >= PARALLEL_HINGES {
            self.stiffness
                .par_iter()
                .zip(self.compensation.par_iter_mut())
                .for_each(work);
        } else {
            self.stiffness
                .iter()
                .zip(self.compensation.iter_mut())
                .for_each(work);
        }
    }

    /// Drops the blocks of [`WallBending::compensate`] (the stiffness is not split).
    pub(crate) fn uncompensate(&mut self) {
        self.compensation.clear();
    }

    /// Whether [`WallBending::compensate`]'s blocks are in use.
    pub(crate) fn compensated(&self) -> bool {
        !self.compensation.is_empty()
    }

    /// Appends the diagonal blocks of [`WallBending::compensate`] at `x2` and `x3` as
    /// triplets (18 per hinge), in place of the couplings of [`WallBending::add_triplets`].
    pub(crate) fn add_compensation_triplets(&self, triplets: &mut Vec<(usize, usize, f64)>) {
        triplets.reserve(18 * self.len());
        for (c, comp) in self.corners.iter().zip(&self.compensation) {
            for (corner, block) in [(c[2], &comp[..9]), (c[3], &comp[9..])] {
                for j in 0..3 {
                    for i in 0..3 {
                        triplets.push((3 * corner + i, 3 * corner + j, block[3 * j + i]));
                    }
                }
            }
        }
    }

    /// `out += scale E p` with `E = [[-P2, C], [C^T, -P3]]` on `(x2, x3)` per hinge: the exact
    /// stiffness minus the preconditioning matrix of [`WallBending::compensate`].
    pub(crate) fn add_correction(&self, scale: f64, p: &[f64], out: &mut [f64]) {
        let at = |v: usize| Vector3::new(p[3 * v], p[3 * v + 1], p[3 * v + 2]);
        for ((c, k), comp) in self
            .corners
            .iter()
            .zip(&self.stiffness)
            .zip(&self.compensation)
        {
            let coupling = Self::coupling(k);
            let p2 = Matrix3::from_column_slice(&comp[..9]);
            let p3 = Matrix3::from_column_slice(&comp[9..]);
            let (a, b) = (at(c[2]), at(c[3]));
            let e2 = coupling * b - p2 * a;
            let e3 = coupling.tr_mul(&a) - p3 * b;
            for (v, e) in [(c[2], e2), (c[3], e3)] {
                for i in 0..3 {
                    out[3 * v + i] += scale * e[i];
                }
            }
        }
    }
}

/// The blocks `(U S U^T, V S V^T)` of a coupling `C = U S V^T` (`WallBending::compensate`).
/// A hinge's coupling has rank one, `C = a b^T`, and then they are `|b| a a^T / |a|` and
/// `|a| b b^T / |b|`, found from `C`'s largest column without a decomposition; a coupling
/// that is not of rank one to round-off (it cannot be, but the bound must hold regardless)
/// takes the singular value decomposition.
fn compensation_blocks(c: &Matrix3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
    let norm = c.norm();
    if norm == 0.0 || !norm.is_finite() {
        return (Matrix3::zeros(), Matrix3::zeros());
    }
    let j = (0..3)
        .max_by(|&i, &k| {
            c.column(i)
                .norm_squared()
                .total_cmp(&c.column(k).norm_squared())
        })
        .unwrap_or(0);
    let a = c.column(j).normalize();
    let b = c.tr_mul(&a);
    if (c - a * b.transpose()).norm() <= 1e-12 * norm {
        let s = b.norm();
        let b = b / s;
        return (a * a.transpose() * s, b * b.transpose() * s);
    }
    let svd = c.svd(true, true);
    match (svd.u, svd.v_t) {
        (Some(u), Some(v_t)) => {
            let s = Matrix3::from_diagonal(&svd.singular_values);
            (u * s * u.transpose(), v_t.transpose() * s * v_t)
        }
        // Not reached for finite input; the scalar bound `|C|_F I` holds as well.
        _ => (Matrix3::identity() * norm, Matrix3::identity() * norm),
    }
}

/// `D = s Y h^3 / (12 (1 - nu^2))` (N m) of a hinge between the triangles `faces`, `h` their
/// mean current thickness, `plate` = `Y / (1 - nu^2)`.
fn plate_bending_modulus(factor: f64, plate: f64, faces: [usize; 2], thickness: &[f64]) -> f64 {
    let h = 0.5 * (thickness[faces[0]] + thickness[faces[1]]);
    factor * plate * h * h * h / 12.0
}

#[cfg(test)]
mod tests;
