//! The error of a running shell ([`ShellError`]): bad input before any work, and failures of a
//! step or of the static solve, naming the step and the element or quantity. Messages name
//! parameters by their Rust names in backticks (`` `dt` ``, `` `newton_iterations` ``), which
//! a command line or a binding maps to its own spelling.

use balloon_integrate::decorators::DecoratorError;
use balloon_integrate::implicit::IntegrateError;
use thiserror::Error;

/// Gas volume growth beyond this factor of the rest volume is reported as a runaway
/// ([`ShellError::RunawayVolume`]).
pub const RUNAWAY_VOLUME_FACTOR: f64 = 1.0e4;

/// Errors of the shell balloon: bad input (before any work) and failures during a run (naming
/// the step and the element or quantity).
#[derive(Debug, Error)]
pub enum ShellError {
    /// The mesh is not a closed, manifold, outward-oriented surface.
    #[error("invalid mesh: {0}")]
    Mesh(#[from] balloon_mesh::MeshError),
    /// A parameter is out of range.
    #[error("invalid parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name, as the builder, the setter or the options struct names it
        /// (`dt`, `gauge_pressure`, `pinned_vertices`, `thickness_tolerance`).
        name: &'static str,
        /// Its value.
        value: String,
        /// The allowed range.
        reason: String,
    },
    /// A material parameter is invalid.
    #[error("invalid material: {0}")]
    Material(#[from] balloon_material::MaterialError),
    /// A rest element is degenerate.
    #[error("element {element}: {source}")]
    Element {
        /// Triangle index.
        element: usize,
        /// What is wrong.
        #[source]
        source: balloon_element::ElementError,
    },
    /// The gas model could not be built or evaluated.
    #[error("gas: {0}")]
    Gas(#[from] balloon_gas::GasError),
    /// The Newton solve failed.
    #[error("step {step} (t = {time:.6} s): {source}")]
    Integrate {
        /// Step number (1-based) that failed.
        step: usize,
        /// Simulation time at the start of the step.
        time: f64,
        /// What failed.
        #[source]
        source: IntegrateError,
    },
    /// The volume projection failed.
    #[error("step {step}: volume projection: {source}")]
    Projection {
        /// Step number (1-based).
        step: usize,
        /// What failed.
        #[source]
        source: balloon_constraint::ConstraintError,
    },
    /// The gas volume ran away (beyond [`RUNAWAY_VOLUME_FACTOR`] times the rest volume): a
    /// physical runaway, not retried with smaller steps. (A volume that is not positive or not
    /// finite is [`ShellError::Diverged`], retried like any numerical failure.)
    #[error(
        "step {step} (t = {time:.6} s): diverged: gas volume: {volume:e} m^3 vs rest {rest_volume:e} m^3 (runaway above {RUNAWAY_VOLUME_FACTOR}x): the pressure exceeds what the shell can hold (e.g. above the neo-Hookean limit point) or the run is unstable"
    )]
    RunawayVolume {
        /// Step number (1-based).
        step: usize,
        /// Simulation time at the start of the step.
        time: f64,
        /// The enclosed volume reached, m^3.
        volume: f64,
        /// The rest volume, m^3.
        rest_volume: f64,
    },
    /// Newton did not converge even at the smallest sub-step the step halvings allow.
    #[error(
        "step {step} (t = {time:.6} s): Newton did not converge: relative residual {residual:.3e} after {iterations} iterations (tolerance {tolerance:e}) at a sub-step of {dt:e} s, the smallest allowed ({halvings} halvings in this step, at most {max_halvings} below the step); try a smaller `dt`, more `newton_iterations`, a looser `newton_tolerance`, `tangent` = projected, or more `mass_damping`"
    )]
    NotConverged {
        /// Step number (1-based).
        step: usize,
        /// Simulation time at the start of the failed sub-step, s.
        time: f64,
        /// The sub-step size that failed last, s.
        dt: f64,
        /// Halvings tried in this step (a sub-step size reached in an earlier step carries
        /// over, so this can be 0 at the smallest size).
        halvings: usize,
        /// The most halvings allowed below the step (`max_step_halvings`).
        max_halvings: usize,
        /// Newton iterations of the last attempt.
        iterations: usize,
        /// Its final relative residual.
        residual: f64,
        /// The Newton tolerance.
        tolerance: f64,
    },
    /// The static solve (`ShellSimulation::solve_static`) failed in one of its Newton solves.
    #[error(
        "static solve (outer iteration {outer}): {source}; try more `solver.max_iterations` (per load stage), a looser `solver.tolerance`, `solver.tangent` = projected, or the dynamic run (`until_converged`)"
    )]
    Static {
        /// Outer iteration (thickness fixed point / multiplier update), 0-based.
        outer: usize,
        /// Newton iterations spent before the failure, over every outer iteration and load
        /// stage (the failing solve's included).
        newton_iterations: usize,
        /// What failed (boxed: it is the largest of the errors).
        #[source]
        source: Box<balloon_integrate::statics::StaticError>,
    },
    /// The static solve's outer loop (thickness fixed point, volume multiplier) did not settle.
    #[error(
        "static solve did not settle after {outer_iterations} outer iterations: Newton residual {residual:.3e}, thickness change {thickness_change:.3e}, volume error {volume_error:.3e}; the load may be near a limit point: try volume control (`gas` = volume) or a smaller load"
    )]
    StaticNotConverged {
        /// Outer iterations done.
        outer_iterations: usize,
        /// Newton iterations over all outer iterations.
        newton_iterations: usize,
        /// Relative Newton residual of the last solve.
        residual: f64,
        /// Relative thickness change of the last projection.
        thickness_change: f64,
        /// Relative volume error under volume control (0 otherwise).
        volume_error: f64,
    },
    /// The run diverged (non-finite or inverted state).
    #[error("step {step} (t = {time:.6} s): diverged: {quantity}: {detail}")]
    Diverged {
        /// Step number (1-based).
        step: usize,
        /// Simulation time at the start of the step.
        time: f64,
        /// The quantity that diverged (e.g. "gas volume", "thickness of element 12").
        quantity: String,
        /// Numbers that explain it, and what to try.
        detail: String,
    },
}

