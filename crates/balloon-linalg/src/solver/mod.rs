//! Linear solvers as values behind one trait ([`LinearSolver`]), and the problem they solve
//! ([`LinearProblem`]): `A x = b` with
//!
//! `A = m_coef M + k_coef (K + sum_i c_i u_i u_i^T)`,
//!
//! `M` a lumped (diagonal) mass matrix, `K` the sparse part of a stiffness matrix and the
//! `c_i u_i u_i^T` dense low-rank terms ([`LowRankTerm`]) that are never assembled. This is the
//! Newton matrix of backward Euler (seed 000, Eq. 23, with `m_coef = 1 + dt alpha`,
//! `k_coef = dt^2 + dt beta`).
//!
//! One type per solver, each with its parameters (Params), a [`SolveInfo`] on success and a
//! [`SolveError`] on failure:
//!
//! * [`MatrixFreeCg`]: CG on `A p` from a [`StiffnessOperator`], Jacobi on `diag(A)` or the mass;
//! * [`AssembledPcg`]: PCG on the assembled matrix, Jacobi or IC(0);
//! * [`CholeskySolver`]: sparse Cholesky of the sparse part, Sherman-Morrison / Woodbury for the
//!   low-rank terms, iterative refinement;
//! * [`FactorizedPcg`]: PCG preconditioned by a kept (lagged) Cholesky factorisation,
//!   refactorised when it stops paying.
//!
//! [`LinearSolverKind`] names them for configuration files and command lines, and
//! [`SolverSettings::build`] makes the boxed solver of a kind.

use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::csr::CsrMatrix;
use crate::error::SolveError;
use crate::low_rank::{LowRankTerm, add_low_rank_product};

mod direct;
mod factorized;
mod matrix_free;
mod pcg;

pub use direct::{CholeskyParams, CholeskySolver};
pub use factorized::{FactorizedPcg, FactorizedPcgParams, SINGLE_PRECISION_MIN_TOLERANCE};
pub use matrix_free::MatrixFreeCg;
pub use pcg::AssembledPcg;

/// Which linear solver Newton uses for `A dv = b` (Eq. 23).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LinearSolverKind {
    /// Matrix-free CG on force differentials (the paper; `"matrix-free-cg"`) with a Jacobi
    /// preconditioner: `diag(A)` when the system implements
    /// `ForceSystem::add_stiffness_diagonal`, else the mass diagonal. Works with every
    /// `ForceSystem`.
    #[default]
    MatrixFreeCg,
    /// Jacobi-preconditioned CG on the assembled sparse matrix plus matrix-free low-rank terms
    /// (`"pcg"`). Needs `ForceSystem::add_stiffness_triplets`.
    Pcg,
    /// Sparse Cholesky (faer) plus Sherman-Morrison / Woodbury for the low-rank terms
    /// (`"cholesky"`). Needs `ForceSystem::add_stiffness_triplets`; the sparse part must be SPD.
    Cholesky,
    /// CG on the assembled matrix plus matrix-free low-rank terms, preconditioned by a sparse
    /// Cholesky factorisation of an *earlier* Newton matrix (`"factorized-pcg"`), kept across
    /// Newton iterations and steps and refreshed when CG needs more than
    /// [`SolverSettings::refactor_iterations`] iterations (or fails); after such a slow
    /// solve the next six solves refactorise first (the matrix is changing fast). Needs
    /// `ForceSystem::add_stiffness_triplets` and an SPD sparse part: use it with the projected
    /// tangent (`TangentKind::Projected`); with the exact tangent an indefinite matrix makes the
    /// factorisation fail and the regularisation retries are costly.
    FactorizedPcg,
}

impl FromStr for LinearSolverKind {
    type Err = SolveError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "matrix-free-cg" => Ok(Self::MatrixFreeCg),
            "pcg" => Ok(Self::Pcg),
            "cholesky" => Ok(Self::Cholesky),
            "factorized-pcg" => Ok(Self::FactorizedPcg),
            _ => Err(SolveError::UnknownKind(s.to_string())),
        }
    }
}

impl std::fmt::Display for LinearSolverKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::MatrixFreeCg => "matrix-free-cg",
            Self::Pcg => "pcg",
            Self::Cholesky => "cholesky",
            Self::FactorizedPcg => "factorized-pcg",
        })
    }
}

