//! What a linear solve reports on success: [`SolveInfo`] (iterations, residual, convergence)
//! and the [`Preconditioner`] it used. Beside [`crate::SolveError`], what it reports on failure.

use serde::{Deserialize, Serialize};

/// Which preconditioner a solve used (reported in [`SolveInfo::preconditioner`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Preconditioner {
    /// Not reported (e.g. a bare [`crate::cg`] call or a user's solver).
    #[default]
    Unreported,
    /// None (a direct solve, or the identity).
    None,
    /// Jacobi on the mass part `m_coef M` alone.
    MassJacobi,
    /// Jacobi on the diagonal of the whole matrix `diag(A)`.
    DiagonalJacobi,
    /// Zero-fill incomplete Cholesky of the sparse part.
    IncompleteCholesky,
    /// A sparse Cholesky factorisation (of this matrix or, lagged, of an earlier one).
    Cholesky,
}

/// What a linear solve achieved.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SolveInfo {
    /// Iterations used (CG), or 1 + refinement steps for a direct solve.
    pub iterations: usize,
    /// Final `||b - A x|| / ||b||` (0 when `b = 0`).
    pub relative_residual: f64,
    /// Whether the requested tolerance was met.
    pub converged: bool,
    /// The preconditioner the solve used.
    pub preconditioner: Preconditioner,
}
