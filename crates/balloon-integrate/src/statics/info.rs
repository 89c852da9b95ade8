//! [`StaticInfo`]: what a static solve did.

use serde::{Deserialize, Serialize};

use crate::timing::PhaseTimes;

/// What a static solve did.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StaticInfo {
    /// Whether the full-load stage reached the tolerance (always `true` for a returned
    /// solve: a non-converged one is [`StaticError::NotConverged`](super::StaticError::NotConverged)).
    pub converged: bool,
    /// Relative residual of the result (module docs).
    pub relative_residual: f64,
    /// Newton iterations over all load stages, failed attempts included.
    pub iterations: usize,
    /// Load stages solved: 1 when the full load converged directly, more with continuation.
    pub load_steps: usize,
    /// Continuation increments rolled back and halved.
    pub load_halvings: usize,
    /// Halvings of Newton steps by the line search, over all stages.
    pub line_search_cuts: usize,
    /// Linear solves retried with a larger shift because the shifted matrix was indefinite.
    pub regularized_solves: usize,
    /// The static energy `E` (J, up to a constant) at the first and at every accepted iterate
    /// of the last stage; non-increasing by construction.
    pub energies: Vec<f64>,
    /// Relative residual at every iterate of the last stage.
    pub relative_residuals: Vec<f64>,
    /// Final Levenberg-Marquardt shift relative to `mu_ref`.
    pub shift: f64,
    /// Numeric factorisations done by the linear solver.
    pub factorizations: usize,
    /// Linear-solver iterations over all Newton iterations (CG iterations; for Cholesky 1 +
    /// iterative-refinement steps per solve).
    #[serde(default)]
    pub linear_iterations: usize,
    /// Wall-clock time per phase over all load stages.
    #[serde(default)]
    pub times: PhaseTimes,
}
