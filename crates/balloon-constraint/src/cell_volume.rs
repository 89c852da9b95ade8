//! Cell volume constraints of impulse-based volume-conserving bodies (seed 003, Diziol, Bender
//! and Bayer, Sec. 4).
//!
//! A *cell* is a lattice hexahedron: 8 particles, 5 tetrahedra and 16 springs (12 edges and 4
//! body diagonals, [`CellSprings`]). One simulation step (Eq. 1) first integrates the external
//! forces (springs, gravity) into the velocities, `v += h F_ext / m`, and forms the *preview*
//! positions `x = p + h v`. Then [`CellVolumeConstraints::project`] visits the cells in
//! Gauss-Seidel order; for each it sums the five preview tetrahedron volumes (Eq. 3) to
//! `V(t+h)`, and with `lambda = cbrt(V0 / V(t+h))` moves its particles by
//! `(lambda - 1)(x_i - c)` about the cell centre `c`, which scales the cell about `c` and so
//! multiplies its volume by `lambda^3`, restoring `V0` (Eq. 2). The velocity change that produces
//! this displacement is
//!
//! ```text
//! Delta v_i = (lambda - 1) (x_i - c) / h,        impulse  J_i = m_i Delta v_i.
//! ```
//!
//! (The printed Eq. 4 divides by `h m_i`: that is the velocity change produced by an *impulse*
//! `(lambda - 1)(x_i - c)`, which would not move the particle by `(lambda - 1)(x_i - c)` unless
//! `m_i = 1`. We use the velocity change above; with equal masses the two differ only by the
//! constant factor `m`, and the momentum argument of the paper holds unchanged.) Sweeps repeat
//! until every cell's relative volume error `|V - V0| / V0` is below the tolerance.
//!
//! With unequal masses, the arithmetic centre `c = mean(x_i)` no longer conserves momentum;
//! [`CellCentre::MassWeighted`] uses `c = sum(m_i x_i) / sum(m_i)`, for which
//! `sum_i m_i Delta v_i = 0` exactly.

use crate::ConstraintError;
pub use crate::cell_global::CellProjectionWorkspace;
use balloon_mesh::tet::signed_tet_volume;
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

/// Which centre the cell is scaled about.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CellCentre {
    /// `c = (1/8) sum x_i`, as in the paper; conserves momentum for equal masses.
    #[default]
    Arithmetic,
    /// `c = sum m_i x_i / sum m_i`; conserves momentum for any masses.
    MassWeighted,
}

/// How a cell's particles are moved to restore its volume.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CellCorrection {
    /// The paper's correction (seed 003, Sec. 4): scale the cell about its centre by
    /// `lambda = cbrt(V0 / V)`, exact for that cell in one visit. Its direction `x_i - c` is not
    /// the constraint gradient, so once cells are sheared it can add kinetic energy (measured:
    /// about 1e-5 relative per step on a free body with random velocities).
    #[default]
    Scaling,
    /// Move along the mass-weighted volume gradient,
    /// `dx_i = -w_i grad_i V (V - V0) / sum_j w_j |grad_j V|^2` (`w = 1/m`), Newton-iterated by
    /// the sweeps: the minimal mass-weighted correction. Its velocity change is an M-orthogonal
    /// projection to first order, so the kinetic energy change is `-C^2 / (2 h^2 sum w |grad V|^2)
    /// <= 0` (it never creates energy to first order), and since `sum_i grad_i V = 0` it conserves
    /// momentum for any masses.
    Gradient,
}

/// How the cell constraints are solved together.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CellSolver {
    /// The paper's Gauss-Seidel sweeps, one cell at a time (seed 003, Sec. 4). Sweeps needed
    /// grow with the lattice size.
    #[default]
    GaussSeidel,
    /// Newton iterations on all cells at once with a sparse Cholesky solve of `J W J^T`
    /// ([`crate::cell_global`]); needs [`CellCorrection::Gradient`] and no over-relaxation.
    /// A few iterations whatever the lattice size.
    Global,
}