impl ShellError {
    /// The Newton iterations a failed static solve spent ([`ShellError::Static`],
    /// [`ShellError::StaticNotConverged`]); `None` for the other errors.
    pub fn static_newton_iterations(&self) -> Option<usize> {
        match self {
            Self::Static {
                newton_iterations, ..
            }
            | Self::StaticNotConverged {
                newton_iterations, ..
            } => Some(*newton_iterations),
            _ => None,
        }
    }

    /// The relative Newton residual a failed static solve ended at, when it is known (a solve
    /// that did not converge; not one whose linear solve failed).
    pub fn static_residual(&self) -> Option<f64> {
        match self {
            Self::Static { source, .. } => match **source {
                balloon_integrate::statics::StaticError::NotConverged { residual, .. } => {
                    Some(residual)
                }
                balloon_integrate::statics::StaticError::NoEquilibrium(ref stall) => {
                    Some(stall.residual)
                }
                _ => None,
            },
            Self::StaticNotConverged { residual, .. } => Some(*residual),
            _ => None,
        }
    }

    /// A parameter of the integrator refused by its own check (`BackwardEulerParams::validate`,
    /// when building or configuring it) as [`ShellError::InvalidParameter`]; any other error
    /// of the integrator as [`ShellError::Integrate`] of step 0.
    pub fn from_integrator_setup(e: IntegrateError) -> Self {
        match e {
            IntegrateError::InvalidParameter {
                name,
                value,
                allowed,
            } => Self::InvalidParameter {
                name,
                value: value.to_string(),
                reason: format!("must be {allowed}"),
            },
            other => Self::Integrate {
                step: 0,
                time: 0.0,
                source: other,
            },
        }
    }

    /// A decorator's refusal of the setting `name` (`pinned_vertices`, `anchor_springs`) as
    /// [`ShellError::InvalidParameter`].
    pub(crate) fn from_decorator(name: &'static str, e: DecoratorError) -> Self {
        match e {
            DecoratorError::VertexOutOfRange {
                what,
                vertex,
                num_vertices,
            } => Self::InvalidParameter {
                name,
                value: vertex.to_string(),
                reason: format!("{what} {vertex}: the shell has {num_vertices} vertices"),
            },
            DecoratorError::InvalidSpring { spring } => Self::InvalidParameter {
                name,
                value: format!("{spring:?}"),
                reason: "the anchor must be finite and the stiffness finite and >= 0".into(),
            },
            DecoratorError::SizeMismatch {
                what,
                expected,
                found,
            } => Self::InvalidParameter {
                name,
                value: format!("{what} of {expected} vertices"),
                reason: format!("the shell has {found} vertices"),
            },
        }
    }
}

/// Checks a time step (s) for a builder and [`crate::ShellSimulation::set_dt`] with the
/// integrator's own rule ([`balloon_integrate::check_time_step`]), so that a bad `dt` is
/// refused before any work, with the same range the integrator enforces.
///
/// # Errors
/// [`ShellError::InvalidParameter`] naming `dt` when it is not positive and finite.
pub fn check_dt(dt: f64) -> Result<f64, ShellError> {
    balloon_integrate::check_time_step(dt).map_err(|_| ShellError::InvalidParameter {
        name: "dt",
        value: dt.to_string(),
        reason: "must be a positive finite number".into(),
    })
}
