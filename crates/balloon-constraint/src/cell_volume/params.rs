//! How the cell constraints are solved: [`CellVolumeParams`] with its choices
//! ([`CellCentre`], [`CellCorrection`], [`CellSolver`]), the adaptive over-relaxation rule, and
//! what a projection reports ([`ProjectionInfo`]).

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
    /// The paper's correction (Diziol, Bender and Bayer 2011, Sec. 4): scale the cell about its
    /// centre by `lambda = cbrt(V0 / V)`, exact for that cell in one visit. Its direction `x_i - c`
    /// is not the constraint gradient, so once cells are sheared it can add kinetic energy
    /// (measured: about 1e-5 relative per step on a free body with random velocities).
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
    /// The paper's Gauss-Seidel sweeps, one cell at a time (Diziol, Bender and Bayer 2011, Sec. 4).
    /// Sweeps needed grow with the lattice size.
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
    /// Adaptive over-relaxation of the Gauss-Seidel sweeps (not in the paper; default `false`). The
    /// sweeps keep the paper's per-cell correction (Eq. 2-4, scaled by `lambda^omega`), but `omega`
    /// is chosen from the observed convergence: the first `2 ADAPT_WINDOW` sweeps run at
    /// `over_relaxation`; the factor `rho` by which the largest cell error shrank per sweep over
    /// the second window of them then gives Young's optimum, `omega = 2 / (1 + sqrt(1 - rho))` (for
    /// a consistently ordered linear system the Gauss-Seidel factor is `rho = mu^2`, `mu` the
    /// Jacobi one, and SOR at this `omega` converges by `omega - 1` per sweep), at most
    /// [`MAX_ADAPTIVE_OMEGA`]. If the error then stops shrinking over a window, `omega - 1` is
    /// halved (see `adaptive_step`). Every cell still ends within `tolerance`, and the per-cell
    /// impulses still sum to zero (momentum is kept); only the number of sweeps (and the point
    /// reached on the constraint set) changes. Measured on a block of 864 cells with every particle
    /// moved by up to 1 mm (`adaptive_relaxation_cuts_the_sweeps_of_a_large_block`): 1458 sweeps at
    /// `omega = 1`, 437 adaptive (it chose 1.51), against 760, 434, 276, 249, 382 and 767 at the
    /// fixed `omega` 1.3, 1.5, 1.6, 1.7, 1.8 and 1.9: the early estimate of `rho` is low (the
    /// slowest error components dominate only later), which keeps `omega` on the safe side of the
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
pub(crate) fn adaptive_step(
    history: &[f64],
    omega: f64,
    adapted: &mut Option<usize>,
) -> Option<f64> {
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

    /// Gauss-Seidel sweeps set up to converge on lattices of about a thousand cells: the gradient
    /// correction and [`CellVolumeParams::adaptive_relaxation`], other settings at their defaults.
    /// The paper's sweeps ([`CellVolumeParams::default`]: scaling correction, `omega = 1`) reduce
    /// the largest cell error by only about 2 % per sweep there and stop at the 500-sweep limit
    /// within 6-35 steps of `balloon volumetric`'s drop-sphere scene on the teddy, bunny, spot and
    /// armadillo (the torus ran its first 400 steps at 157 sweeps per step); these settings run
    /// 2000 steps on all five (`cargo xtask validate --only drop-sphere`, 93-344 sweeps per step);
    /// with the scaling correction and adaptive relaxation the impact inverts a cell (bunny step
    /// 1417, spot step 970), as the scaling adds kinetic energy. This is the default of `balloon
    /// volumetric --volume-solver gauss-seidel`.
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
