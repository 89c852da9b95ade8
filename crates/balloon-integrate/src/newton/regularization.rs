//! How the Newton core keeps its matrix positive definite: a mass shift `A + tau M`.
//!
//! Two policies, one per use:
//!
//! * The retry shift (backward Euler steps): no shift while the Newton matrix
//!   `A = (1 + dt alpha) M + (dt^2 + dt beta) K` is positive definite (the inertia makes it so
//!   for small steps); when a solve meets an indefinite matrix (CG meets non-positive
//!   curvature, Cholesky a non-positive pivot) it is retried with a shift from CG's Rayleigh
//!   quotient or `1e-2 m_coef`, tenfold on later retries, at most
//!   [`MAX_REGULARIZATION_RETRIES`] times. The next iteration of the step starts from a
//!   quarter of the shift that worked ([`SHIFT_DECAY`]) rather than from 0 (Levenberg-Marquardt
//!   memory). The shift shortens the step but not what the step solves for.
//! * The Levenberg-Marquardt shift (static solves, where nothing else makes the
//!   matrix regular: `K + mu M`): a shift relative to the stiffness scale `mu_ref = |diag K| /
//!   |m|` that falls fourfold after a full step, rises by `2^c` after a step the line search cut
//!   `c` times, tenfold on an indefinite matrix or a direction that is not a descent direction,
//!   a hundredfold when no step was found, and never falls below its minimum.

use balloon_linalg::SolveError;

/// Retries of an indefinite linear solve with a growing mass shift before giving up.
pub const MAX_REGULARIZATION_RETRIES: usize = 14;

/// A regularised Newton iteration of a step hands this fraction of its mass shift to the next
/// one as the shift to try first.
pub const SHIFT_DECAY: f64 = 0.25;

/// The largest Levenberg-Marquardt shift relative to `mu_ref` before a static stage is
/// declared stuck.
pub const MAX_SHIFT: f64 = 1e12;

/// A kept factorisation is refreshed before a static solve whose shift differs from the
/// factorised one by more than this factor, unless both shifts are below [`SHIFT_NEGLIGIBLE`]
/// `mu_ref`.
const SHIFT_REFRESH_RATIO: f64 = 3.0;

/// Shifts (relative to `mu_ref`) below which a change of the shift leaves a kept factor a good
/// preconditioner: measured on the peer sphere, a factor at `6e-5 mu_ref` preconditions the
/// matrix at a fourfold smaller shift in 3 CG iterations, one at `1e-2` the matrix at a fourfold
/// smaller shift in 17.
const SHIFT_NEGLIGIBLE: f64 = 1e-4;

/// The mass-shift policy of a Newton solve (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Regularization {
    /// Backward Euler: shift only after an indefinite solve.
    RetryShift {
        /// Retry indefinite solves with a shift (else the solver's error is returned).
        enabled: bool,
        /// The shift of the last successful solve (0 without regularisation), relative to the
        /// mass matrix like `m_coef`.
        last: f64,
    },
    /// Static solves: a shift at every solve.
    LevenbergMarquardt {
        /// The current shift relative to `scale`.
        shift: f64,
        /// `mu_ref`, 1/s^2 (0 until the first linearisation sets it).
        scale: f64,
        /// The smallest shift relative to `scale`.
        min: f64,
    },
}

/// What the Newton loop does when no step along the direction was acceptable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum NoStep {
    /// The solve fails.
    Fail,
    /// The shift is at its largest: stop iterating (the caller reports the residual).
    Stop,
    /// Try again from the same iterate with the larger shift.
    Retry,
}

impl Regularization {
    /// Whether a solve reported indefinite is retried with a larger mass shift on a matrix
    /// with a mass term of its own (`m_coef > 0`, a time step): the backward-Euler ladder.
    /// The linear solver may then call a matrix indefinite from a cheaper test
    /// (`LinearSolver::set_shift_retries`). Static solves (`m_coef = 0`) keep the exact
    /// verdict: their Levenberg-Marquardt shift is all that conditions the matrix, and a
    /// positive definite matrix called indefinite would shift them off Newton's quadratic
    /// convergence.
    pub(crate) fn retries_with_mass(&self, m_coef: f64) -> bool {
        matches!(self, Self::RetryShift { enabled: true, .. }) && m_coef > 0.0
    }

    /// The shift (added to `m_coef`) of the first solve of Newton iteration `k`.
    pub(crate) fn first_shift(&self, k: usize, m_coef: f64) -> f64 {
        match *self {
            Self::RetryShift { last, .. } => {
                if k > 0 {
                    start_shift(last, m_coef)
                } else {
                    0.0
                }
            }
            Self::LevenbergMarquardt { shift, scale, .. } => shift * scale,
        }
    }

