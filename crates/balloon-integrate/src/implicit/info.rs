//! [`StepInfo`]: what one backward Euler step did.

use serde::{Deserialize, Serialize};

use crate::timing::PhaseTimes;

/// What one [`BackwardEuler::step`](super::BackwardEuler::step) did.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StepInfo {
    /// Newton iterations performed (linear solves).
    pub newton_iterations: usize,
    /// CG iterations per Newton iteration (for Cholesky: 1 + iterative-refinement steps).
    pub linear_iterations: Vec<usize>,
    /// Final relative residual `||b - A dv|| / ||b||` per Newton iteration.
    pub linear_residuals: Vec<f64>,
    /// `||b_k||` (N s) at each Newton iterate evaluated (the last one is the result's, except in
    /// the paper's mode, which never evaluates its result: there it is the last iterate's before
    /// the final update).
    pub newton_residuals: Vec<f64>,
    /// Relative residual (module docs) at each Newton iterate evaluated.
    pub relative_residuals: Vec<f64>,
    /// Relative residual of the result: `|b| / (dt F)`, the residual force over the force scale
    /// `F` (module docs). In the paper's mode (`newton_tolerance = 0`) the residual of the last
    /// iterate Newton evaluated, before its final update: evaluating the result only for the
    /// record would cost a fourth force and stiffness evaluation per step (measured 3-13% of the
    /// step time in `cargo xtask bench --quick`).
    pub relative_residual: f64,
    /// Halvings of Newton steps made by the line search over the step.
    pub line_search_cuts: usize,
    /// The incremental potential (J, up to a constant; module docs) at the first iterate and
    /// at every accepted one, when the system has a potential and the energy line search runs
    /// (empty otherwise). Non-increasing by construction (up to round-off).
    pub energies: Vec<f64>,
    /// Whether the step converged: with `newton_tolerance > 0` whether the residual test
    /// passed, always `true` for a returned step unless
    /// [`BackwardEulerParams::accept_unconverged`](super::BackwardEulerParams::accept_unconverged) is set (otherwise a non-converged step is
    /// [`IntegrateError::NotConverged`](super::IntegrateError::NotConverged)); in the paper's mode
    /// (`newton_tolerance = 0`, no residual test) whether every linear solve met its
    /// tolerance.
    pub converged: bool,
    /// Linear solves that had to be retried with a mass shift because `A` was indefinite (see
    /// [`BackwardEulerParams::regularize_indefinite`](super::BackwardEulerParams::regularize_indefinite)).
    pub regularized_solves: usize,
    /// Largest mass shift `tau` used in the step (0 when none was needed), relative to the mass
    /// matrix: the solved matrix was `(1 + dt alpha + tau) M + (dt^2 + dt beta) K`.
    pub max_regularization: f64,
    /// Numeric sparse Cholesky factorisations done in the step (Cholesky: one per solve;
    /// factorized PCG: only when the lagged preconditioner was refreshed).
    pub factorizations: usize,
    /// Wall-clock time of the step per phase (the integrator's phases; `projection_ms` is 0
    /// here: the shell adds its projection).
    #[serde(default)]
    pub times: PhaseTimes,
    /// The first Newton iteration reused the previous step's Newton matrix (a chord step,
    /// [`BackwardEulerParams::tangent_reuse_steps`](super::BackwardEulerParams::tangent_reuse_steps)) and its step was taken.
    #[serde(default)]
    pub reused_tangent: bool,
    /// The system could not be evaluated at the usual first iterate `v_(0) = v^n` (the
    /// predictor `x^n + dt v^n` inverted an element or turned the surface inside out), so
    /// Newton started from `v_(0) = 0`, the step's start positions (module docs of
    /// [`crate::implicit`], "First iterate").
    #[serde(default)]
    pub started_at_rest: bool,
}

impl StepInfo {
    /// Total linear-solver iterations over the step.
    pub fn total_linear_iterations(&self) -> usize {
        self.linear_iterations.iter().sum()
    }
}
