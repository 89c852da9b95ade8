//! Time integrators over generic systems for the `balloon` toolkit.
//!
//! **For:** advancing any mechanical system that can report masses, forces and force
//! differentials ([`ForceSystem`]) with backward Euler + Newton (Wang et al. 2015, Eq. 18-23)
//! using a run-time choice of linear solver (any [`linear::LinearSolver`], from
//! `balloon-linalg`), and any first-order ODE with explicit Euler, symplectic Euler, midpoint or
//! RK4 (Song 2009, Ch. 5); and solving for the static equilibrium of such a system directly
//! ([`statics::StaticSolver`]: the same energy without the inertia term, Newton with a
//! Levenberg-Marquardt shift, line search and load continuation). Both run on **one Newton
//! core** ([`newton`]: line search, regularisation, convergence test, the Newton matrix handed
//! to the linear solver, one error type).
//!
//! **Not for:** knowing what the forces are. Nothing here knows about balloons, meshes or gas.
//!
//! ```
//! use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
//! use balloon_integrate::{ForceSystem, SystemError};
//!
//! /// A 1 kg particle on a spring of stiffness `k` to the origin, with its potential.
//! struct Anchor {
//!     k: f64,
//!     m: [f64; 3],
//! }
//! impl ForceSystem for Anchor {
//!     fn num_dofs(&self) -> usize {
//!         3
//!     }
//!     fn masses(&self) -> &[f64] {
//!         &self.m
//!     }
//!     fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
//!         for i in 0..3 {
//!             f[i] = -self.k * x[i];
//!         }
//!         Ok(())
//!     }
//!     fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
//!         for i in 0..3 {
//!             df[i] -= self.k * dx[i];
//!         }
//!     }
//!     fn potential_energy(&mut self, _t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
//!         Ok(Some(0.5 * self.k * x.iter().map(|c| c * c).sum::<f64>()))
//!     }
//! }
//!
//! let mut system = Anchor { k: 100.0, m: [1.0; 3] };
//! let mut integrator = BackwardEuler::new(BackwardEulerParams::default())?;
//! let (mut x, mut v) = (vec![0.1, 0.0, 0.0], vec![0.0; 3]);
//! let mut energy = f64::INFINITY;
//! for n in 0..50 {
//!     let info = integrator.step(&mut system, n as f64 * 0.01, 0.01, &mut x, &mut v, None)?;
//!     assert!(info.converged);
//!     // Backward Euler dissipates: kinetic + spring energy never grows.
//!     let e = 0.5 * v.iter().map(|c| c * c).sum::<f64>() + 0.5 * 100.0 * x[0] * x[0];
//!     assert!(e <= energy * (1.0 + 1e-12));
//!     energy = e;
//! }
//! # Ok::<(), balloon_integrate::implicit::IntegrateError>(())
//! ```
//!
//! Features: `parallel` (default on) forwards to `balloon-linalg/parallel`, so that
//! `BackwardEulerParams::parallel_factorization` can run the sparse Cholesky factorisation on
//! the rayon pool; without it the factorisation always runs on the calling thread.

pub mod decorators;
pub mod explicit;
pub mod implicit;
pub mod newton;
pub mod statics;
pub mod substep;
pub mod system;
pub mod timing;

/// The linear algebra behind Newton's method: the `balloon-linalg` crate, re-exported under its
/// old path (`balloon_integrate::linear::LinearSolverKind` etc.).
pub use balloon_linalg as linear;

pub use implicit::check_time_step;
pub use system::{ForceSystem, LowRankTerm, StiffnessBlocks, SystemError, TangentKind};
pub use timing::PhaseTimes;
