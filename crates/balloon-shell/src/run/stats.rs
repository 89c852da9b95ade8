//! The statistics of one step of a running shell: [`ShellStepStats`], and the work summed
//! over its sub-steps.

use balloon_integrate::PhaseTimes;
use serde::{Deserialize, Serialize};

/// What one step did and where the balloon is.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ShellStepStats {
    /// Step number, 1-based: the first step is 1 (the state after `step` steps).
    pub step: usize,
    /// Simulation time at the end of the step, s.
    pub time: f64,
    /// Enclosed gas volume, m^3.
    pub gas_volume: f64,
    /// Gauge pressure `p - p_ambient`, Pa.
    pub gauge_pressure: f64,
    /// Shell material volume / rest shell material volume (1 when the projection is exact).
    pub shell_volume_ratio: f64,
    /// Newton iterations performed, including those of sub-step attempts that did not
    /// converge and were retried at half the size.
    pub newton_iterations: usize,
    /// Linear (CG) iterations summed over the Newton iterations (0 for Cholesky).
    pub linear_iterations: usize,
    /// Numeric sparse Cholesky factorisations done by the linear solver in the accepted
    /// sub-steps of this step (`StepInfo::factorizations`; attempts rolled back are not
    /// counted).
    #[serde(default)]
    pub factorizations: usize,
    /// Relative Newton residual of the result (`StepInfo::relative_residual`: the residual
    /// force over the force scale), the largest over the sub-steps.
    pub newton_residual: f64,
    /// Newton steps shortened by the line search (halvings), summed over the sub-steps.
    pub line_search_cuts: usize,
    /// Linear solves retried with a larger mass shift because the Newton matrix was indefinite
    /// (`StepInfo::regularized_solves`), summed over the accepted sub-steps.
    #[serde(default)]
    pub regularized_solves: usize,
    /// The smallest sub-step taken, s (`dt` when the step was not split).
    pub dt_used: f64,
    /// Sub-steps rolled back and retried at half the size in this step.
    pub halvings: usize,
    /// Projection iterations.
    pub projection_iterations: usize,
    /// Sub-steps the step took: 1 normally, more when it had to be halved after a numerical
    /// failure or started from a sub-step size a hard earlier step left (see
    /// `max_step_halvings` of [`ShellSimulation::new`](crate::ShellSimulation::new)); they
    /// add up to `dt`.
    pub substeps: usize,
    /// Largest vertex speed, m/s.
    pub max_speed: f64,
    /// Relative gas-volume change over the step, |dV| / V.
    pub volume_change: f64,
    /// Mean / min / max thickness, m.
    pub thickness_mean: f64,
    /// Minimum thickness, m.
    pub thickness_min: f64,
    /// Maximum thickness, m.
    pub thickness_max: f64,
    /// Wall-clock time of the step, ms.
    pub step_ms: f64,
    /// Where the step's time went, ms: the integrator's phases (forces, energies of the line
    /// search, assembly, factorisations, linear solves) and the shell-volume projection, over
    /// every sub-step including those rolled back and retried. `step_ms` minus their sum is
    /// the rest (state checks, statistics, copies).
    #[serde(default)]
    pub times: PhaseTimes,
}

/// Work summed over the sub-steps of one step.
#[derive(Debug, Default)]
pub(crate) struct StepTotals {
    pub(crate) newton_iterations: usize,
    pub(crate) linear_iterations: usize,
    pub(crate) factorizations: usize,
    pub(crate) newton_residual: f64,
    pub(crate) line_search_cuts: usize,
    pub(crate) regularized_solves: usize,
    pub(crate) projection_iterations: usize,
    pub(crate) substeps: usize,
    pub(crate) halvings: usize,
    pub(crate) min_dt: f64,
}
