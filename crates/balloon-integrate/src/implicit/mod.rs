//! Backward Euler with Newton-Raphson on velocities (Wang et al. 2015, Eq. 18-23), globalised
//! as the minimisation of an incremental potential by the Newton core of [`crate::newton`].
//!
//! Unknown: the end-of-step velocity `v`. With `x(v) = x^n + dt v`, backward Euler (Eq. 18) is
//! the nonlinear equation
//!
//! `r(v) = M (v - v^n) - dt (f(x(v)) + f_ext - C v) = 0`, `C = alpha M + beta K`.
//!
//! Newton from `v_(0) = v^n` solves, at each iterate `x_(k) = x^n + dt v_(k)`,
//!
//! `A dv = b`, `A = M + dt C + dt^2 K(x_(k)) = (1 + dt alpha) M + (dt^2 + dt beta) K`,
//! `b = M (v^n - v_(k)) + dt (f(x_(k)) + f_ext - C v_(k))` (Eq. 23),
//!
//! then `v_(k+1) = v_(k) + s dv` with a step length `s` from the line search. `K = -df/dx` is
//! the system's tangent stiffness (elastic plus gas, the latter's rank-1 part never assembled).
//! On a linear force system one iteration is exact.
//!
//! # Incremental potential
//!
//! When the system has a potential `W` (`f = -dW/dx`, [`ForceSystem::potential_energy`](crate::ForceSystem::potential_energy)) and
//! `beta = 0`, the backward Euler step is the minimiser of
//!
//! `E(x) = (1 + dt alpha) / (2 dt^2) |x - x^n - dt v^n / (1 + dt alpha)|_M^2 + W(x) - f_ext . x`.
//!
//! Mass damping is folded in: the damping force `-alpha M v = -alpha M (x - x^n) / dt` is the
//! negative gradient of `alpha / (2 dt) |x - x^n|_M^2`, and adding that to the inertia term
//! `1 / (2 dt^2) |x - x^n - dt v^n|_M^2` completes the square above (up to a constant). Then
//! `dE/dx = -b / dt` and `d^2E/dx^2 = A / dt^2`, so the Newton step `dx = dt dv` is Newton on
//! `E`, a descent direction whenever `A` is positive definite (which the projected tangent or
//! the mass-shift retry ensures), with `dE = -s b . dv` to first order. The line search halves
//! `s` from 1 until Armijo's condition `E(v + s dv) <= E(v) - 1e-4 s b . dv` holds; a state
//! where `E` is undefined (an inverted element) counts as `E = inf`. Close to convergence the
//! decrease falls below what `f64` resolves in `E`; a trial within round-off of `E` is then
//! accepted when it lowers `|b|`. Internally `E` is evaluated in the velocity form
//! `(1 + dt alpha)/2 |v - v^n/(1 + dt alpha)|_M^2 + W(x(v)) - dt f_ext . v`, which differs from
//! `E(x)` by a constant. [`StepInfo::energies`] records it at every accepted iterate.
//!
//! Stiffness damping `beta K v` has no potential: with `beta > 0` (and for a direction that is
//! not a descent direction of `E`) the search backtracks on the residual norm instead,
//! `|b(v + s dv)| <= (1 - 1e-4 s) |b(v)|`, taking the shortest step if none decreases it.
//! Systems without a potential take full Newton steps (as before), still stopped on the
//! residual.
//!
//! # Convergence test
//!
//! Newton stops when the residual force `|b| / dt` (N) is at most
//! [`BackwardEulerParams::newton_tolerance`] times the force scale
//!
//! `F = |M (v - v^n)| / dt + F_int + |f_ext| + |C v|`,
//!
//! the sum of the norms of the terms of `r / dt` at the current iterate, with the internal
//! forces counted by [`ForceSystem::force_scale`](crate::ForceSystem::force_scale) (for the shell: the norms of the elastic and of
//! the pressure forces separately, which balance at an inflated rest shape) or `|f|`. Every term
//! is a force norm over the same degrees of freedom, so the ratio does not depend on the units,
//! the size of the model or its resolution. At rest every term vanishes and `|b|` is round-off,
//! so `F` has a floor `F_0 = 1e-3 |m| L / dt^2` (`|m|` the norm of the masses, `L` the
//! bounding-box diagonal of `x^n`): the residual force that moves the body by `1e-3 L` in one
//! step, far below the forces of any loaded state; a residual below `tol F_0` leaves the
//! positions off by about `1e-3 tol L` at most. A step that does not converge within
//! [`BackwardEulerParams::newton_iterations`] is [`IntegrateError::NotConverged`].
//! `newton_tolerance = 0` is the paper's mode: a fixed number of full Newton steps, no line
//! search and no residual test (the residual of the result is still reported).
//! [`BackwardEulerParams::accept_unconverged`] keeps the line search and the residual test
//! but accepts the last iterate after `newton_iterations` (a bounded cost per step, for
//! interactive use): every accepted iterate lowers `E`, which the paper's full steps do not
//! guarantee. In the live viewer, a dragged and pinched pair of connected rubber balloons
//! (two 2562-vertex membranes, `dt` = 10 ms) ran away with three full steps (the surface
//! turned inside out) in 3 of 60 randomised drag sequences, and in none of 60 with three
//! line-searched iterations and the first iterate below.
//!
//! # First iterate
//!
//! Newton starts from `v_(0) = v^n`, the positions `x^n + dt v^n`. Where the system cannot be
//! evaluated there (an element inverted, the enclosed volume not positive: the previous
//! velocity carries the surface through itself within `dt`), it starts from `v_(0) = 0`, the
//! step's start positions `x^n`, which are a valid state (the end of the last step), and
//! [`StepInfo::started_at_rest`] says so. The step still solves the same equation; only the
//! path differs.
//!
//! # Reused tangent (chord steps)
//!
//! Near rest a step is settled by one Newton iteration, whose cost is mostly the tangent: the
//! stiffness evaluation and the assembly of `A` (on the teddy with the paper's gas, 7.4 and 3.7
//! ms of a 25 ms step). After such a step the next step's first iteration solves with the same
//! `A` and low-rank terms (a chord, or Shamanskii, step), evaluating only the forces at
//! `v^n`. The direction is the only thing that changes: the step is still line-searched and
//! stopped on the residual test above, so it converges to the same tolerance, and a second
//! iteration, if the tolerance asks for one, linearises at its own iterate. A chord step the
//! line search would cut is dropped (the iteration is repeated from the same iterate with its
//! own tangent). Conditions: [`BackwardEulerParams::tangent_reuse_steps`] (at most that many in
//! a row), an assembled linear solver, no stiffness damping, a residual test, the same `dt` and
//! no regularisation shift in the matrix. [`StepInfo::reused_tangent`] says when it was used.
//!
//! # Files
//!
//! `params.rs` ([`BackwardEulerParams`], validated once), `info.rs` ([`StepInfo`]), `step.rs`
//! ([`BackwardEuler`] and its step), `reuse.rs` (when a step reuses the last matrix); the
//! Newton iteration itself, its line search, regularisation, convergence test and error are in
//! [`crate::newton`].

mod info;
mod params;
mod reuse;
mod step;
#[cfg(test)]
mod tests;

pub use info::StepInfo;
pub use params::{
    BackwardEulerParams, DEFAULT_INEXACT_FORCING, DEFAULT_NEWTON_ITERATIONS,
    DEFAULT_NEWTON_TOLERANCE, DEFAULT_TANGENT_REUSE_STEPS,
};
pub use step::BackwardEuler;

pub use crate::newton::{MAX_NEWTON_ITERATIONS, NEWTON_STALL_WINDOW};

/// Errors of [`BackwardEuler::step`]: the Newton core's error ([`crate::newton::NewtonError`]).
pub type IntegrateError = crate::newton::NewtonError;

/// Checks a time step (s): positive and finite. The one check of dt for the implicit
/// integrator and the systems stepped by it (the shell calls it when dt is set, so a bad dt is
/// refused before any work).
pub fn check_time_step(dt: f64) -> Result<f64, IntegrateError> {
    crate::newton::check_parameter(
        "dt",
        dt,
        dt.is_finite() && dt > 0.0,
        "positive and finite (s)",
    )?;
    Ok(dt)
}
