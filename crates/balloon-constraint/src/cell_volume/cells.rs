//! The cell constraints themselves ([`CellVolumeConstraints`]: cells, tetrahedra, rest volumes)
//! and what they measure: a cell's volume (Eq. 3) and its gradient, the largest relative error,
//! the first inverted tetrahedron.

use super::params::{CellCorrection, CellSolver, CellVolumeParams};
use crate::ConstraintError;
use balloon_mesh::tet::signed_tet_volume;
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

/// The volume constraints of all cells.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellVolumeConstraints {
    /// Eight particles per cell.
    pub cells: Vec<[usize; 8]>,
    /// Five tetrahedra per cell, as particle indices.
    pub tets: Vec<[[usize; 4]; 5]>,
    /// Rest volume `V0` per cell (m^3).
    pub rest_volumes: Vec<f64>,
    /// Parameters.
    pub params: CellVolumeParams,
}

/// Volume of a cell: the sum of its five signed tetrahedron volumes (Eq. 3).
pub fn cell_volume(positions: &[Point3<f64>], tets: &[[usize; 4]; 5]) -> f64 {
    tets.iter()
        .map(|t| {
            signed_tet_volume(
                &positions[t[0]],
                &positions[t[1]],
                &positions[t[2]],
                &positions[t[3]],
            )
        })
        .sum()
}

/// Volume of cell `c` and its gradient with respect to its eight corners (Eq. 3 summed over
/// the five tetrahedra: `dV/dx_b = (x_c - x_a) x (x_d - x_a) / 6` and cyclic, `dV/dx_a` minus
/// their sum).
pub(crate) fn volume_and_gradient(
    x: &[Point3<f64>],
    cell: &[usize; 8],
    tets: &[[usize; 4]; 5],
    grad: &mut [Vector3<f64>; 8],
) -> f64 {
    *grad = [Vector3::zeros(); 8];
    let slot = |i: usize| cell.iter().position(|&k| k == i).unwrap_or(0);
    let mut volume = 0.0;
    for t in tets {
        let [a, b, c, d] = t.map(|i| x[i]);
        volume += signed_tet_volume(&a, &b, &c, &d);
        let gb = (c - a).cross(&(d - a)) / 6.0;
        let gc = (d - a).cross(&(b - a)) / 6.0;
        let gd = (b - a).cross(&(c - a)) / 6.0;
        grad[slot(t[0])] -= gb + gc + gd;
        grad[slot(t[1])] += gb;
        grad[slot(t[2])] += gc;
        grad[slot(t[3])] += gd;
    }
    volume
}

impl CellVolumeConstraints {
    /// Constraints for `cells` with tetrahedra `tets` (particle indices), rest volumes measured
    /// at `rest_positions`.
    pub fn new(
        cells: Vec<[usize; 8]>,
        tets: Vec<[[usize; 4]; 5]>,
        rest_positions: &[Point3<f64>],
        params: CellVolumeParams,
    ) -> Result<Self, ConstraintError> {
        if !(params.tolerance > 0.0 && params.tolerance < 1.0) {
            return Err(ConstraintError::invalid(
                "tolerance",
                params.tolerance,
                "must be in (0, 1)",
            ));
        }
        if !(params.over_relaxation > 0.0 && params.over_relaxation < 2.0) {
            return Err(ConstraintError::invalid(
                "over_relaxation",
                params.over_relaxation,
                "must be in (0, 2)",
            ));
        }
        if params.solver == CellSolver::Global {
            if params.correction != CellCorrection::Gradient {
                return Err(ConstraintError::IncompatibleOption {
                    option: "correction",
                    value: "scaling",
                    reason: "the global solver moves along the volume gradients: use the \
                             gradient correction with it",
                });
            }
            if params.over_relaxation != 1.0 {
                return Err(ConstraintError::invalid(
                    "over_relaxation",
                    params.over_relaxation,
                    "must be 1 with the global solver (it applies to Gauss-Seidel sweeps)",
                ));
            }
            if params.adaptive_relaxation {
                return Err(ConstraintError::IncompatibleOption {
                    option: "adaptive_relaxation",
                    value: "true",
                    reason: "it applies to the Gauss-Seidel sweeps, not the global solver",
                });
            }
        }
        if params.max_sweeps == 0 {
            return Err(ConstraintError::invalid("max_sweeps", 0.0, "must be >= 1"));
        }
        let rest_volumes: Vec<f64> = tets
            .iter()
            .map(|t| cell_volume(rest_positions, t))
            .collect();
        for (cell, &volume) in rest_volumes.iter().enumerate() {
            if volume.is_nan() || volume <= 0.0 {
                return Err(ConstraintError::BadRestVolume { cell, volume });
            }
        }
        Ok(Self {
            cells,
            tets,
            rest_volumes,
            params,
        })
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// True when there are no cells.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// Total volume of the cells at `positions` (m^3): the sum of [`cell_volume`] in cell order.
    pub fn total_volume(&self, positions: &[Point3<f64>]) -> f64 {
        self.tets.iter().map(|t| cell_volume(positions, t)).sum()
    }

    /// Total rest volume of the cells (m^3): the sum of `rest_volumes`.
    pub fn rest_volume(&self) -> f64 {
        self.rest_volumes.iter().sum()
    }

    /// Largest relative volume error `|V - V0| / V0` over the cells, and the cell.
    pub fn max_relative_error(&self, positions: &[Point3<f64>]) -> (f64, usize) {
        let mut worst = (0.0, 0);
        for (c, t) in self.tets.iter().enumerate() {
            let e = (cell_volume(positions, t) / self.rest_volumes[c] - 1.0).abs();
            if e > worst.0 || e.is_nan() {
                worst = (e, c);
            }
        }
        worst
    }

    /// First tetrahedron with non-positive volume, if any (Sec. 4: the step must be halved).
    pub fn find_inverted(&self, positions: &[Point3<f64>]) -> Option<ConstraintError> {
        for (cell, tets) in self.tets.iter().enumerate() {
            for (tet, t) in tets.iter().enumerate() {
                let volume = signed_tet_volume(
                    &positions[t[0]],
                    &positions[t[1]],
                    &positions[t[2]],
                    &positions[t[3]],
                );
                if volume.is_nan() || volume <= 0.0 {
                    return Some(ConstraintError::Inverted { cell, tet, volume });
                }
            }
        }
        None
    }
}