/// Parameters of the volume projection.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CellVolumeParams {
    /// Largest accepted relative cell-volume error `|V - V0| / V0` after projection. Default
    /// `1e-10`.
    pub tolerance: f64,
    /// Largest number of sweeps over all cells (Gauss-Seidel) or of Newton iterations
    /// (global). Default 500.
    pub max_sweeps: usize,
    /// Centre of the scaling. Default [`CellCentre::Arithmetic`].
    pub centre: CellCentre,
    /// How the particles are moved. Default [`CellCorrection::Scaling`] (the paper's).
    pub correction: CellCorrection,
    /// Over-relaxation `omega` in (0, 2): each visit scales a cell by `lambda^omega` instead of
    /// `lambda` (successive over-relaxation of the Gauss-Seidel sweeps; 1 is the paper's exact
    /// per-cell correction). Every cell still ends within the tolerance and momentum is still
    /// conserved; the path, and so the final point on the constraint set, differs slightly.
    /// Measured on the CLI's default teddy run: 111 mean sweeps per step at 1.0, 55 at 1.3,
    /// 104 at 1.6. Default 1.
    pub over_relaxation: f64,
    /// Gauss-Seidel sweeps (the paper's) or one global solve. Default
    /// [`CellSolver::GaussSeidel`].
    pub solver: CellSolver,
    /// Adaptive over-relaxation of the Gauss-Seidel sweeps (not in the paper; default `false`).
    /// The sweeps keep the paper's per-cell correction (Eq. 2-4, scaled by `lambda^omega`), but
    /// `omega` is chosen from the observed convergence: the first `2 ADAPT_WINDOW` sweeps run
    /// at `over_relaxation`; the factor `rho` by which the largest cell error shrank per sweep
    /// over the second window of them then gives Young's optimum,
    /// `omega = 2 / (1 + sqrt(1 - rho))` (for a consistently ordered linear system the
    /// Gauss-Seidel factor is `rho = mu^2`, `mu` the Jacobi one, and SOR at this `omega`
    /// converges by `omega - 1` per sweep), at most [`MAX_ADAPTIVE_OMEGA`]. If the error then
    /// stops shrinking over a window, `omega - 1` is halved (see `adaptive_step`). Every cell still ends within
    /// `tolerance`, and the per-cell impulses still sum to zero (momentum is kept); only the
    /// number of sweeps (and the point reached on the constraint set) changes. Measured on a
    /// block of 864 cells with every particle moved by up to 1 mm
    /// (`adaptive_relaxation_cuts_the_sweeps_of_a_large_block`): 1458 sweeps at `omega = 1`,
    /// 437 adaptive (it chose 1.51), against 760, 434, 276, 249, 382 and 767 at the fixed
    /// `omega` 1.3, 1.5, 1.6, 1.7, 1.8 and 1.9: the early estimate of `rho` is low (the slowest
    /// error components dominate only later), which keeps `omega` on the safe side of the
    /// optimum, where a too large one costs more than a too small one here.
    pub adaptive_relaxation: bool,
}

/// Sweeps over which the convergence factor of the Gauss-Seidel sweeps is measured for
/// [`CellVolumeParams::adaptive_relaxation`].
pub const ADAPT_WINDOW: usize = 8;

/// Largest over-relaxation the adaptive rule chooses (a factor close to 1 would put it close to
/// 2, where SOR stops converging).
pub const MAX_ADAPTIVE_OMEGA: f64 = 1.9;

/// One decision of [`CellVolumeParams::adaptive_relaxation`] after a sweep: `history` holds
/// the largest relative cell error before the first sweep and after each sweep so far, `omega`
/// is the current factor, `adapted` the sweep at which it was last changed (`None`: not yet).
/// After a burn-in of [`ADAPT_WINDOW`] plain sweeps (the first sweeps remove the
/// short-wavelength error much faster than the rest, so they say little about the slow
/// convergence), the factor `rho` per sweep over the next window gives
/// `omega = `[`optimal_over_relaxation`]`(rho)`, once; afterwards, a window over which the error
/// did not shrink halves `omega - 1`. Returns the new `omega` when it changes.
fn adaptive_step(history: &[f64], omega: f64, adapted: &mut Option<usize>) -> Option<f64> {
    let sweep = history.len() - 1;
    let factor = |from: usize| (history[sweep] / history[from]).powf(1.0 / (sweep - from) as f64);
    match *adapted {
        None if sweep == 2 * ADAPT_WINDOW => {
            let rho = factor(ADAPT_WINDOW);
            *adapted = Some(sweep);
            let next = optimal_over_relaxation(rho);
            (next != omega).then_some(next)
        }
        Some(at) if sweep >= at + ADAPT_WINDOW && omega > 1.0 => {
            if factor(sweep - ADAPT_WINDOW) >= 1.0 {
                *adapted = Some(sweep);
                Some(1.0 + 0.5 * (omega - 1.0))
            } else {
                None
            }
        }
        _ => None,
    }
}

