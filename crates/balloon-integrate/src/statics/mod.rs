//! Static equilibrium of a [`ForceSystem`] with a potential: Newton with a Levenberg-Marquardt
//! mass shift and an Armijo line search on the energy, and load continuation.
//!
//! The rest shape under a load minimises the static energy
//!
//! `E(x) = W(x) - f_ext . x`,
//!
//! `W` the system's potential ([`ForceSystem::potential_energy`]: for the shell the elastic
//! energy of Eq. 6-8 plus the gas potential whose gradient is the pressure force of Eq. 15).
//! This is the incremental potential of backward Euler ([`crate::implicit`]) without its inertia
//! term. Its stationarity condition is `r(x) = f(x) + f_ext = 0`.
//!
//! # Newton with a Levenberg-Marquardt shift
//!
//! Each iteration solves `(K + mu M) dx = r` with the configured linear solver (the seam of
//! [`crate::linear::LinearSolver`], `m_coef = mu`, `k_coef = 1`; the rank-1 gas term goes to
//! the solver as a low-rank term, Eq. 16-17). The shift `mu M` (mass-weighted, so it does not
//! depend on the mesh resolution) is the regularisation this module chose over a vanishing
//! pseudo-mass: a membrane has no out-of-plane stiffness where it is flat and unloaded, a free
//! body has a six-dimensional null space of rigid motions (nothing is pinned), and the pressure
//! follower term makes `K` indefinite; `K + mu M` is positive definite for `mu` large enough,
//! and then `dx` is a descent direction of `E`. `mu` is relative to the stiffness scale
//! `mu_ref = |diag K| / |m|` of the first linearisation; it starts at
//! [`StaticParams::initial_shift`]` mu_ref`, falls fourfold after a full step, rises by `2^c`
//! after a step the line search cut `c` times and tenfold when the factorisation meets a
//! non-positive pivot or the direction is not a descent direction, and never falls below
//! [`StaticParams::min_shift`]` mu_ref`. Near the solution the shift is tiny and Newton
//! converges quadratically on the exact Hessian; the rigid motions stay undetermined only up to
//! what the shift leaves of round-off (the residual has no component along them), or of the
//! preconditioner's rounding: a free body's solve removes them from every direction
//! ([`StaticParams::remove_rigid_motions`]; the shell sets it when nothing is pinned).
//!
//! # Reused factorisations
//!
//! The default linear solver keeps its sparse Cholesky factor across Newton iterations and
//! across solves ([`LinearSolverKind::FactorizedPcg`](crate::linear::LinearSolverKind::FactorizedPcg): CG on the current matrix preconditioned
//! by the kept factor, the rank-1 gas term by Sherman-Morrison in the preconditioner; the
//! symbolic analysis is reused while the pattern stays). The shift is the part of the matrix
//! that moves most far from the solution, so the solver refreshes the factor itself before a
//! solve whose shift differs from the factorised one by more than threefold, unless both are
//! below `1e-4 mu_ref` (where the shift no longer changes the preconditioner's quality: a
//! factor at `6e-5 mu_ref` preconditions the peer sphere's matrix at a fourfold smaller shift
//! in 3 CG iterations). Near the solution the shift stays small and the factor is kept; a
//! stale solve that stalls anyway is finished with a fresh factor by the linear solver. A stale
//! solve that meets non-positive curvature (the current matrix is indefinite: a thickness
//! update of the shell's outer loop can make it so) is retried with a tenfold shift on the same
//! kept factor, without the factorisation that would fail at a non-positive pivot.
//! [`LinearSolverKind::Cholesky`](crate::linear::LinearSolverKind::Cholesky) (refactorise every iteration) remains an option.
//!
//! The linear solves are inexact (inexact Newton, with a forcing term tied to the target
//! rather than Eisenstat and Walker's; [`StaticParams::inexact_forcing`]): an iterative solver
//! is asked for the relative residual `0.1 tol / |r|_rel` (between its own tolerance and
//! `0.1`), i.e. a linearised residual of a tenth of the stage's tolerance, which is all one
//! Newton step can use. Near the solution a
//! step then costs one CG iteration on the kept factor instead of the three to five that
//! reach `1e-8` (the peer sphere: 12 CG iterations for 11 Newton iterations instead of 32,
//! same Newton iterations, the same rest shape to `1e-9` of its diagonal). The convergence
//! test stays on the nonlinear residual.
//!
//! The line search halves the step from 1 until Armijo's condition
//! `E(x + s dx) <= E(x) - 1e-4 s r . dx` holds, an undefined energy (an inverted element, a
//! non-positive gas volume) counting as infinite; within the round-off of `E` a trial that
//! lowers `|r|` is accepted, as in the dynamic Newton ([`crate::implicit`], same constants).
//!
//! # Convergence test
//!
//! The same relative residual as the dynamic Newton: the residual force `|r|` (N) over the force
//! scale, the sum of the norms of the terms of `r` (the internal forces counted by
//! [`ForceSystem::force_scale`], e.g. the elastic and the pressure forces separately, plus
//! `|f_ext|`). In place of the dynamic test's inertial floor, the scale has the floor
//! `1e-10 |diag K| L` (`L` the bounding-box diagonal): the force that would move the body by
//! `1e-10 L` against its own stiffness, far below any loaded state but above the round-off of
//! the forces of an unloaded one.
//!
//! # Load continuation
//!
//! [`StaticSolver::solve_with_continuation`] first tries the full load from the given shape; if
//! that does not converge it starts again from the given shape and raises the load factor
//! ([`LoadScaling::set_load_factor`], external forces scaled alike) from 0 to 1 in adaptive
//! increments: an increment that converges (to [`StaticParams::continuation_tolerance`]) lets the
//! next one double, one that fails is rolled back and halved, at most
//! [`StaticParams::max_load_halvings`] times. The last stage, at the full load, converges to
//! [`StaticParams::tolerance`].
//!
//! # Stalled stages
//!
//! A stage runs while it makes progress: Newton iterates in windows of
//! [`StaticParams::stall_window`] (100) iterations, and a window that does not halve the best
//! relative residual of the stage ends it as stalled; otherwise it runs to
//! [`StaticParams::max_iterations`] (1000). A fixed cap per stage does not suit thin flat parts
//! (fins, wings, ears): their walls open by a nearly free motion, the exact tangent is
//! indefinite along the wrinkles of the compressed band where a fin meets the body, and
//! Newton's path at the full load is long but converging (a 0.1 m body with a 4 mm fin under
//! 1500 Pa: best residual `1.3e-1` after 75 iterations, `2.3e-3` after 200, converged before
//! 225). A cap of 200 threw that away, and the continuation from the rest shape cannot
//! do better: a flat wall has no stiffness against the pressure until it curves, its
//! deflection grows like the cube root of the load, so every load increment, however small,
//! starts equally far from its equilibrium (the relative residual of the 6 mm fin's stages
//! stalls at 0.2-0.28 from load factor 0.5 down to `2^-12`). Load halvings do not help there:
//! after [`StaticParams::max_stalled_stages`] (3) stalled increments in a row the solve stops
//! with [`StaticError::NoEquilibrium`](crate::newton::NewtonError::NoEquilibrium), which says
//! where the residual of the last iterate concentrates (the vertex with the largest residual
//! force and the share of `|r|^2` on the 5 % of vertices with the largest), keeps that iterate
//! ([`StaticSolver::stalled_iterate`]) for the caller to compute the smallest eigenvalue of the
//! stiffness there ([`StaticSolver::stability`]; the shell's static solve does), and leaves
//! `x` at the last converged load factor. Windows are calls of the same Newton core that
//! carry its state (iterate, residual, energy, shift), so a stage that does not stall takes
//! exactly the iterates of one call.
//!
//! ```
//! use balloon_integrate::linear::LinearSolverKind;
//! use balloon_integrate::statics::{StaticParams, StaticSolver};
//! use balloon_integrate::{ForceSystem, SystemError};
//!
//! /// A particle on a spring of stiffness `k` to the origin, pulled by an external force.
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
//! // This system cannot assemble its stiffness: matrix-free CG instead of the default Cholesky.
//! let mut params = StaticParams::default();
//! params.solver.linear.kind = LinearSolverKind::MatrixFreeCg;
//! let mut solver = StaticSolver::new(params)?;
//! let mut x = vec![0.0; 3];
//! let info = solver.solve(&mut system, 0.0, &mut x, Some(&[2.0, 0.0, -1.0]))?;
//! assert!(info.converged && info.relative_residual <= 1e-6);
//! // k x = f_ext.
//! assert!((x[0] - 0.02).abs() < 1e-9 && (x[2] + 0.01).abs() < 1e-9);
//! # Ok::<(), balloon_integrate::statics::StaticError>(())
//! ```
//!
//! # Files
//!
//! `params.rs` ([`StaticParams`], validated once), `info.rs` ([`StaticInfo`]), `solver.rs`
//! ([`StaticSolver`] and one load stage), `continuation.rs` (the load path); the Newton
//! iteration, its line search, Levenberg-Marquardt shift, convergence test and error are the
//! core of [`crate::newton`], shared with the backward Euler step.

mod anderson;
mod continuation;
mod info;
mod params;
mod solver;
mod stability;
#[cfg(test)]
mod tests;

pub use anderson::{Anderson, AndersonParams};
pub use info::StaticInfo;
pub use params::{DEFAULT_STALL_WINDOW, DEFAULT_STATIC_ITERATIONS, StaticParams};
pub use solver::StaticSolver;
pub use stability::{Stability, StabilityParams};

/// Phase timings (moved to [`crate::timing`]; kept here under their old path).
pub use crate::timing::PhaseTimes;

use crate::system::ForceSystem;

/// Errors of [`StaticSolver`]: the Newton core's error ([`crate::newton::NewtonError`]).
pub type StaticError = crate::newton::NewtonError;

/// A force system whose load can be scaled by a factor in `[0, 1]` (the gas load of the
/// shell, for example), for [`StaticSolver::solve_with_continuation`].
pub trait LoadScaling: ForceSystem {
    /// Scales the load from the next [`ForceSystem::forces`] call on (`1` = the full load).
    fn set_load_factor(&mut self, factor: f64);
}
