//! Linear solvers as values behind one trait ([`LinearSolver`]), and the problem they solve
//! ([`LinearProblem`]): `A x = b` with
//!
//! `A = m_coef M + k_coef (K + sum_i c_i u_i u_i^T)`,
//!
//! `M` a lumped (diagonal) mass matrix, `K` the sparse part of a stiffness matrix and the `c_i u_i
//! u_i^T` dense low-rank terms ([`crate::LowRankTerm`]) that are never assembled. This is the
//! Newton matrix of backward Euler (Wang et al. 2015, Eq. 23, with `m_coef = 1 + dt alpha`, `k_coef
//! = dt^2 + dt beta`).
//!
//! One type per solver, each with its parameters (Params), a [`crate::SolveInfo`] on success and a
//! [`crate::SolveError`] on failure:
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

mod direct;
mod factorized;
mod matrix_free;
mod params;
mod pcg;
mod problem;
mod settings;

pub use direct::{CholeskyParams, CholeskySolver};
pub use factorized::{FactorizedPcg, FactorizedPcgParams, SINGLE_PRECISION_MIN_TOLERANCE};
pub use matrix_free::MatrixFreeCg;
pub use params::{CgParams, LinearSolverKind, LinearSolverParams, PcgPreconditioner};
pub use pcg::AssembledPcg;
pub use problem::{
    Correction, LinearProblem, LinearSolver, ProblemForm, StiffnessCorrection, StiffnessOperator,
};
pub use settings::SolverSettings;
