//! The problem every solver solves ([`LinearProblem`], in matrix-free or assembled
//! [`ProblemForm`], the stiffness given as a [`StiffnessOperator`] in the matrix-free form) and
//! the trait every solver implements ([`LinearSolver`]).

use crate::csr::CsrMatrix;
use crate::error::SolveError;
use crate::info::SolveInfo;
use crate::low_rank::{LowRankTerm, add_low_rank_product};

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

/// A sparse correction `E` of an assembled stiffness: the problem's stiffness is
/// `K = K_sparse + E`, where `K_sparse` is what the matrix holds. A system gives one when the
/// matrix it assembles is a better *preconditioner* than its exact sparse stiffness (for
/// example with couplings that add fill to a Cholesky factor replaced by diagonal terms that
/// bound them): iterative solvers apply the whole `K`, and factorise only the matrix
/// ([`LinearSolver::accepts_correction`]).
pub trait StiffnessCorrection {
    /// `out += scale E p`.
    fn add_scaled(&self, scale: f64, p: &[f64], out: &mut [f64]);
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

/// The linear system `A x = b`, `A = m_coef M + k_coef (K + sum_i c_i u_i u_i^T)` (Wang et al.
/// 2015, Eq. 23), in matrix-free or assembled form ([`ProblemForm`]).
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
    /// With the assembled form, a correction `E` of the matrix's stiffness:
    /// `A = matrix + k_coef E` plus the low-rank terms ([`LinearProblem::with_correction`]).
    /// `None` (the default) when the matrix holds the whole sparse part.
    pub correction: Option<Correction<'a>>,
}

/// A [`StiffnessCorrection`] held by a [`LinearProblem`].
#[derive(Clone, Copy)]
pub struct Correction<'a>(pub &'a dyn StiffnessCorrection);

impl std::fmt::Debug for Correction<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Correction")
    }
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
            correction: None,
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
            correction: None,
        }
    }

    /// The same problem with the stiffness `K = K_sparse + E`: `E` applied by `correction`
    /// wherever the problem is applied ([`LinearProblem::apply`]), while the matrix (what a
    /// factorising solver factorises) holds `K_sparse` only. Only solvers that
    /// [accept a correction](LinearSolver::accepts_correction) may be given one; for the
    /// matrix-free form the correction is ignored (its operator is the whole `K`).
    pub fn with_correction(mut self, correction: &'a dyn StiffnessCorrection) -> Self {
        self.correction = Some(Correction(correction));
        self
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
                if let Some(Correction(c)) = self.correction {
                    c.add_scaled(self.k_coef, p, out);
                }
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

    /// Whether the solver solves a problem with a [`StiffnessCorrection`]
    /// ([`LinearProblem::with_correction`]) correctly: iterative solvers that apply the
    /// problem and use the matrix only to precondition do (they say so); a direct solver,
    /// which solves with the matrix itself, does not (the default `false`).
    fn accepts_correction(&self) -> bool {
        false
    }

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

    /// Tells the solver whether its caller answers a [`SolveError::NotPositiveDefinite`] with
    /// a larger diagonal shift and a new solve (a Newton core's shift ladder, `true`), so that
    /// the solver may give that verdict from a cheaper, less precise test: a wrong verdict then
    /// costs a larger shift, not a wrong answer. Default: ignored (every verdict is exact).
    fn set_shift_retries(&mut self, _retries: bool) {}
}