/// Young's optimal SOR factor `2 / (1 + sqrt(1 - rho))` for an observed Gauss-Seidel
/// convergence factor `rho` per sweep, in `[1, MAX_ADAPTIVE_OMEGA]` (1 when `rho` is not in
/// `(0, 1)`).
pub fn optimal_over_relaxation(rho: f64) -> f64 {
    if !(rho > 0.0 && rho < 1.0) {
        return 1.0;
    }
    (2.0 / (1.0 + (1.0 - rho).sqrt())).clamp(1.0, MAX_ADAPTIVE_OMEGA)
}

impl CellVolumeParams {
    /// The global solver with the gradient correction it needs ([`CellSolver::Global`]), other
    /// settings at their defaults.
    pub fn global() -> Self {
        Self {
            correction: CellCorrection::Gradient,
            solver: CellSolver::Global,
            ..Self::default()
        }
    }

    /// Gauss-Seidel sweeps set up to converge on lattices of about a thousand cells: the
    /// gradient correction and [`CellVolumeParams::adaptive_relaxation`], other settings at
    /// their defaults. The paper's sweeps ([`CellVolumeParams::default`]: scaling correction,
    /// `omega = 1`) reduce the largest cell error by only about 2 % per sweep there and stop
    /// at the 500-sweep limit within 6-35 steps of `balloon volumetric`'s drop-sphere scene on
    /// the teddy, bunny, spot and armadillo (the torus ran its first 400 steps at 157 sweeps
    /// per step); these settings run 2000 steps on all five (`cargo xtask validate --only
    /// drop-sphere`, 93-344 sweeps per step); with the scaling correction and adaptive relaxation the impact
    /// inverts a cell (bunny step 1417, spot step 970), as the scaling adds kinetic energy.
    /// This is the default of `balloon volumetric --volume-solver gauss-seidel`.
    pub fn gauss_seidel() -> Self {
        Self {
            correction: CellCorrection::Gradient,
            solver: CellSolver::GaussSeidel,
            adaptive_relaxation: true,
            ..Self::default()
        }
    }
}

impl Default for CellVolumeParams {
    fn default() -> Self {
        Self {
            tolerance: 1e-10,
            max_sweeps: 500,
            centre: CellCentre::Arithmetic,
            correction: CellCorrection::Scaling,
            over_relaxation: 1.0,
            solver: CellSolver::GaussSeidel,
            adaptive_relaxation: false,
        }
    }
}