    /// The shift to retry with after a solve at `current` met an indefinite matrix (`err`),
    /// or `None` when this policy does not retry (or the Levenberg-Marquardt shift is at its
    /// largest already).
    pub(crate) fn after_indefinite(
        &mut self,
        current: f64,
        m_coef: f64,
        err: &SolveError,
        masses: &[f64],
    ) -> Option<f64> {
        match self {
            Self::RetryShift { enabled, .. } => {
                enabled.then(|| next_shift(current, m_coef, err, masses))
            }
            // At the largest shift a still indefinite matrix will not become definite: the
            // solve fails at once instead of refactorising at the same shift.
            Self::LevenbergMarquardt { shift, .. } if *shift >= MAX_SHIFT => None,
            Self::LevenbergMarquardt { shift, scale, .. } => {
                *shift = (*shift * 10.0).min(MAX_SHIFT);
                Some(*shift * *scale)
            }
        }
    }

    /// A solve with shift `used` succeeded.
    pub(crate) fn solved(&mut self, used: f64) {
        if let Self::RetryShift { last, .. } = self {
            *last = used;
        }
    }

    /// A step of the line search was accepted after `cuts` halvings.
    pub(crate) fn accepted(&mut self, cuts: usize) {
        if let Self::LevenbergMarquardt { shift, min, .. } = self {
            *shift = if cuts == 0 {
                (*shift * 0.25).max(*min)
            } else {
                (*shift * 2f64.powi(cuts as i32)).min(MAX_SHIFT)
            };
        }
    }

    /// The direction is not a descent direction: `true` to retry with a larger shift, `false`
    /// to search on the residual instead.
    pub(crate) fn not_descent(&mut self) -> bool {
        match self {
            Self::RetryShift { .. } => false,
            Self::LevenbergMarquardt { shift, .. } => {
                *shift = (*shift * 10.0).min(MAX_SHIFT);
                true
            }
        }
    }

    /// No step along the direction was acceptable.
    pub(crate) fn no_step(&mut self) -> NoStep {
        match self {
            Self::RetryShift { .. } => NoStep::Fail,
            Self::LevenbergMarquardt { shift, .. } => {
                if *shift >= MAX_SHIFT {
                    NoStep::Stop
                } else {
                    *shift = (*shift * 100.0).min(MAX_SHIFT);
                    NoStep::Retry
                }
            }
        }
    }

    /// Whether a kept factorisation at `factored` should be refreshed before a solve at the
    /// shift `mu` (both 1/s^2): only under Levenberg-Marquardt, when the shift moved more than
    /// threefold and is not negligible.
    pub(crate) fn refactor(&self, factored: f64, mu: f64) -> bool {
        let Self::LevenbergMarquardt { scale, .. } = *self else {
            return false;
        };
        let (lo, hi) = if factored < mu {
            (factored, mu)
        } else {
            (mu, factored)
        };
        hi >= SHIFT_NEGLIGIBLE * scale && hi > SHIFT_REFRESH_RATIO * lo
    }

    /// The shift of the last successful solve of a step (0 without regularisation), or the
    /// current Levenberg-Marquardt shift relative to `mu_ref`.
    pub(crate) fn current(&self) -> f64 {
        match *self {
            Self::RetryShift { last, .. } => last,
            Self::LevenbergMarquardt { shift, .. } => shift,
        }
    }
}

/// The next mass shift `tau` after an indefinite solve: from CG's Rayleigh quotient when there
/// is one (enough to make that direction positive with margin), otherwise 1% of the mass
/// coefficient, and tenfold the previous shift on later retries.
fn next_shift(previous: f64, m_coef: f64, err: &SolveError, masses: &[f64]) -> f64 {
    if previous > 0.0 {
        return previous * 10.0;
    }
    let m_min = masses
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min)
        .max(f64::MIN_POSITIVE);
    match err {
        SolveError::NonPositiveCurvature {
            curvature,
            direction_norm_squared,
            ..
        } if *direction_norm_squared > 0.0 => {
            (2.0 * curvature.abs() / (direction_norm_squared * m_min)).max(1e-2 * m_coef)
        }
        _ => 1e-2 * m_coef,
    }
}

/// The mass shift the next Newton iteration of a step tries first after one that needed
/// `last` (relative to the mass matrix, like `m_coef`): `SHIFT_DECAY * last`, or 0 (no
/// regularisation) once that falls below `1e-3 m_coef`. Measured on the built-in teddy's first
/// five default steps (`balloon inflate --steps 5`): starting every iteration from 0 took 137
/// Newton iterations, 4 rejected sub-steps and 11.8 s; this 68, none and 5.6 s.
pub(crate) fn start_shift(last: f64, m_coef: f64) -> f64 {
    let next = SHIFT_DECAY * last;
    if next < 1e-3 * m_coef { 0.0 } else { next }
}