/// Preconditioner of the assembled PCG solver ([`LinearSolverKind::Pcg`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PcgPreconditioner {
    /// Jacobi, `diag(A)^-1` including the low-rank diagonal (`"jacobi"`, default).
    #[default]
    Jacobi,
    /// Zero-fill incomplete Cholesky of the sparse part ([`crate::IncompleteCholesky`], `"ic0"`); the
    /// low-rank terms are left to CG.
    IncompleteCholesky,
}

impl FromStr for PcgPreconditioner {
    type Err = SolveError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "jacobi" => Ok(Self::Jacobi),
            "ic0" | "incomplete-cholesky" => Ok(Self::IncompleteCholesky),
            _ => Err(SolveError::UnknownKind(format!(
                "{s} (preconditioner: expected \"jacobi\" or \"ic0\")"
            ))),
        }
    }
}

impl std::fmt::Display for PcgPreconditioner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Jacobi => "jacobi",
            Self::IncompleteCholesky => "ic0",
        })
    }
}

/// Parameters of the linear solve in each Newton iteration.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LinearSolverParams {
    /// Which solver (default [`LinearSolverKind::MatrixFreeCg`], as the paper).
    pub kind: LinearSolverKind,
    /// Maximum CG iterations (default 500; ignored by Cholesky).
    pub max_iterations: usize,
    /// Stop CG when `||b - A x|| <= relative_tolerance * ||b||` (default `1e-8`; ignored by
    /// Cholesky, which reports its achieved residual).
    pub relative_tolerance: f64,
}

impl Default for LinearSolverParams {
    fn default() -> Self {
        Self {
            kind: LinearSolverKind::MatrixFreeCg,
            max_iterations: 500,
            relative_tolerance: 1e-8,
        }
    }
}

/// Parameters of every CG-based solver.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CgParams {
    /// Maximum CG iterations (default 500).
    pub max_iterations: usize,
    /// Stop when `||b - A x|| <= relative_tolerance * ||b||` (default `1e-8`).
    pub relative_tolerance: f64,
}

impl Default for CgParams {
    fn default() -> Self {
        let p = LinearSolverParams::default();
        Self {
            max_iterations: p.max_iterations,
            relative_tolerance: p.relative_tolerance,
        }
    }
}

impl From<LinearSolverParams> for CgParams {
    fn from(p: LinearSolverParams) -> Self {
        Self {
            max_iterations: p.max_iterations,
            relative_tolerance: p.relative_tolerance,
        }
    }
}

/// Everything [`SolverSettings::build`] needs to make the solver of a [`LinearSolverKind`]
/// (each field is used by the kinds that have it).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SolverSettings {
    /// The kind and the CG tolerances.
    pub linear: LinearSolverParams,
    /// Preconditioner of [`LinearSolverKind::Pcg`].
    pub pcg_preconditioner: PcgPreconditioner,
    /// [`LinearSolverKind::FactorizedPcg`]: CG iterations above which the lagged factor is
    /// judged stale (see [`FactorizedPcgParams::refactor_iterations`]; default 8).
    pub refactor_iterations: usize,
    /// Run the numeric sparse Cholesky factorisation on the rayon pool (needs the `parallel`
    /// feature; otherwise ignored).
    pub parallel_factorization: bool,
    /// [`LinearSolverKind::FactorizedPcg`]: the cost of a factorisation in CG iterations for
    /// the amortised refresh (see [`FactorizedPcgParams::refactor_cost`]; default 0: off).
    pub refactor_cost: usize,
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            linear: LinearSolverParams::default(),
            pcg_preconditioner: PcgPreconditioner::default(),
            refactor_iterations: FactorizedPcgParams::default().refactor_iterations,
            parallel_factorization: false,
            refactor_cost: 0,
        }
    }
}

impl SolverSettings {
    /// A new boxed solver of `self.linear.kind` with these settings.
    pub fn build(&self) -> Box<dyn LinearSolver> {
        let cg = CgParams::from(self.linear);
        match self.linear.kind {
            LinearSolverKind::MatrixFreeCg => Box::new(MatrixFreeCg::new(cg)),
            LinearSolverKind::Pcg => Box::new(AssembledPcg::new(cg, self.pcg_preconditioner)),
            LinearSolverKind::Cholesky => Box::new(CholeskySolver::new(CholeskyParams {
                relative_tolerance: self.linear.relative_tolerance,
                parallel: self.parallel_factorization,
                ..CholeskyParams::default()
            })),
            LinearSolverKind::FactorizedPcg => Box::new(FactorizedPcg::new(FactorizedPcgParams {
                cg,
                refactor_iterations: self.refactor_iterations,
                parallel: self.parallel_factorization,
                refactor_cost: self.refactor_cost,
                ..FactorizedPcgParams::default()
            })),
        }
    }
}

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