/// Result of one projection.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ProjectionInfo {
    /// Sweeps performed.
    pub sweeps: usize,
    /// Largest relative cell-volume error before the projection.
    pub initial_error: f64,
    /// Largest relative cell-volume error after it.
    pub final_error: f64,
}

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

    /// Applies the volume impulses (Eq. 2-4) in Gauss-Seidel sweeps (or, with
    /// [`CellSolver::Global`], by Newton iterations on all cells at once).
    ///
    /// * `preview`: the positions `x = p + h v` of Eq. 1 (m), moved in place to the corrected
    ///   positions;
    /// * `velocities`: `v(t + h)` (m/s), changed by `Delta v_i = (lambda - 1)(x_i - c) / h` so that
    ///   `p + h v` equals the corrected preview again;
    /// * `masses`: particle masses (kg), used by [`CellCentre::MassWeighted`] and the gradient
    ///   correction; `f64::INFINITY` marks a fixed particle, which the projection never moves
    ///   (its cells take the gradient correction);
    /// * `h`: the time step (s).
    ///
    /// Returns [`ConstraintError::Inverted`] when a preview tetrahedron is not positive (before
    /// or during the sweeps), and [`ConstraintError::CellVolumeNotConverged`] after `max_sweeps`.
    pub fn project(
        &self,
        preview: &mut [Point3<f64>],
        velocities: &mut [Vector3<f64>],
        masses: &[f64],
        h: f64,
    ) -> Result<ProjectionInfo, ConstraintError> {
        self.project_to_tolerance(preview, velocities, masses, h, self.params.tolerance)
    }

    /// [`CellVolumeConstraints::project`] with another relative tolerance (e.g. a loose one for
    /// the intermediate rounds of a contact loop). The global solver gets a fresh workspace
    /// each call; use [`CellVolumeConstraints::project_with`] to keep one.
    pub fn project_to_tolerance(
        &self,
        preview: &mut [Point3<f64>],
        velocities: &mut [Vector3<f64>],
        masses: &[f64],
        h: f64,
        tolerance: f64,
    ) -> Result<ProjectionInfo, ConstraintError> {
        self.project_with(
            &mut CellProjectionWorkspace::new(),
            preview,
            velocities,
            masses,
            h,
            tolerance,
        )
    }

    /// The Gauss-Seidel sweeps of [`CellVolumeConstraints::project`].
    pub(crate) fn project_gauss_seidel(
        &self,
        preview: &mut [Point3<f64>],
        velocities: &mut [Vector3<f64>],
        masses: &[f64],
        h: f64,
        tolerance: f64,
    ) -> Result<ProjectionInfo, ConstraintError> {
        if let Some(e) = self.find_inverted(preview) {
            return Err(e);
        }
        let (initial_error, _) = self.max_relative_error(preview);
        let mut info = ProjectionInfo {
            sweeps: 0,
            initial_error,
            final_error: initial_error,
        };
        if initial_error <= tolerance {
            return Ok(info);
        }
        // Largest errors after each sweep, for the adaptive over-relaxation.
        let mut omega = self.params.over_relaxation;
        let mut history: Vec<f64> = vec![initial_error];
        let mut adapted_at: Option<usize> = None;
        for sweep in 1..=self.params.max_sweeps {
            for (c, cell) in self.cells.iter().enumerate() {
                let v = cell_volume(preview, &self.tets[c]);
                if v.is_nan() || v <= 0.0 {
                    return Err(ConstraintError::Inverted {
                        cell: c,
                        tet: 0,
                        volume: v,
                    });
                }
                // A fixed corner (infinite mass) cannot follow a scaling about the centre: such
                // a cell is corrected along the gradient, where that corner's weight is zero.
                if self.params.correction == CellCorrection::Gradient
                    || cell.iter().any(|&i| masses[i] == f64::INFINITY)
                {
                    self.gradient_correction(c, v, omega, preview, velocities, masses, h);
                    continue;
                }
                let lambda = if omega == 1.0 {
                    (self.rest_volumes[c] / v).cbrt()
                } else {
                    (self.rest_volumes[c] / v).powf(omega / 3.0)
                };
                let centre = self.centre(preview, masses, cell);
                for &i in cell {
                    let dx = (preview[i].coords - centre) * (lambda - 1.0);
                    preview[i] += dx;
                    velocities[i] += dx / h;
                }
            }
            if let Some(e) = self.find_inverted(preview) {
                return Err(e);
            }
            let (err, cell) = self.max_relative_error(preview);
            info.sweeps = sweep;
            info.final_error = err;
            if err <= tolerance {
                return Ok(info);
            }
            if self.params.adaptive_relaxation {
                history.push(err);
                if let Some(next) = adaptive_step(&history, omega, &mut adapted_at) {
                    omega = next;
                }
            }
            if sweep == self.params.max_sweeps {
                return Err(ConstraintError::CellVolumeNotConverged {
                    sweeps: sweep,
                    max_error: err,
                    cell,
                });
            }
        }
        Ok(info)
    }

    /// One mass-weighted gradient step for cell `c` of current volume `v` (see
    /// [`CellCorrection::Gradient`]), scaled by the over-relaxation factor `omega`.
    #[allow(clippy::too_many_arguments)]
    fn gradient_correction(
        &self,
        c: usize,
        v: f64,
        omega: f64,
        preview: &mut [Point3<f64>],
        velocities: &mut [Vector3<f64>],
        masses: &[f64],
        h: f64,
    ) {
        let cell = &self.cells[c];
        let mut grad = [Vector3::zeros(); 8];
        crate::cell_global::volume_and_gradient(preview, cell, &self.tets[c], &mut grad);
        let denom: f64 = cell
            .iter()
            .zip(&grad)
            .map(|(&i, g)| g.norm_squared() / masses[i])
            .sum();
        if denom.is_nan() || denom <= 0.0 {
            return;
        }
        let s = omega * (v - self.rest_volumes[c]) / denom;
        for (&i, g) in cell.iter().zip(&grad) {
            let dx = -g * (s / masses[i]);
            preview[i] += dx;
            velocities[i] += dx / h;
        }
    }

    fn centre(&self, x: &[Point3<f64>], masses: &[f64], cell: &[usize; 8]) -> Vector3<f64> {
        match self.params.centre {
            CellCentre::Arithmetic => {
                cell.iter().fold(Vector3::zeros(), |a, &i| a + x[i].coords) / 8.0
            }
            CellCentre::MassWeighted => {
                let m: f64 = cell.iter().map(|&i| masses[i]).sum();
                cell.iter()
                    .fold(Vector3::zeros(), |a, &i| a + x[i].coords * masses[i])
                    / m
            }
        }
    }
}

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

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use balloon_test_support::{
        Rng, assert_second_order, check_gradient, check_jacobian, taylor_remainder_orders,
    };

    /// Particles, cells and tetrahedra of a lattice block.
    pub(crate) type Block = (Vec<Point3<f64>>, Vec<[usize; 8]>, Vec<[[usize; 4]; 5]>);

    /// An `nx x ny x nz` block of cells of edge 0.1 m with the lattice's alternating five-tet
    /// split (parity `(i + j + k) % 2`), built from the lattice's corner and tetrahedron tables
    /// without running the generator.
    pub(crate) fn block3(nx: usize, ny: usize, nz: usize) -> Block {
        use balloon_mesh::lattice::{CELL_TETS as T, CORNERS as C};
        let vid = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
        let mut x = Vec::new();
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    x.push(Point3::new(i as f64, j as f64, k as f64) * 0.1);
                }
            }
        }
        let (mut cells, mut tets) = (Vec::new(), Vec::new());
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let corners = C.map(|[a, b, c]| vid(i + a, j + b, k + c));
                    let mut ts = T[(i + j + k) % 2].map(|t| t.map(|l| corners[l]));
                    for t in &mut ts {
                        if signed_tet_volume(&x[t[0]], &x[t[1]], &x[t[2]], &x[t[3]]) < 0.0 {
                            t.swap(2, 3);
                        }
                    }
                    cells.push(corners);
                    tets.push(ts);
                }
            }
        }
        (x, cells, tets)
    }

    /// A row of `nx` cells.
    fn block(nx: usize) -> Block {
        block3(nx, 1, 1)
    }

    fn perturbed(x: &[Point3<f64>], amp: f64, seed: u64) -> Vec<Point3<f64>> {
        let mut rng = Rng::new(seed);
        x.iter()
            .map(|p| p + Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * amp)
            .collect()
    }

    #[test]
    fn projection_restores_every_cell_volume_and_conserves_momentum() {
        // Equal masses and the arithmetic centre: each cell's impulses sum to zero (Sec. 4), so
        // total momentum cannot change, while every cell returns to its rest volume.
        let (x0, cells, tets) = block(4);
        let c = CellVolumeConstraints::new(cells, tets, &x0, CellVolumeParams::default()).unwrap();
        let mut x = perturbed(&x0, 0.01, 3);
        let mut v = vec![Vector3::new(0.3, -0.1, 0.2); x.len()];
        let m = vec![0.5; x.len()];
        let p0: Vector3<f64> = v.iter().zip(&m).map(|(v, m)| v * *m).sum();
        let h = 1e-2;
        let info = c.project(&mut x.clone(), &mut v.clone(), &m, h).unwrap();
        assert!(info.initial_error > 1e-3);
        // Over-relaxed sweeps reach the same tolerance and also conserve momentum.
        let sor = CellVolumeConstraints {
            params: CellVolumeParams {
                over_relaxation: 1.3,
                ..CellVolumeParams::default()
            },
            ..c.clone()
        };
        let (mut xs, mut vs) = (x.clone(), v.clone());
        sor.project(&mut xs, &mut vs, &m, h).unwrap();
        assert!(sor.max_relative_error(&xs).0 <= 1e-10);
        let ps: Vector3<f64> = vs.iter().zip(&m).map(|(v, m)| v * *m).sum();
        assert!((ps - p0).norm() < 1e-12);
        let info = c.project(&mut x, &mut v, &m, h).unwrap();
        assert!(info.final_error <= 1e-10);
        let (err, _) = c.max_relative_error(&x);
        assert!(err <= 1e-10);
        let p1: Vector3<f64> = v.iter().zip(&m).map(|(v, m)| v * *m).sum();
        assert!(
            (p1 - p0).norm() < 1e-12,
            "momentum drift {}",
            (p1 - p0).norm()
        );
    }

    #[test]
    fn adaptive_relaxation_cuts_the_sweeps_of_a_large_block() {
        // 12 x 12 x 6 = 864 cells (the CLI's lattices have about 1000), every particle moved by
        // up to 1 mm: the paper's sweeps (omega = 1) converge by a steady factor close to 1 per
        // sweep, so they need hundreds; the adaptive rule measures that factor and switches to
        // Young's omega. Both end within the tolerance with the momentum unchanged.
        let (x0, cells, tets) = block3(12, 12, 6);
        let params = |adaptive| CellVolumeParams {
            adaptive_relaxation: adaptive,
            max_sweeps: 5000,
            ..CellVolumeParams::default()
        };
        let m = vec![0.5; x0.len()];
        let h = 1e-3;
        let x = perturbed(&x0, 1e-3, 11);
        let v0 = vec![Vector3::new(0.1, 0.0, -0.2); x.len()];
        let p0: Vector3<f64> = v0.iter().zip(&m).map(|(v, m)| v * *m).sum();
        let mut sweeps = Vec::new();
        for adaptive in [false, true] {
            let c = CellVolumeConstraints::new(cells.clone(), tets.clone(), &x0, params(adaptive))
                .unwrap();
            let (mut xs, mut vs) = (x.clone(), v0.clone());
            let info = c.project(&mut xs, &mut vs, &m, h).unwrap();
            assert!(c.max_relative_error(&xs).0 <= 1e-10);
            let p: Vector3<f64> = vs.iter().zip(&m).map(|(v, m)| v * *m).sum();
            // Round-off over hundreds of sweeps of about 1000 particles: relative to M * 1 m/s.
            let mass: f64 = m.iter().sum();
            assert!(
                (p - p0).norm() < 1e-13 * mass,
                "momentum {}",
                (p - p0).norm()
            );
            sweeps.push(info.sweeps);
        }
        eprintln!("sweeps: paper {}, adaptive {}", sweeps[0], sweeps[1]);
        assert!(
            sweeps[1] * 3 < sweeps[0],
            "adaptive {} vs plain {} sweeps",
            sweeps[1],
            sweeps[0]
        );
        assert!((optimal_over_relaxation(0.98) - 2.0 / (1.0 + 0.02f64.sqrt())).abs() < 1e-15);
        assert_eq!(optimal_over_relaxation(0.0), 1.0);
        assert_eq!(optimal_over_relaxation(1.2), 1.0);
        assert_eq!(optimal_over_relaxation(0.9999), MAX_ADAPTIVE_OMEGA);
        let global = CellVolumeParams {
            adaptive_relaxation: true,
            ..CellVolumeParams::global()
        };
        assert!(CellVolumeConstraints::new(cells, tets, &x0, global).is_err());
    }

    #[test]
    fn gauss_seidel_preset_converges_where_the_papers_sweeps_hit_the_limit() {
        // The 864-cell block of the test above: at the default limit of 500 sweeps the paper's
        // sweeps (1458 needed) stop with CellVolumeNotConverged; `gauss_seidel()` (gradient correction,
        // adaptive relaxation) ends within the tolerance, keeping the momentum.
        let (x0, cells, tets) = block3(12, 12, 6);
        let m = vec![0.5; x0.len()];
        let x = perturbed(&x0, 1e-3, 11);
        let v0 = vec![Vector3::new(0.1, 0.0, -0.2); x.len()];
        let paper = CellVolumeConstraints::new(
            cells.clone(),
            tets.clone(),
            &x0,
            CellVolumeParams::default(),
        )
        .unwrap();
        let r = paper.project(&mut x.clone(), &mut v0.clone(), &m, 1e-3);
        assert!(
            matches!(r, Err(ConstraintError::CellVolumeNotConverged { .. })),
            "{r:?}"
        );
        let preset = CellVolumeParams::gauss_seidel();
        assert_eq!(preset.max_sweeps, CellVolumeParams::default().max_sweeps);
        let c = CellVolumeConstraints::new(cells, tets, &x0, preset).unwrap();
        let (mut xs, mut vs) = (x, v0.clone());
        let info = c.project(&mut xs, &mut vs, &m, 1e-3).unwrap();
        assert!(info.sweeps < preset.max_sweeps, "{info:?}");
        assert!(c.max_relative_error(&xs).0 <= 1e-10);
        let p0: Vector3<f64> = v0.iter().zip(&m).map(|(v, m)| v * *m).sum();
        let p: Vector3<f64> = vs.iter().zip(&m).map(|(v, m)| v * *m).sum();
        assert!((p - p0).norm() < 1e-13 * m.iter().sum::<f64>());
    }

    #[test]
    fn mass_weighted_centre_conserves_momentum_with_unequal_masses() {
        let (x0, cells, tets) = block(3);
        let params = CellVolumeParams {
            centre: CellCentre::MassWeighted,
            ..CellVolumeParams::default()
        };
        let c = CellVolumeConstraints::new(cells, tets, &x0, params).unwrap();
        let mut x = perturbed(&x0, 0.01, 5);
        let mut v = vec![Vector3::zeros(); x.len()];
        let mut rng = Rng::new(9);
        let m: Vec<f64> = (0..x.len()).map(|_| 1.0 + 0.9 * rng.next_f64()).collect();
        c.project(&mut x, &mut v, &m, 1e-2).unwrap();
        let p: Vector3<f64> = v.iter().zip(&m).map(|(v, m)| v * *m).sum();
        let scale: f64 = v.iter().zip(&m).map(|(v, m)| v.norm() * m).sum();
        assert!(scale > 1e-3);
        assert!(p.norm() < 1e-12 * scale.max(1.0), "momentum {}", p.norm());
    }

    #[test]
    fn velocity_change_matches_displacement() {
        // p + h v must equal the corrected preview: the velocity carries the correction.
        let (x0, cells, tets) = block(2);
        let c = CellVolumeConstraints::new(cells, tets, &x0, CellVolumeParams::default()).unwrap();
        let p = perturbed(&x0, 0.005, 11);
        let mut rng = Rng::new(12);
        let mut v: Vec<Vector3<f64>> = (0..p.len())
            .map(|_| Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 0.2)
            .collect();
        let h = 5e-3;
        let mut x: Vec<Point3<f64>> = p.iter().zip(&v).map(|(p, v)| p + v * h).collect();
        c.project(&mut x, &mut v, &vec![1.0; p.len()], h).unwrap();
        for i in 0..p.len() {
            assert!((p[i] + v[i] * h - x[i]).norm() < 1e-14);
        }
    }

    #[test]
    fn inverted_preview_is_reported_with_cell_and_tet() {
        let (x0, cells, tets) = block(2);
        let c = CellVolumeConstraints::new(cells, tets, &x0, CellVolumeParams::default()).unwrap();
        let mut x = x0.clone();
        // Push corner 6 of cell 0 through the opposite face.
        x[c.cells[0][6]] = Point3::new(-0.05, -0.05, -0.05);
        let mut v = vec![Vector3::zeros(); x.len()];
        let e = c
            .project(&mut x, &mut v, &vec![1.0; x0.len()], 1e-2)
            .unwrap_err();
        assert!(
            matches!(e, ConstraintError::Inverted { cell: 0, .. }),
            "{e}"
        );
    }

    #[test]
    fn volume_impulses_do_not_create_kinetic_energy() {
        // For a free body with random velocities and no springs, the impulses only remove the
        // velocity component that changes the cell volumes (for cube-like cells the volume
        // gradient is radial about the centre), so kinetic energy cannot grow.
        let (x0, cells, tets) = block(4);
        let c = CellVolumeConstraints::new(cells, tets, &x0, CellVolumeParams::default()).unwrap();
        for seed in 1..20 {
            let mut rng = Rng::new(seed);
            let mut v: Vec<Vector3<f64>> = (0..x0.len())
                .map(|_| Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()))
                .collect();
            let ke = |v: &[Vector3<f64>]| v.iter().map(|v| 0.5 * v.norm_squared()).sum::<f64>();
            let before = ke(&v);
            let h = 1e-3;
            let mut x: Vec<Point3<f64>> = x0.iter().zip(&v).map(|(p, v)| p + v * h).collect();
            c.project(&mut x, &mut v, &vec![1.0; x0.len()], h).unwrap();
            let after = ke(&v);
            assert!(
                after <= before * (1.0 + 1e-12),
                "seed {seed}: {before} -> {after}"
            );
        }
    }

    #[test]
    fn gradient_correction_restores_volume_and_conserves_momentum_for_unequal_masses() {
        // sum_i grad_i V = 0 (translation invariance), so the impulses m_i dv_i = -grad_i V s / h
        // sum to zero whatever the masses, and the kinetic energy does not grow.
        let (x0, cells, tets) = block(4);
        let params = CellVolumeParams {
            correction: CellCorrection::Gradient,
            ..CellVolumeParams::default()
        };
        let c = CellVolumeConstraints::new(cells, tets, &x0, params).unwrap();
        let mut rng = Rng::new(3);
        let masses: Vec<f64> = (0..x0.len()).map(|_| 1.0 + 0.5 * rng.next_f64()).collect();
        let mut v: Vec<Vector3<f64>> = (0..x0.len())
            .map(|_| Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()))
            .collect();
        let momentum = |v: &[Vector3<f64>]| {
            v.iter()
                .zip(&masses)
                .fold(Vector3::zeros(), |a, (v, m)| a + v * *m)
        };
        let ke = |v: &[Vector3<f64>]| {
            v.iter()
                .zip(&masses)
                .map(|(v, m)| 0.5 * m * v.norm_squared())
                .sum::<f64>()
        };
        let (p0, e0) = (momentum(&v), ke(&v));
        let h = 1e-2;
        let mut x: Vec<Point3<f64>> = x0.iter().zip(&v).map(|(p, v)| p + v * h).collect();
        let info = c.project(&mut x, &mut v, &masses, h).unwrap();
        assert!(
            info.initial_error > 1e-3 && info.final_error <= 1e-10,
            "{info:?}"
        );
        assert!(
            (momentum(&v) - p0).norm() < 1e-12,
            "momentum {:?} vs {:?}",
            momentum(&v),
            p0
        );
        assert!(ke(&v) <= e0, "{e0} -> {}", ke(&v));
    }

    #[test]
    fn spring_force_is_minus_energy_gradient_and_differential_matches() {
        let (x0, cells, _) = block(2);
        let params = SpringParams {
            edge_stiffness: 100.0,
            diagonal_stiffness: 30.0,
            edge_damping: 0.0,
            diagonal_damping: 0.0,
        };
        let s = CellSprings::new(&cells, &x0, &params);
        assert_eq!(s.springs.len(), 32);
        let x = perturbed(&x0, 0.02, 21);
        let flat: Vec<f64> = x.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
        let unflat = |f: &[f64]| -> Vec<Point3<f64>> {
            f.chunks_exact(3)
                .map(|c| Point3::new(c[0], c[1], c[2]))
                .collect()
        };
        let zero_v = vec![Vector3::zeros(); x.len()];
        let force = |f: &[f64]| -> Vec<f64> {
            let mut out = vec![Vector3::zeros(); x.len()];
            s.add_forces(&unflat(f), &zero_v, &mut out);
            out.iter().flat_map(|v| [v.x, v.y, v.z]).collect()
        };
        check_gradient(
            |f| s.energy(&unflat(f)),
            |f| force(f).iter().map(|g| -g).collect(),
            &flat,
            1e-6,
            1e-6,
        );
        // Taylor remainder of the energy along a random direction falls 4x per halving.
        let dir = Rng::new(22).vector(flat.len());
        let ratios = taylor_remainder_orders(
            |f| s.energy(&unflat(f)),
            |f| force(f).iter().map(|g| -g).collect(),
            &flat,
            &dir,
            1e-3,
        );
        assert_second_order(&ratios);
        check_jacobian(
            force,
            |f, dx| {
                let dxv: Vec<Vector3<f64>> = dx
                    .chunks_exact(3)
                    .map(|c| Vector3::new(c[0], c[1], c[2]))
                    .collect();
                s.force_differential(&unflat(f), &dxv)
                    .iter()
                    .flat_map(|v| [v.x, v.y, v.z])
                    .collect()
            },
            &flat,
            1e-6,
            1e-6,
            4,
        );
    }

    #[test]
    fn damping_dissipates_and_forces_sum_to_zero() {
        // Damping forces oppose the relative velocity: their power is never positive; all spring
        // forces come in equal and opposite pairs, so they sum to zero.
        let (x0, cells, _) = block(2);
        let s = CellSprings::new(&cells, &x0, &SpringParams::default());
        let x = perturbed(&x0, 0.01, 31);
        let mut rng = Rng::new(32);
        let v: Vec<Vector3<f64>> = (0..x.len())
            .map(|_| Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()))
            .collect();
        let mut f_all = vec![Vector3::zeros(); x.len()];
        s.add_forces(&x, &v, &mut f_all);
        let mut f_el = vec![Vector3::zeros(); x.len()];
        s.add_forces(&x, &vec![Vector3::zeros(); x.len()], &mut f_el);
        let power: f64 = (0..x.len()).map(|i| (f_all[i] - f_el[i]).dot(&v[i])).sum();
        assert!(power <= 0.0);
        let net: Vector3<f64> = f_all.iter().sum();
        assert!(net.norm() < 1e-9);
        assert!(
            SpringParams {
                edge_stiffness: -1.0,
                ..SpringParams::default()
            }
            .validate()
            .unwrap_err()
            .to_string()
            .contains("edge_stiffness")
        );
    }
}
