//! The error type of `balloon-linalg`.

use thiserror::Error;

/// Everything that can go wrong in assembly, factorisation, a linear solve or a matrix export.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SolveError {
    /// CG met a search direction `p` with `p^T A p <= 0`: the matrix is not positive definite
    /// (e.g. a compressed, buckling state with the follower term on, or a negative time step).
    /// Use a smaller time step, turn off the follower term, or use a direct solver.
    #[error(
        "CG breakdown at iteration {iteration}: non-positive curvature p^T A p = {curvature:e} (|p|^2 = {direction_norm_squared:e}); the system matrix is not positive definite"
    )]
    NonPositiveCurvature {
        /// CG iteration (0-based).
        iteration: usize,
        /// The value of `p^T A p`.
        curvature: f64,
        /// `|p|^2`, for scale.
        direction_norm_squared: f64,
    },
    /// A factorisation (sparse Cholesky or IC(0)) met a non-positive pivot: the matrix is not
    /// positive definite. Use PCG or the matrix-free solver, or a smaller time step.
    #[error(
        "{method} factorisation of the {n}x{n} matrix ({nnz} entries) failed: non-positive pivot{} (diagonal shift {shift:e}); the matrix is not positive definite",
        pivot.map(|p| format!(" at row {p}")).unwrap_or_default()
    )]
    NotPositiveDefinite {
        /// `"sparse Cholesky"` or `"IC(0)"`.
        method: &'static str,
        /// Matrix size.
        n: usize,
        /// Stored entries (the lower triangle for IC(0)).
        nnz: usize,
        /// The row of the failing pivot, when the factoriser reports it.
        pivot: Option<usize>,
        /// The largest diagonal shift tried (0 for the plain Cholesky).
        shift: f64,
    },
    /// IC(0) needs every diagonal entry in the sparsity pattern.
    #[error("IC(0): row {row} has no diagonal entry in the sparsity pattern")]
    MissingDiagonal {
        /// The row.
        row: usize,
    },
    /// The sparse Cholesky's symbolic analysis or workspace could not be made (the index type
    /// overflowed or memory ran out).
    #[error("sparse Cholesky of the {n}x{n} matrix: {what} failed ({reason})")]
    FactorResources {
        /// `"symbolic analysis"` or `"workspace allocation"`.
        what: &'static str,
        /// Matrix size.
        n: usize,
        /// `"out of memory"` or `"index overflow"`.
        reason: &'static str,
    },
    /// A solve with a factor was asked for before a successful factorisation.
    #[error("solve called before a successful factorisation")]
    NotFactorized,
    /// The CSR arrays do not describe a valid matrix for `sprs`.
    #[error("not a valid CSR matrix for sprs: {0}")]
    InvalidCsr(#[source] sprs::errors::StructureError),
    /// The small Woodbury capacitance matrix `I + C U^T A^-1 U` is singular.
    #[error("Woodbury capacitance matrix of the low-rank terms ({rank}x{rank}) is singular")]
    SingularCapacitance {
        /// Number of low-rank terms.
        rank: usize,
    },
    /// A NaN or infinity appeared in the solve (the right-hand side or matrix is not finite).
    #[error("non-finite value in the linear solve at iteration {iteration}")]
    NonFinite {
        /// Iteration at which it was detected.
        iteration: usize,
    },
    /// Vector or matrix sizes disagree.
    #[error("dimension mismatch: {what} has length {len}, expected {expected}")]
    Dimension {
        /// Which array.
        what: &'static str,
        /// Its length.
        len: usize,
        /// Expected length.
        expected: usize,
    },
    /// A triplet refers to a row or column outside the matrix.
    #[error("stiffness triplet ({row}, {col}) is outside the {n}x{n} matrix")]
    TripletOutOfRange {
        /// Row index.
        row: usize,
        /// Column index.
        col: usize,
        /// Matrix size.
        n: usize,
    },
    /// The solver name could not be parsed.
    #[error(
        "unknown linear solver `{0}`; expected one of \"matrix-free-cg\", \"pcg\", \"cholesky\", \"factorized-pcg\""
    )]
    UnknownKind(String),
    /// The solver needs an assembled matrix but was given a matrix-free problem.
    #[error("the `{solver}` solver needs an assembled matrix; the problem is matrix-free")]
    NeedsAssembledMatrix {
        /// Name of the solver.
        solver: &'static str,
    },
    /// A direct solver was given a problem whose matrix is only part of its stiffness
    /// ([`crate::LinearProblem::with_correction`]); it would solve the wrong system.
    #[error(
        "the `{solver}` solver solves with the matrix itself and cannot take a stiffness correction"
    )]
    CorrectionUnsupported {
        /// Name of the solver.
        solver: &'static str,
    },
    /// No matrix has been assembled yet (e.g. asking for the Newton matrix of a run that uses
    /// the matrix-free solver, or before the first step).
    #[error("no assembled matrix is available (the matrix-free solver never assembles one)")]
    NotAssembled,
    /// Writing or reading a Matrix Market file failed.
    #[error("Matrix Market file {path}: {detail}")]
    MatrixMarket {
        /// The file.
        path: String,
        /// What went wrong.
        detail: String,
    },
}

impl SolveError {
    /// Whether the error says the matrix is not positive definite (CG's non-positive curvature
    /// or a failed Cholesky factorisation): the case a caller may cure by shifting the matrix.
    pub fn is_indefinite(&self) -> bool {
        matches!(
            self,
            Self::NonPositiveCurvature { .. } | Self::NotPositiveDefinite { .. }
        )
    }
}
