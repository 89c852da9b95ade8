//! The 16 springs of every cell (12 edges and 4 body diagonals, Sec. 4): explicit, damped,
//! integrated into the velocities before the volume impulses (Eq. 1).

use crate::ConstraintError;
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

/// The 12 edges of a cell as local corner pairs (corner order of
/// `balloon_mesh::lattice::CORNERS`).
pub const CELL_EDGES: [[usize; 2]; 12] = [
    [0, 1],
    [1, 2],
    [2, 3],
    [3, 0],
    [4, 5],
    [5, 6],
    [6, 7],
    [7, 4],
    [0, 4],
    [1, 5],
    [2, 6],
    [3, 7],
];

/// The 4 body diagonals of a cell as local corner pairs.
pub const CELL_DIAGONALS: [[usize; 2]; 4] = [[0, 6], [1, 7], [2, 4], [3, 5]];

/// One damped spring.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Spring {
    /// Its two particles.
    pub ends: [usize; 2],
    /// Rest length (m).
    pub rest_length: f64,
    /// Stiffness (N/m).
    pub stiffness: f64,
    /// Damping along the spring (N s/m).
    pub damping: f64,
}

/// Stiffness and damping of the cell springs (Fig. 3: edges and diagonals separately).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SpringParams {
    /// Edge spring stiffness (N/m). Default 2e4.
    pub edge_stiffness: f64,
    /// Edge spring damping (N s/m). Default 20.
    pub edge_damping: f64,
    /// Body-diagonal spring stiffness (N/m). Default 2e4.
    pub diagonal_stiffness: f64,
    /// Body-diagonal spring damping (N s/m). Default 20.
    pub diagonal_damping: f64,
}

impl Default for SpringParams {
    fn default() -> Self {
        Self {
            edge_stiffness: 2e4,
            edge_damping: 20.0,
            diagonal_stiffness: 2e4,
            diagonal_damping: 20.0,
        }
    }
}

impl SpringParams {
    /// Springs scaled to the particle mass `mass` (kg) and time step `dt` (s): stiffness
    /// `stiffness * m / h^2` and damping `damping * m / h` on edges and diagonals alike. The
    /// springs act explicitly (Eq. 1), so the relative `stiffness` must stay well below 1 for
    /// stability; a fixed stiffness in N/m turns unstable when a finer lattice makes the
    /// particles lighter.
    pub fn mass_scaled(stiffness: f64, damping: f64, mass: f64, dt: f64) -> Self {
        let (k, c) = (stiffness * mass / (dt * dt), damping * mass / dt);
        Self {
            edge_stiffness: k,
            edge_damping: c,
            diagonal_stiffness: k,
            diagonal_damping: c,
        }
    }

    /// Checks that all values are finite and non-negative; the error names the parameter.
    pub fn validate(&self) -> Result<(), ConstraintError> {
        for (name, value) in [
            ("edge_stiffness", self.edge_stiffness),
            ("edge_damping", self.edge_damping),
            ("diagonal_stiffness", self.diagonal_stiffness),
            ("diagonal_damping", self.diagonal_damping),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ConstraintError::invalid(
                    name,
                    value,
                    "must be finite and >= 0",
                ));
            }
        }
        Ok(())
    }
}

/// The 16 springs of every cell (a spring on an edge shared by several cells appears once per
/// cell, as in the paper where each constraint owns its springs).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CellSprings {
    /// All springs.
    pub springs: Vec<Spring>,
}

impl CellSprings {
    /// Springs for `cells` with rest lengths measured at `rest_positions`.
    pub fn new(
        cells: &[[usize; 8]],
        rest_positions: &[Point3<f64>],
        params: &SpringParams,
    ) -> Self {
        let mut springs = Vec::with_capacity(16 * cells.len());
        for cell in cells {
            for (pairs, k, c) in [
                (&CELL_EDGES[..], params.edge_stiffness, params.edge_damping),
                (
                    &CELL_DIAGONALS[..],
                    params.diagonal_stiffness,
                    params.diagonal_damping,
                ),
            ] {
                for &[a, b] in pairs {
                    let ends = [cell[a], cell[b]];
                    springs.push(Spring {
                        ends,
                        rest_length: (rest_positions[ends[1]] - rest_positions[ends[0]]).norm(),
                        stiffness: k,
                        damping: c,
                    });
                }
            }
        }
        Self { springs }
    }

    /// Largest spring strain `|l / L0 - 1|` at positions `x` (0 without springs).
    pub fn max_strain(&self, x: &[Point3<f64>]) -> f64 {
        self.springs
            .iter()
            .map(|s| {
                let l = (x[s.ends[1]] - x[s.ends[0]]).norm();
                (l / s.rest_length - 1.0).abs()
            })
            .fold(0.0, f64::max)
    }

    /// Elastic energy `sum k/2 (|x_b - x_a| - L0)^2` (J).
    pub fn energy(&self, x: &[Point3<f64>]) -> f64 {
        self.springs
            .iter()
            .map(|s| {
                let l = (x[s.ends[1]] - x[s.ends[0]]).norm();
                0.5 * s.stiffness * (l - s.rest_length).powi(2)
            })
            .sum()
    }

    /// Adds the spring forces to `forces` (N): elastic `-k (l - L0) d` on the first end and
    /// damping `-c ((v_a - v_b) . d) d` along the unit direction `d = (x_a - x_b)/l`, equal and
    /// opposite on the two ends (so they exert no net force: momentum is conserved).
    pub fn add_forces(&self, x: &[Point3<f64>], v: &[Vector3<f64>], forces: &mut [Vector3<f64>]) {
        for s in &self.springs {
            let [a, b] = s.ends;
            let d = x[a] - x[b];
            let l = d.norm();
            if l <= f64::MIN_POSITIVE {
                continue;
            }
            let n = d / l;
            let f = n * (-s.stiffness * (l - s.rest_length) - s.damping * (v[a] - v[b]).dot(&n));
            forces[a] += f;
            forces[b] -= f;
        }
    }

    /// Force differential `df = -K dx` of the elastic part at `x` (N), for a direction `dx` (m):
    /// for one spring `K = k [n n^T + (1 - L0/l)(I - n n^T)]` on the relative displacement.
    pub fn force_differential(&self, x: &[Point3<f64>], dx: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        let mut df = vec![Vector3::zeros(); x.len()];
        for s in &self.springs {
            let [a, b] = s.ends;
            let d = x[a] - x[b];
            let l = d.norm();
            if l <= f64::MIN_POSITIVE {
                continue;
            }
            let n = d / l;
            let r = dx[a] - dx[b];
            let kr =
                (n * n.dot(&r) + (r - n * n.dot(&r)) * (1.0 - s.rest_length / l)) * s.stiffness;
            df[a] -= kr;
            df[b] += kr;
        }
        df
    }
}
