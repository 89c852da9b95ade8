//! The one error type of the Newton core, shared by the backward Euler step
//! ([`crate::implicit::BackwardEuler`]) and the static solve ([`crate::statics::StaticSolver`]).

use balloon_linalg::SolveError;
use thiserror::Error;

use crate::system::SystemError;

/// Errors of a Newton solve: a dynamic step ([`crate::implicit::BackwardEuler::step`], where it
/// is also called [`crate::implicit::IntegrateError`]) or a static solve
/// ([`crate::statics::StaticSolver`], also called [`crate::statics::StaticError`]).
///
/// Each variant says when it happens; the numbers it carries explain it. Parameters are named
/// by their field names (`dt`, `newton_iterations`, ...), never by a command-line flag.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum NewtonError {
    /// The force system failed (inverted element, non-finite gas volume, ...). Usually the step
    /// or load is too large for the state: a smaller `dt` or load increment helps.
    #[error("force system error in Newton iteration {iteration}: {source}")]
    System {
        /// Newton iteration (0-based; of the load stage in a static solve).
        iteration: usize,
        /// The system's error.
        #[source]
        source: SystemError,
    },
    /// The linear solver broke down for another reason than an indefinite matrix that the
    /// regularisation could handle (a Cholesky failure, CG out of iterations, ...).
    #[error("linear solver failed in Newton iteration {iteration}: {source}")]
    Linear {
        /// Newton iteration (0-based).
        iteration: usize,
        /// The solver's error.
        #[source]
        source: SolveError,
    },
    /// A position, velocity or force became NaN or infinite.
    #[error("non-finite {quantity} at dof {dof} (vertex {vertex}) in Newton iteration {iteration}")]
    NonFinite {
        /// "position", "velocity" or "force".
        quantity: &'static str,
        /// Degree of freedom.
        dof: usize,
        /// Vertex `dof / 3`.
        vertex: usize,
        /// Newton iteration (0-based).
        iteration: usize,
    },
    /// A parameter is out of its range (the time step, a damping coefficient, a tolerance, an
    /// iteration bound, gravity, a shift). Pass a value in `allowed`.
    #[error("invalid parameter: `{name}` = {value:e} must be {allowed}")]
    InvalidParameter {
        /// The parameter (`dt`, `mass_damping`, ..., as the fields of
        /// [`crate::implicit::BackwardEulerParams`] and [`crate::statics::StaticParams`]).
        name: &'static str,
        /// The value given.
        value: f64,
        /// Its admissible range, in words.
        allowed: &'static str,
    },
    /// An array handed to the solver does not have one entry per degree of freedom.
    #[error("invalid input: `{what}` has length {len}, the system has {expected} dofs")]
    LengthMismatch {
        /// Which array (`x`, `v`, `masses`, `external_forces`).
        what: &'static str,
        /// Its length.
        len: usize,
        /// The system's number of degrees of freedom.
        expected: usize,
    },
    /// An input array holds a NaN or an infinity.
    #[error("invalid input: `{what}` entry {dof} (vertex {vertex}) is not finite")]
    NonFiniteInput {
        /// Which array (`x`, `external_forces`).
        what: &'static str,
        /// Degree of freedom.
        dof: usize,
        /// Vertex `dof / 3`.
        vertex: usize,
    },
    /// A lumped mass is not positive and finite.
    #[error("invalid input: mass of dof {dof} (vertex {vertex}) is {mass:e} kg; must be positive")]
    InvalidMass {
        /// Degree of freedom.
        dof: usize,
        /// Vertex `dof / 3`.
        vertex: usize,
        /// The mass, kg.
        mass: f64,
    },
    /// The system has no potential energy, so there is nothing to minimise (the static solve
    /// needs one; a gas model without a potential cannot be solved statically).
    #[error(
        "the force system has no potential energy; the static solve needs one (a gas model without a potential cannot be solved statically)"
    )]
    NoPotential,
    /// The process asked the solves to stop (a signal caught by the front end; see
    /// [`crate::newton::set_cancel_check`]). Not recoverable: no retry with a smaller step.
    #[error("interrupted in Newton iteration {iteration} (a stop was requested)")]
    Interrupted {
        /// Newton iteration (0-based) at which the request was seen.
        iteration: usize,
    },
    /// Newton did not bring the relative residual down to the tolerance within the allowed
    /// iterations, stalled (the residual did not halve over
    /// [`crate::newton::NEWTON_STALL_WINDOW`] iterations), or the line search found no
    /// acceptable step: the step or stage is not accepted. `load_factor` is the static solve's
    /// load factor reached (1 = the full load; `None` for a dynamic step).
    #[error(
        "{}",
        match load_factor {
            None => format!(
                "Newton did not converge: relative residual {residual:.3e} after {iterations} iterations (tolerance {tolerance:e})"
            ),
            Some(f) => format!(
                "static solve did not converge: relative residual {residual:.3e} after {iterations} Newton iterations (tolerance {tolerance:e}) at load factor {f}"
            ),
        }
    )]
    NotConverged {
        /// Newton iterations done (over all load stages of a static solve).
        iterations: usize,
        /// Relative residual at the last iterate.
        residual: f64,
        /// The tolerance asked for.
        tolerance: f64,
        /// The static solve's load factor reached; `None` for a dynamic step.
        load_factor: Option<f64>,
    },
    /// A static solve stopped because its load stages stalled: `stalled_stages` continuation
    /// increments in a row ran [`crate::statics::StaticParams::stall_window`] Newton
    /// iterations without halving their best residual, so smaller increments did not help
    /// (module docs of [`crate::statics`], "Stalled stages"). The evidence: where the residual
    /// of the last iterate concentrates, and (when the caller computed it) the smallest
    /// eigenvalue of the stiffness there; a negative one says the energy is indefinite along a
    /// mode (the wall wrinkles or buckles), so there is no smooth equilibrium near that path.
    #[error("{}", no_equilibrium_message(.0))]
    NoEquilibrium(Box<Stall>),
}