/// The stiffness `K` as an operator, for matrix-free solvers: `K p` and, optionally, its diagonal.
pub trait StiffnessOperator {
    /// `out = K p` (overwrite). In a [`LinearProblem`] this is the *whole* stiffness, low-rank
    /// terms included.
    fn apply(&self, p: &[f64], out: &mut [f64]);

    /// Adds the diagonal of the sparse part of `K` (without the low-rank terms) to `diagonal`
    /// and returns `true`, or returns `false` if the operator cannot (the default).
    fn add_diagonal(&self, diagonal: &mut [f64]) -> bool {
        let _ = diagonal;
        false
    }
}

/// How the matrix of a [`LinearProblem`] is given.
#[derive(Clone, Copy)]
pub enum ProblemForm<'a> {
    /// Matrix-free: `A p = m_coef M p + k_coef K p`, `K p` (low-rank terms included) from the
    /// operator.
    MatrixFree {
        /// Lumped mass per degree of freedom (the diagonal of `M`).
        masses: &'a [f64],
        /// The whole stiffness `K`.
        stiffness: &'a dyn StiffnessOperator,
    },
    /// Assembled: `matrix = m_coef M + k_coef K_sparse`; the low-rank terms are applied by the
    /// solver.
    Assembled {
        /// The assembled sparse part (symmetric, both triangles stored).
        matrix: &'a CsrMatrix,
        /// A counter that changes whenever the pattern of `matrix` changes
        /// ([`crate::SparseAssembler::pattern_version`]): symbolic factorisations are reused
        /// while it stays the same.
        pattern_version: u64,
    },
}

impl std::fmt::Debug for ProblemForm<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::MatrixFree { masses, .. } => f
                .debug_struct("MatrixFree")
                .field("dofs", &masses.len())
                .finish_non_exhaustive(),
            Self::Assembled {
                matrix,
                pattern_version,
            } => f
                .debug_struct("Assembled")
                .field("n", &matrix.n)
                .field("nnz", &matrix.nnz())
                .field("pattern_version", pattern_version)
                .finish(),
        }
    }
}

/// The linear system `A x = b`, `A = m_coef M + k_coef (K + sum_i c_i u_i u_i^T)` (seed 000,
/// Eq. 23), in matrix-free or assembled form ([`ProblemForm`]).
#[derive(Clone, Copy, Debug)]
pub struct LinearProblem<'a> {
    /// Coefficient of the mass matrix (already inside the matrix in the assembled form).
    pub m_coef: f64,
    /// Coefficient of the stiffness (already inside the matrix in the assembled form, applied
    /// by the solver to the low-rank terms).
    pub k_coef: f64,
    /// The low-rank terms of `K`. In the matrix-free form the operator already applies them;
    /// they are listed so that a preconditioner can use their diagonal.
    pub low_rank: &'a [LowRankTerm],
    /// How `M` and `K` are given.
    pub form: ProblemForm<'a>,
}

impl<'a> LinearProblem<'a> {
    /// A matrix-free problem `m_coef M + k_coef K`, `K` (low-rank terms included) applied by
    /// `stiffness`; `low_rank` lists those terms for preconditioners.
    pub fn matrix_free(
        m_coef: f64,
        k_coef: f64,
        masses: &'a [f64],
        stiffness: &'a dyn StiffnessOperator,
        low_rank: &'a [LowRankTerm],
    ) -> Self {
        Self {
            m_coef,
            k_coef,
            low_rank,
            form: ProblemForm::MatrixFree { masses, stiffness },
        }
    }

    /// An assembled problem: `matrix = m_coef M + k_coef K_sparse` plus
    /// `k_coef sum_i c_i u_i u_i^T` from `low_rank`.
    pub fn assembled(
        matrix: &'a CsrMatrix,
        pattern_version: u64,
        m_coef: f64,
        k_coef: f64,
        low_rank: &'a [LowRankTerm],
    ) -> Self {
        Self {
            m_coef,
            k_coef,
            low_rank,
            form: ProblemForm::Assembled {
                matrix,
                pattern_version,
            },
        }
    }

