//! The options and the report of the static rest shape: [`StaticOptions`] (how the gas is
//! held, [`StaticControl`], and the tolerances of the outer loop), [`StaticReport`] and one
//! [`OuterRecord`] per outer iteration.

use balloon_integrate::statics::{PhaseTimes, Stability, StaticInfo, StaticParams};
use serde::{Deserialize, Serialize};

#[cfg(doc)]
use crate::ShellSimulation;

/// How the gas is held in a static solve.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StaticControl {
    /// The simulation's own gas model at the current time: a given amount (ideal gas, pump)
    /// or a given pressure (constant pressure).
    #[default]
    Gas,
    /// A given enclosed volume, m^3; the gauge pressure is its Lagrange multiplier.
    Volume {
        /// The target gas volume, m^3 (positive).
        target: f64,
    },
}

/// Options of [`ShellSimulation::solve_static`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct StaticOptions {
    /// How the gas is held.
    pub control: StaticControl,
    /// The Newton solver's parameters (tolerance, iterations per load stage, linear solver,
    /// shifts, continuation).
    pub solver: StaticParams,
    /// Include the pressure follower term in the tangent (default `true`: the exact Hessian).
    pub follower_term: bool,
    /// Most outer iterations (thickness fixed point and multiplier updates; default 60).
    pub max_outer_iterations: usize,
    /// Relative thickness change of one projection below which the thickness is at its fixed
    /// point (default `1e-8`).
    pub thickness_tolerance: f64,
    /// Relative volume error `|V - V_t| / V_t` at which the volume control is met (default
    /// `1e-8`).
    pub volume_tolerance: f64,
    /// Compute the smallest eigenvalue of the equilibrium's stiffness
    /// ([`StaticReport::stability`], [`balloon_integrate::statics::StaticSolver::stability`]):
    /// whether the equilibrium is stable under the load as held (the volume under volume
    /// control, the gas otherwise). Default `false` (one more factorisation and a few tens of
    /// linear solves on it).
    pub stability: bool,
}

impl Default for StaticOptions {
    fn default() -> Self {
        Self {
            control: StaticControl::Gas,
            solver: StaticParams::default(),
            follower_term: true,
            max_outer_iterations: 60,
            thickness_tolerance: 1e-8,
            volume_tolerance: 1e-8,
            stability: false,
        }
    }
}

/// What [`ShellSimulation::solve_static`] found.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StaticReport {
    /// Whether the equilibrium, the thickness fixed point and the volume target were all met
    /// (always `true` for a returned report; failures are errors).
    pub converged: bool,
    /// Relative Newton residual of the last solve (the dynamic Newton's measure).
    pub relative_residual: f64,
    /// Newton iterations over all solves.
    pub newton_iterations: usize,
    /// Outer iterations (solves).
    pub outer_iterations: usize,
    /// Load-continuation stages over all solves (1 per solve when no continuation was
    /// needed).
    pub load_steps: usize,
    /// Line-search cuts over all solves.
    pub line_search_cuts: usize,
    /// Enclosed gas volume, m^3.
    pub gas_volume: f64,
    /// Gauge pressure, Pa (the multiplier under volume control).
    pub gauge_pressure: f64,
    /// `|V - V_t| / V_t` under volume control (0 otherwise).
    pub volume_error: f64,
    /// Relative thickness change of the last projection.
    pub thickness_change: f64,
    /// Smallest element area over its rest area.
    pub min_area_stretch: f64,
    /// Largest element area over its rest area.
    pub max_area_stretch: f64,
    /// Mean thickness, m.
    pub thickness_mean: f64,
    /// Smallest thickness, m.
    pub thickness_min: f64,
    /// Largest thickness, m.
    pub thickness_max: f64,
    /// Shell material volume over its rest value.
    pub shell_volume_ratio: f64,
    /// Wall-clock time, ms.
    pub solve_ms: f64,
    /// Numeric factorisations over all solves.
    #[serde(default)]
    pub factorizations: usize,
    /// Linear-solver iterations over all solves.
    #[serde(default)]
    pub linear_iterations: usize,
    /// Wall-clock time per phase over all solves and projections.
    #[serde(default)]
    pub times: PhaseTimes,
    /// One record per outer iteration.
    #[serde(default)]
    pub outer: Vec<OuterRecord>,
    /// The last solve's details (energies, residuals, shift, factorisations).
    pub last_solve: StaticInfo,
    /// With [`StaticOptions::stability`]: the smallest eigenvalue of the stiffness at the
    /// equilibrium (rigid motions removed when nothing is pinned; its mode left out of the
    /// report, [`StabilityReport`]).
    #[serde(default)]
    pub stability: Option<StabilityReport>,
}

/// The stability of a static equilibrium as [`StaticReport`] carries it (the
/// [`Stability`] without its mode).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StabilityReport {
    /// The smallest eigenvalue `lambda` of `K y = lambda M y`, 1/s^2: negative when the
    /// equilibrium is unstable (`sqrt(-lambda)` is the growth rate of its mode).
    pub smallest_eigenvalue: f64,
    /// `lambda` relative to the stiffness scale `|diag K| / |m|`.
    pub relative_eigenvalue: f64,
    /// The second smallest eigenvalue, 1/s^2, when resolved.
    pub second_eigenvalue: Option<f64>,
    /// Relative residual of the eigenpair on the operator.
    pub residual: f64,
    /// Linear solves (Lanczos steps).
    pub steps: usize,
}

impl StabilityReport {
    /// Whether the equilibrium is unstable: the smallest eigenvalue below `-1e-9` of the
    /// stiffness scale (round-off of a neutral mode stays above).
    pub fn unstable(&self) -> bool {
        self.relative_eigenvalue < -1e-9
    }
}

impl From<&Stability> for StabilityReport {
    fn from(s: &Stability) -> Self {
        Self {
            smallest_eigenvalue: s.smallest_eigenvalue,
            relative_eigenvalue: s.relative_eigenvalue,
            second_eigenvalue: s.second_eigenvalue,
            residual: s.residual,
            steps: s.steps,
        }
    }
}

/// One outer iteration of [`ShellSimulation::solve_static`] (the `statics` module docs,
/// "Thickness at rest").
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct OuterRecord {
    /// The relative residual the Newton solve was asked for.
    pub tolerance: f64,
    /// The relative residual it reached.
    pub relative_residual: f64,
    /// Newton iterations of the solve.
    pub newton_iterations: usize,
    /// Linear solves of the solve retried with a larger shift (indefinite matrix).
    pub regularized_solves: usize,
    /// Numeric factorisations of the solve.
    pub factorizations: usize,
    /// Relative thickness change of the projection of its result.
    pub thickness_change: f64,
    /// Whether the next thickness was extrapolated (Anderson) rather than the projection's.
    pub accelerated: bool,
}
