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
use nalgebra::{SMatrixView, Vector3};

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
    /// Where the hinge's corners sit in its triangles: `[x0, x1, x2]` in `A` and `[x1, x0, x3]`
    /// in `B` (corner indices 0-2), for folding the Hessian into the triangle blocks.
    local: Vec<[[usize; 3]; 2]>,
    forces: Vec<[Vector3<f64>; 4]>,
    /// 12x12 column-major hinge Hessians at the last linearisation.
    stiffness: Vec<[f64; 144]>,
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
        let mut local = Vec::with_capacity(found.len());
        let at = |t: &[usize; 3], v: usize| t.iter().position(|&u| u == v).unwrap_or(0);
        for h in found {
            let hinge = Hinge::try_new(&h.corners.map(point)).map_err(|source| {
                ShellSystemError::Element {
                    element: h.faces[0],
                    source,
                }
            })?;
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
            local,
            forces: vec![[Vector3::zeros(); 4]; n],
            stiffness: vec![[0.0; 144]; n],
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

/// `D = s Y h^3 / (12 (1 - nu^2))` (N m) of a hinge between the triangles `faces`, `h` their
/// mean current thickness, `plate` = `Y / (1 - nu^2)`.
fn plate_bending_modulus(factor: f64, plate: f64, faces: [usize; 2], thickness: &[f64]) -> f64 {
    let h = 0.5 * (thickness[faces[0]] + thickness[faces[1]]);
    factor * plate * h * h * h / 12.0
}

#[cfg(test)]
mod tests;