    /// Number of unknowns.
    pub fn dim(&self) -> usize {
        match self.form {
            ProblemForm::MatrixFree { masses, .. } => masses.len(),
            ProblemForm::Assembled { matrix, .. } => matrix.n,
        }
    }

    /// The assembled sparse part and its pattern version, if the problem is assembled.
    pub fn matrix(&self) -> Option<(&'a CsrMatrix, u64)> {
        match self.form {
            ProblemForm::Assembled {
                matrix,
                pattern_version,
            } => Some((matrix, pattern_version)),
            ProblemForm::MatrixFree { .. } => None,
        }
    }

    /// `out = A p` (overwrite), in either form.
    pub fn apply(&self, p: &[f64], out: &mut [f64]) {
        match self.form {
            ProblemForm::MatrixFree { masses, stiffness } => {
                stiffness.apply(p, out);
                for i in 0..out.len() {
                    out[i] = self.m_coef * masses[i] * p[i] + self.k_coef * out[i];
                }
            }
            ProblemForm::Assembled { matrix, .. } => {
                matrix.mul_into(p, out);
                add_low_rank_product(self.low_rank, self.k_coef, p, out);
            }
        }
    }

    /// Checks that `b` and `x` have the problem's dimension (and, in the assembled form, that
    /// the low-rank vectors do too).
    pub fn check_dimensions(&self, b: &[f64], x: &[f64]) -> Result<(), SolveError> {
        let n = self.dim();
        for (what, len) in [("b", b.len()), ("x", x.len())] {
            if len != n {
                return Err(SolveError::Dimension {
                    what,
                    len,
                    expected: n,
                });
            }
        }
        if let ProblemForm::Assembled { .. } = self.form
            && let Some(t) = self.low_rank.iter().find(|t| t.vector.len() != n)
        {
            return Err(SolveError::Dimension {
                what: "low-rank vector",
                len: t.vector.len(),
                expected: n,
            });
        }
        Ok(())
    }
}

/// A linear solver for [`LinearProblem`]s: a value holding its parameters and whatever it keeps
/// between solves (workspaces, symbolic analyses, factorisations). Adding a solver means adding
/// a type that implements this trait.
pub trait LinearSolver: std::fmt::Debug + Send {
    /// A short name for messages (e.g. `"cholesky"`).
    fn name(&self) -> &str;

    /// Whether the solver needs the assembled form ([`ProblemForm::Assembled`]). A caller that
    /// can assemble should do so when this is `true`, and may pass the matrix-free form when it
    /// is `false`.
    fn needs_assembled_matrix(&self) -> bool;

    /// Solves `A x = b`. On entry `x` holds an initial guess (iterative solvers start from it,
    /// direct solvers ignore it); on success it holds the solution. Not reaching the tolerance
    /// within the iteration budget is not an error (`converged: false`); breakdowns are.
    fn solve(
        &mut self,
        problem: &LinearProblem<'_>,
        b: &[f64],
        x: &mut [f64],
    ) -> Result<SolveInfo, SolveError>;

    /// Numeric factorisations done since the solver was made (default 0: it never factorises).
    fn factorizations(&self) -> u64 {
        0
    }

    /// Wall-clock seconds spent in numeric factorisations (and symbolic analyses) since the
    /// solver was made, for per-phase profiles (default 0: it never factorises). The rest of
    /// the time of [`LinearSolver::solve`] is the solve proper (triangular solves, CG).
    fn factorization_seconds(&self) -> f64 {
        0.0
    }

    /// Asks the solver to factorise the matrix of its next solve afresh instead of keeping an
    /// earlier factorisation (a caller that knows the matrix changed a lot, e.g. a
    /// Levenberg-Marquardt shift that moved, can spare the solver the iterations that would
    /// tell it). Default: nothing kept, nothing to do.
    fn invalidate_factorization(&mut self) {}

    /// Sets the relative residual `||b - A x|| <= tolerance ||b||` at which the following
    /// solves stop (an inexact Newton's forcing term: a solve need not be more accurate than
    /// the Newton step it serves). Iterative solvers take it; the default does nothing (a
    /// direct solver solves to round-off).
    fn set_relative_tolerance(&mut self, _tolerance: f64) {}
}
