//! Sparse linear algebra for the implicit integrators of the `balloon` toolkit.
//!
//! **For:** solving the Newton systems of implicit time stepping,
//! `A = m_coef M + k_coef (K + sum_i c_i u_i u_i^T)` with a lumped mass `M`, a sparse stiffness
//! `K` and dense low-rank terms that are never assembled (Wang et al. 2015, Eq. 16-17 and 23):
//!
//! * storage and assembly: [`CsrMatrix`] (the hot-path type), [`SparseAssembler`] (from triplets
//!   or dense element blocks, pattern reused while unchanged), conversion to and from
//!   [`sprs::CsMat`] (the type to hand to other code) and Matrix Market export
//!   ([`write_matrix_market`]);
//! * Krylov: preconditioned conjugate gradients ([`cg`]);
//! * preconditioners: Jacobi ([`jacobi`]), zero-fill incomplete Cholesky
//!   ([`IncompleteCholesky`]), a kept sparse factorisation ([`FactorizedPcg`]);
//! * sparse Cholesky by faer ([`SparseCholesky`], symbolic analysis reused);
//! * low-rank solves by Sherman-Morrison / Woodbury ([`solve_with_low_rank`], [`LowRankTerm`]);
//! * linear solvers as values behind one trait ([`LinearSolver`], one type per solver, each with
//!   Params / [`SolveInfo`] / [`SolveError`]), named for configuration by [`LinearSolverKind`]
//!   and built by [`SolverSettings::build`].
//!
//! **Not for:** knowing where the matrices come from (no forces, meshes or time steps here),
//! dense or general non-symmetric linear algebra (use nalgebra or faer directly), or
//! eigenproblems.
//!
//! Features: `parallel` (default on) lets the numeric Cholesky factorisation run on the rayon
//! thread pool when asked to; without it everything runs on the calling thread.
//!
//! ```
//! use balloon_linalg::{
//!     LinearProblem, LinearSolver, LinearSolverKind, LowRankTerm, SolverSettings,
//!     SparseAssembler,
//! };
//!
//! // A = 2 M + 1 (K + 0.5 u u^T): M = I, K the 1D Laplacian, u = (1, 1, 1, 1).
//! let n = 4;
//! let mut triplets = Vec::new();
//! for i in 0..n {
//!     triplets.push((i, i, 2.0));
//!     if i + 1 < n {
//!         triplets.push((i, i + 1, -1.0));
//!         triplets.push((i + 1, i, -1.0));
//!     }
//! }
//! let masses = vec![1.0; n];
//! let mut assembler = SparseAssembler::new();
//! assembler.assemble(&masses, 2.0, &triplets, 1.0)?;
//! let low_rank = [LowRankTerm { coefficient: 0.5, vector: vec![1.0; n] }];
//! let problem = LinearProblem::assembled(
//!     assembler.matrix(),
//!     assembler.pattern_version(),
//!     2.0,
//!     1.0,
//!     &low_rank,
//! );
//! let b = [1.0, 0.0, 0.0, 1.0];
//! for kind in [LinearSolverKind::Pcg, LinearSolverKind::Cholesky] {
//!     let mut settings = SolverSettings::default();
//!     settings.linear.kind = kind;
//!     let mut solver: Box<dyn LinearSolver> = settings.build();
//!     let mut x = vec![0.0; n];
//!     let info = solver.solve(&problem, &b, &mut x)?;
//!     assert!(info.converged, "{kind}");
//!     // Check A x = b.
//!     let mut ax = vec![0.0; n];
//!     problem.apply(&x, &mut ax);
//!     assert!(ax.iter().zip(&b).all(|(a, b)| (a - b).abs() < 1e-8));
//! }
//! // The assembled sparse part as a `sprs` matrix.
//! let a = assembler.to_csmat()?;
//! assert_eq!(a.nnz(), 10);
//! # Ok::<(), balloon_linalg::SolveError>(())
//! ```

mod assemble;
mod cholesky;
mod csr;
mod error;
mod info;
mod krylov;
mod low_rank;
mod precond;
mod solver;
mod vector;

pub use assemble::{SparseAssembler, StiffnessBlocks};
pub use cholesky::{PARALLEL_FACTORIZATION_ROWS, SOLVE_BATCH_COLUMNS, SparseCholesky};
pub use csr::{CsrMatrix, read_matrix_market, write_matrix_market};
pub use error::SolveError;
pub use info::{Preconditioner, SolveInfo};
pub use krylov::{CgWorkspace, cg};
pub use low_rank::{LowRankTerm, add_low_rank_product, solve_with_low_rank};
pub use precond::{IncompleteCholesky, jacobi};
pub use solver::{
    AssembledPcg, CgParams, CholeskyParams, CholeskySolver, Correction, FactorizedPcg,
    FactorizedPcgParams, LinearProblem, LinearSolver, LinearSolverKind, LinearSolverParams,
    MatrixFreeCg, PcgPreconditioner, ProblemForm, SINGLE_PRECISION_MIN_TOLERANCE, SolverSettings,
    StiffnessCorrection, StiffnessOperator,
};
pub use sprs;
pub use vector::dot;

#[cfg(test)]
mod tests;