/// What a static solve that ended with [`NewtonError::NoEquilibrium`] found (boxed: the
/// error stays small).
#[derive(Debug, Clone, PartialEq)]
pub struct Stall {
    /// Newton iterations done over all load stages.
    pub iterations: usize,
    /// Relative residual at the last iterate of the last stalled stage.
    pub residual: f64,
    /// The load factor of the last converged stage (0: none converged).
    pub load_factor: f64,
    /// Stalled increments in a row.
    pub stalled_stages: usize,
    /// The vertex with the largest residual force at the last iterate.
    pub vertex: usize,
    /// Its position there, m.
    pub position: [f64; 3],
    /// The share of `|r|^2` on the 5 % of vertices with the largest residual force.
    pub share: f64,
    /// The smallest eigenvalue of `K y = lambda M y` at the last iterate, 1/s^2, when
    /// computed ([`crate::statics::StaticSolver::stability`]).
    pub smallest_eigenvalue: Option<f64>,
    /// The same relative to the stiffness scale `|diag K| / |m|`.
    pub relative_eigenvalue: Option<f64>,
}

/// The message of [`NewtonError::NoEquilibrium`].
fn no_equilibrium_message(stall: &Stall) -> String {
    let Stall {
        iterations,
        residual,
        load_factor,
        stalled_stages: stalled,
        vertex,
        position: p,
        share,
        smallest_eigenvalue: eigenvalue,
        relative_eigenvalue: relative,
    } = stall;
    let (eigenvalue, relative) = (*eigenvalue, *relative);
    let eigen = match (eigenvalue, relative) {
        (Some(l), Some(r)) if r < -1e-9 => format!(
            "; the stiffness there is indefinite (smallest eigenvalue {l:.3e} 1/s^2, {r:.1e} of \
             the stiffness scale): the wall wrinkles or buckles along this load path"
        ),
        (Some(l), Some(r)) => format!(
            "; the stiffness there is positive semi-definite (smallest eigenvalue {l:.3e} 1/s^2, \
             {r:.1e} of the stiffness scale): a flat energy rather than a buckled wall"
        ),
        _ => String::new(),
    };
    format!(
        "static solve stalled, no smooth equilibrium found: {stalled} load increments in a row stalled \
         (the best residual did not halve over `stall_window` Newton iterations), the last at \
         relative residual {residual:.3e}; {iterations} Newton iterations, last converged load \
         factor {load_factor}; the residual concentrates at vertex {vertex} ({:.4}, {:.4}, \
         {:.4}) m, {:.0} % of |r|^2 on the 5 % of vertices that carry most{eigen}",
        p[0],
        p[1],
        p[2],
        100.0 * share
    )
}

impl NewtonError {
    /// Whether a failure of this kind may go away with a smaller step or load increment
    /// (numerical failures), as opposed to bad input that no retry can mend.
    pub fn is_recoverable(&self) -> bool {
        !matches!(
            self,
            Self::InvalidParameter { .. }
                | Self::LengthMismatch { .. }
                | Self::NonFiniteInput { .. }
                | Self::InvalidMass { .. }
                | Self::NoPotential
                | Self::Interrupted { .. }
        )
    }
}

/// `Err(InvalidParameter)` unless `ok`.
pub(crate) fn check_parameter(
    name: &'static str,
    value: f64,
    ok: bool,
    allowed: &'static str,
) -> Result<(), NewtonError> {
    if ok {
        Ok(())
    } else {
        Err(NewtonError::InvalidParameter {
            name,
            value,
            allowed,
        })
    }
}
