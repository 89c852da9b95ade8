//! Time integrators over generic systems for the `balloon` toolkit.
//!
//! **For:** advancing any mechanical system that can report masses, forces and force
//! differentials ([`ForceSystem`]) with backward Euler + Newton (seed 000, Eq. 18-23) using a
//! run-time choice of linear solver (any [`linear::LinearSolver`], from `balloon-linalg`), and any first-order ODE with explicit Euler, symplectic
//! Euler, midpoint or RK4 (seed 004, Ch. 5).
//!
//! **Not for:** knowing what the forces are. Nothing here knows about balloons, meshes or gas.
//!
//! Features: `parallel` (default on) forwards to `balloon-linalg/parallel`, so that
//! `BackwardEulerParams::parallel_factorization` can run the sparse Cholesky factorisation on
//! the rayon pool; without it the factorisation always runs on the calling thread.

pub mod explicit;
pub mod implicit;
pub mod system;

/// The linear algebra behind Newton's method: the `balloon-linalg` crate, re-exported under its
/// old path (`balloon_integrate::linear::LinearSolverKind` etc.).
pub use balloon_linalg as linear;

pub use system::{ForceSystem, LowRankTerm, StiffnessBlocks, SystemError, TangentKind};
