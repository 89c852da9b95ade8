//! Backward Euler with Newton-Raphson on velocities (seed 000, Eq. 18-23), globalised as the
//! minimisation of an incremental potential.
//!
//! Unknown: the end-of-step velocity `v`. With `x(v) = x^n + dt v`, backward Euler (Eq. 18) is
//! the nonlinear equation
//!
//! `r(v) = M (v - v^n) - dt (f(x(v)) + f_ext - C v) = 0`, `C = alpha M + beta K`.
//!
//! Newton from `v_(0) = v^n` solves, at each iterate `x_(k) = x^n + dt v_(k)`,
//!
//! `A dv = b`, `A = M + dt C + dt^2 K(x_(k)) = (1 + dt alpha) M + (dt^2 + dt beta) K`,
//! `b = M (v^n - v_(k)) + dt (f(x_(k)) + f_ext - C v_(k))` (Eq. 23),
//!
//! then `v_(k+1) = v_(k) + s dv` with a step length `s` from the line search. `K = -df/dx` is
//! the system's tangent stiffness (elastic plus gas, the latter's rank-1 part never assembled).
//! On a linear force system one iteration is exact.
//!
//! # Incremental potential
//!
//! When the system has a potential `W` (`f = -dW/dx`, [`ForceSystem::potential_energy`]) and
//! `beta = 0`, the backward Euler step is the minimiser of
//!
//! `E(x) = (1 + dt alpha) / (2 dt^2) |x - x^n - dt v^n / (1 + dt alpha)|_M^2 + W(x) - f_ext . x`.
//!
//! Mass damping is folded in: the damping force `-alpha M v = -alpha M (x - x^n) / dt` is the
//! negative gradient of `alpha / (2 dt) |x - x^n|_M^2`, and adding that to the inertia term
//! `1 / (2 dt^2) |x - x^n - dt v^n|_M^2` completes the square above (up to a constant). Then
//! `dE/dx = -b / dt` and `d^2E/dx^2 = A / dt^2`, so the Newton step `dx = dt dv` is Newton on
//! `E`, a descent direction whenever `A` is positive definite (which the projected tangent or
//! the mass-shift retry ensures), with `dE = -s b . dv` to first order. The line search halves
//! `s` from 1 until Armijo's condition `E(v + s dv) <= E(v) - 1e-4 s b . dv` holds; a state
//! where `E` is undefined (an inverted element) counts as `E = inf`. Close to convergence the
//! decrease falls below what `f64` resolves in `E`; a trial within round-off of `E` is then
//! accepted when it lowers `|b|`. Internally `E` is evaluated in the velocity form
//! `(1 + dt alpha)/2 |v - v^n/(1 + dt alpha)|_M^2 + W(x(v)) - dt f_ext . v`, which differs from
//! `E(x)` by a constant. [`StepInfo::energies`] records it at every accepted iterate.
//!
//! Stiffness damping `beta K v` has no potential: with `beta > 0` (and for a direction that is
//! not a descent direction of `E`) the search backtracks on the residual norm instead,
//! `|b(v + s dv)| <= (1 - 1e-4 s) |b(v)|`, taking the shortest step if none decreases it.
//! Systems without a potential take full Newton steps (as before), still stopped on the
//! residual.
//!
//! # Convergence test
//!
//! Newton stops when the residual force `|b| / dt` (N) is at most
//! [`BackwardEulerParams::newton_tolerance`] times the force scale
//!
//! `F = |M (v - v^n)| / dt + F_int + |f_ext| + |C v|`,
//!
//! the sum of the norms of the terms of `r / dt` at the current iterate, with the internal
//! forces counted by [`ForceSystem::force_scale`] (for the shell: the norms of the elastic and of
//! the pressure forces separately, which balance at an inflated rest shape) or `|f|`. Every term
//! is a force norm over the same degrees of freedom, so the ratio does not depend on the units,
//! the size of the model or its resolution. At rest every term vanishes and `|b|` is round-off,
//! so `F` has a floor `F_0 = 1e-3 |m| L / dt^2` (`|m|` the norm of the masses, `L` the
//! bounding-box diagonal of `x^n`): the residual force that moves the body by `1e-3 L` in one
//! step, far below the forces of any loaded state; a residual below `tol F_0` leaves the
//! positions off by about `1e-3 tol L` at most. A step that does not converge within
//! [`BackwardEulerParams::newton_iterations`] is [`IntegrateError::NotConverged`].
//! `newton_tolerance = 0` is the paper's mode: a fixed number of full Newton steps, no line
//! search and no residual test (the residual of the result is still reported).
//!
//! # Reused tangent (chord steps)
//!
//! Near rest a step is settled by one Newton iteration, whose cost is mostly the tangent: the
//! stiffness evaluation and the assembly of `A` (on the teddy with the paper's gas, 7.4 and 3.7
//! ms of a 25 ms step). After such a step the next step's first iteration solves with the same
//! `A` and low-rank terms (a chord, or Shamanskii, step), evaluating only the forces at
//! `v^n`. The direction is the only thing that changes: the step is still line-searched and
//! stopped on the residual test above, so it converges to the same tolerance, and a second
//! iteration, if the tolerance asks for one, linearises at its own iterate. A chord step the
//! line search would cut is dropped (the iteration is repeated from the same iterate with its
//! own tangent). Conditions: [`BackwardEulerParams::tangent_reuse_steps`] (at most that many in
//! a row), an assembled linear solver, no stiffness damping, a residual test, the same `dt` and
//! no regularisation shift in the matrix. [`StepInfo::reused_tangent`] says when it was used.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use std::path::Path;
use std::time::Instant;

use balloon_linalg::sprs::CsMat;
use balloon_linalg::{
    LinearProblem, LinearSolver, LinearSolverParams, PcgPreconditioner, Preconditioner, SolveError,
    SolveInfo, SolverSettings, SparseAssembler, StiffnessOperator,
};

use crate::system::{ForceSystem, LowRankTerm, SystemError, TangentKind};
use crate::timing::{PhaseTimes, ms_since};

/// Default [`BackwardEulerParams::newton_iterations`]: the most Newton iterations a step may
/// take.
pub const DEFAULT_NEWTON_ITERATIONS: usize = 30;

/// Default [`BackwardEulerParams::newton_tolerance`] (relative residual). Newton always takes
/// at least one iteration.
pub const DEFAULT_NEWTON_TOLERANCE: f64 = 1e-6;

/// Parameters of [`BackwardEuler`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BackwardEulerParams {
    /// Maximum Newton iterations per step (default [`DEFAULT_NEWTON_ITERATIONS`]; at least 1,
    /// at most [`MAX_NEWTON_ITERATIONS`]). In the paper's mode (`newton_tolerance = 0`) exactly
    /// this many full steps (the paper: 3).
    pub newton_iterations: usize,
    /// Newton stops when the relative residual `|b| / (dt F)` (the residual force over the
    /// force scale `F`, module docs) is at most this (default
    /// [`DEFAULT_NEWTON_TOLERANCE`]); a step that does not get there within
    /// `newton_iterations` is [`IntegrateError::NotConverged`]. `0` is the paper's mode:
    /// `newton_iterations` full Newton steps, no line search, no residual test.
    pub newton_tolerance: f64,
    /// The linear solver and its tolerances.
    pub linear: LinearSolverParams,
    /// Rayleigh mass damping `alpha`, 1/s (`C = alpha M + beta K`; default 0).
    pub mass_damping: f64,
    /// Rayleigh stiffness damping `beta`, s (default 0).
    pub stiffness_damping: f64,
    /// Gravitational acceleration, m/s^2, applied as `m_i g` per degree of freedom (default 0).
    pub gravity: [f64; 3],
    /// What to do when the Newton matrix `A = M + dt C + dt^2 K` is not positive definite (CG meets
    /// non-positive curvature, or the Cholesky factorisation meets a non-positive pivot), as
    /// happens when a membrane is compressed (St. Venant-Kirchhoff is not convex in compression,
    /// and a shell without bending buckles). With `true` (default) the solve is retried with a
    /// mass shift `A + tau M`, `tau` growing tenfold per retry (Levenberg-Marquardt): the Newton
    /// step is shortened but the residual it reduces, and so the backward Euler solution, is
    /// unchanged. The next Newton iteration of the step starts from a quarter of the shift
    /// that worked (down to none), rather than from 0 again. With `false` the solver error is
    /// returned.
    pub regularize_indefinite: bool,
    /// Preconditioner of the assembled PCG solver (default Jacobi; ignored by the others).
    pub pcg_preconditioner: PcgPreconditioner,
    /// Which tangent stiffness the system linearises with (default [`TangentKind::Exact`];
    /// [`TangentKind::Projected`] is projected Newton: an SPD Newton matrix at every iterate, so
    /// no regularisation retries). Passed to [`ForceSystem::set_tangent`] at every step.
    pub tangent: TangentKind,
    /// [`crate::linear::LinearSolverKind::FactorizedPcg`] only: when a solve with the lagged Cholesky
    /// preconditioner takes more than this many CG iterations (default 8), the next 6 solves
    /// refactorise first, then the lagged factor is tried again. A solve with a lagged factor
    /// that does not converge within `2 x refactor_iterations` iterations (or breaks down
    /// numerically) is continued with a fresh factorisation of the current matrix; one that
    /// meets non-positive curvature reports the matrix indefinite.
    pub refactor_iterations: usize,
    /// Run the numeric sparse Cholesky factorisation (Cholesky and factorized PCG) on the rayon
    /// thread pool (default `false`: sequential).
    pub parallel_factorization: bool,
    /// [`crate::linear::LinearSolverKind::FactorizedPcg`] only: the cost of a factorisation in
    /// CG iterations; the kept factor is refreshed once the solves with it have taken that many
    /// iterations more than the first solve after the factorisation (default 0: off; see
    /// `balloon_linalg::FactorizedPcgParams::refactor_cost`).
    pub refactor_cost: usize,
    /// Steps in a row whose first Newton iteration may reuse the Newton matrix of the previous
    /// step (a chord iteration; default [`DEFAULT_TANGENT_REUSE_STEPS`], `0`: never). Only with
    /// an assembled linear solver, no stiffness damping, a residual test
    /// (`newton_tolerance > 0`), the same `dt` as the step that assembled the matrix, and after
    /// a converged step whose last matrix needed no regularisation shift. The reused matrix
    /// only chooses the direction: the step is still line-searched, stopped on the residual at
    /// the new iterate and so converges to the same tolerance. A chord step the line search
    /// would cut is not taken: the step goes on with a fresh tangent from the same iterate.
    /// Near rest, where one Newton iteration per step is all the tolerance asks for, it saves
    /// the stiffness evaluation and the assembly of most steps (module docs, "Reused tangent").
    pub tangent_reuse_steps: usize,
    /// Inexact Newton: each linear solve is asked for a linearised residual of this fraction
    /// of `newton_tolerance` (the relative CG tolerance `inexact_forcing * newton_tolerance /
    /// |r|_rel`, at most `0.1`, at least `linear.relative_tolerance`; default
    /// [`DEFAULT_INEXACT_FORCING`]). `0` solves every step to `linear.relative_tolerance`.
    /// Iterative linear solvers only (a direct solve is exact); not in the paper's mode. The
    /// convergence test stays on the nonlinear residual, so the result is unchanged to the
    /// Newton tolerance.
    pub inexact_forcing: f64,
}

/// Default [`BackwardEulerParams::inexact_forcing`] (and the static solver's): a linear solve
/// brings the linearised residual to a tenth of the Newton tolerance.
pub const DEFAULT_INEXACT_FORCING: f64 = 0.1;

/// The relative tolerance an inexact Newton step asks of its linear solve: `forcing * tol /
/// relative_residual`, clamped to `[floor, 0.1]` (`floor`: the solver's own tolerance; a
/// `forcing` of 0 gives `floor`).
pub(crate) fn forcing_tolerance(forcing: f64, tol: f64, relative_residual: f64, floor: f64) -> f64 {
    const LOOSEST: f64 = 0.1;
    let floor = floor.min(LOOSEST);
    let eta = forcing * tol / relative_residual;
    if eta.is_finite() {
        eta.clamp(floor, LOOSEST)
    } else {
        floor
    }
}

/// Default [`BackwardEulerParams::tangent_reuse_steps`].
pub const DEFAULT_TANGENT_REUSE_STEPS: usize = 8;

impl BackwardEulerParams {
    /// The settings [`SolverSettings::build`] makes the configured linear solver from.
    pub fn solver_settings(&self) -> SolverSettings {
        SolverSettings {
            linear: self.linear,
            pcg_preconditioner: self.pcg_preconditioner,
            refactor_iterations: self.refactor_iterations,
            parallel_factorization: self.parallel_factorization,
            refactor_cost: self.refactor_cost,
        }
    }
}

impl Default for BackwardEulerParams {
    fn default() -> Self {
        Self {
            newton_iterations: DEFAULT_NEWTON_ITERATIONS,
            newton_tolerance: DEFAULT_NEWTON_TOLERANCE,
            linear: LinearSolverParams::default(),
            mass_damping: 0.0,
            stiffness_damping: 0.0,
            gravity: [0.0; 3],
            regularize_indefinite: true,
            pcg_preconditioner: PcgPreconditioner::Jacobi,
            tangent: TangentKind::Exact,
            refactor_iterations: 8,
            parallel_factorization: false,
            refactor_cost: 0,
            tangent_reuse_steps: DEFAULT_TANGENT_REUSE_STEPS,
            inexact_forcing: DEFAULT_INEXACT_FORCING,
        }
    }
}

/// What one [`BackwardEuler::step`] did.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StepInfo {
    /// Newton iterations performed (linear solves).
    pub newton_iterations: usize,
    /// CG iterations per Newton iteration (for Cholesky: 1 + iterative-refinement steps).
    pub linear_iterations: Vec<usize>,
    /// Final relative residual `||b - A dv|| / ||b||` per Newton iteration.
    pub linear_residuals: Vec<f64>,
    /// `||b_k||` (N s) at each Newton iterate evaluated (the last one is the result's, except in
    /// the paper's mode, which never evaluates its result: there it is the last iterate's before
    /// the final update).
    pub newton_residuals: Vec<f64>,
    /// Relative residual (module docs) at each Newton iterate evaluated.
    pub relative_residuals: Vec<f64>,
    /// Relative residual of the result: `|b| / (dt F)`, the residual force over the force scale
    /// `F` (module docs). In the paper's mode (`newton_tolerance = 0`) the residual of the last
    /// iterate Newton evaluated, before its final update: evaluating the result only for the
    /// record would cost a fourth force and stiffness evaluation per step (measured 3-13% of the
    /// step time in `cargo xtask bench --quick`).
    pub relative_residual: f64,
    /// Halvings of Newton steps made by the line search over the step.
    pub line_search_cuts: usize,
    /// The incremental potential (J, up to a constant; module docs) at the first iterate and
    /// at every accepted one, when the system has a potential and the energy line search runs
    /// (empty otherwise). Non-increasing by construction (up to round-off).
    pub energies: Vec<f64>,
    /// Whether the step converged: with `newton_tolerance > 0` always `true` for a returned
    /// step (a non-converged one is [`IntegrateError::NotConverged`]); in the paper's mode
    /// (`newton_tolerance = 0`, no residual test) whether every linear solve met its
    /// tolerance.
    pub converged: bool,
    /// Linear solves that had to be retried with a mass shift because `A` was indefinite (see
    /// [`BackwardEulerParams::regularize_indefinite`]).
    pub regularized_solves: usize,
    /// Largest mass shift `tau` used in the step (0 when none was needed), relative to the mass
    /// matrix: the solved matrix was `(1 + dt alpha + tau) M + (dt^2 + dt beta) K`.
    pub max_regularization: f64,
    /// Numeric sparse Cholesky factorisations done in the step (Cholesky: one per solve;
    /// factorized PCG: only when the lagged preconditioner was refreshed).
    pub factorizations: usize,
    /// Wall-clock time of the step per phase (the integrator's phases; `projection_ms` is 0
    /// here: the shell adds its projection).
    #[serde(default)]
    pub times: PhaseTimes,
    /// The first Newton iteration reused the previous step's Newton matrix (a chord step,
    /// [`BackwardEulerParams::tangent_reuse_steps`]) and its step was taken.
    #[serde(default)]
    pub reused_tangent: bool,
}

impl StepInfo {
    /// Total linear-solver iterations over the step.
    pub fn total_linear_iterations(&self) -> usize {
        self.linear_iterations.iter().sum()
    }
}

/// Checks a time step (s): positive and finite. The one check of dt for the implicit
/// integrator and the systems stepped by it (the shell calls it when dt is set, so a bad dt is
/// refused before any work).
pub fn check_time_step(dt: f64) -> Result<f64, IntegrateError> {
    if dt.is_finite() && dt > 0.0 {
        Ok(dt)
    } else {
        Err(IntegrateError::InvalidParameter {
            name: "dt",
            value: dt,
            allowed: "positive and finite (s)",
        })
    }
}

/// Errors of [`BackwardEuler::step`].
#[derive(Debug, Error, Clone, PartialEq)]
pub enum IntegrateError {
    /// The force system failed (inverted element, non-finite gas volume, ...).
    #[error("force system error in Newton iteration {iteration}: {source}")]
    System {
        /// Newton iteration (0-based).
        iteration: usize,
        /// The system's error.
        #[source]
        source: SystemError,
    },
    /// The linear solver broke down (non-positive curvature, Cholesky failure, ...).
    #[error("linear solver failed in Newton iteration {iteration}: {source}")]
    Linear {
        /// Newton iteration (0-based).
        iteration: usize,
        /// The solver's error.
        #[source]
        source: SolveError,
    },
    /// A position, velocity or force became NaN or infinite.
    #[error("non-finite {quantity} at dof {dof} (vertex {vertex}) in Newton iteration {iteration}")]
    NonFinite {
        /// "position", "velocity" or "force".
        quantity: &'static str,
        /// Degree of freedom.
        dof: usize,
        /// Vertex `dof / 3`.
        vertex: usize,
        /// Newton iteration (0-based).
        iteration: usize,
    },
    /// A parameter is out of its range (the time step, a damping coefficient, the Newton
    /// tolerance or iteration bound, gravity). Pass a value in `allowed`.
    #[error("invalid parameter: `{name}` = {value:e} must be {allowed}")]
    InvalidParameter {
        /// The parameter (`dt`, `mass_damping`, ..., as in [`BackwardEulerParams`]).
        name: &'static str,
        /// The value given.
        value: f64,
        /// Its admissible range, in words.
        allowed: &'static str,
    },
    /// An array handed to [`BackwardEuler::step`] does not have one entry per degree of freedom.
    #[error("invalid input: `{what}` has length {len}, the system has {expected} dofs")]
    LengthMismatch {
        /// Which array (`x`, `v`, `masses`, `external_forces`).
        what: &'static str,
        /// Its length.
        len: usize,
        /// The system's number of degrees of freedom.
        expected: usize,
    },
    /// A lumped mass is not positive and finite.
    #[error("invalid input: mass of dof {dof} (vertex {vertex}) is {mass:e} kg; must be positive")]
    InvalidMass {
        /// Degree of freedom.
        dof: usize,
        /// Vertex `dof / 3`.
        vertex: usize,
        /// The mass, kg.
        mass: f64,
    },
    /// Newton did not bring the relative residual down to the tolerance within the allowed
    /// iterations (or the line search found no acceptable step): the step is not accepted.
    #[error(
        "Newton did not converge: relative residual {residual:.3e} after {iterations} iterations (tolerance {tolerance:e})"
    )]
    NotConverged {
        /// Newton iterations done.
        iterations: usize,
        /// Relative residual at the last iterate (see [`StepInfo::relative_residual`]).
        residual: f64,
        /// [`BackwardEulerParams::newton_tolerance`].
        tolerance: f64,
    },
}

/// Backward Euler + Newton integrator holding scratch buffers, the cached sparse pattern and
/// its linear solver (a [`LinearSolver`] value, by default the one
/// [`BackwardEulerParams::linear`] names), reused across Newton iterations and steps.
///
/// Any linear solver plugs in with one line, [`BackwardEuler::with_linear_solver`]; here a
/// user's own (unpreconditioned CG on the matrix-free Newton matrix):
///
/// ```
/// use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
/// use balloon_integrate::linear::{
///     CgWorkspace, LinearProblem, LinearSolver, SolveError, SolveInfo, cg,
/// };
/// use balloon_integrate::{ForceSystem, SystemError};
///
/// /// Plain CG, counting its solves.
/// #[derive(Debug, Default)]
/// struct PlainCg {
///     workspace: CgWorkspace,
///     solves: usize,
/// }
///
/// impl LinearSolver for PlainCg {
///     fn name(&self) -> &str {
///         "plain-cg"
///     }
///     fn needs_assembled_matrix(&self) -> bool {
///         false
///     }
///     fn solve(
///         &mut self,
///         problem: &LinearProblem<'_>,
///         b: &[f64],
///         x: &mut [f64],
///     ) -> Result<SolveInfo, SolveError> {
///         self.solves += 1;
///         let identity = |r: &[f64], z: &mut [f64]| z.copy_from_slice(r);
///         cg(|p, out| problem.apply(p, out), identity, b, x, 100, 1e-10, &mut self.workspace)
///     }
/// }
///
/// /// One particle on a linear spring to the origin, `f = -k x`.
/// struct Spring {
///     masses: Vec<f64>,
///     k: f64,
/// }
///
/// impl ForceSystem for Spring {
///     fn num_dofs(&self) -> usize {
///         3
///     }
///     fn masses(&self) -> &[f64] {
///         &self.masses
///     }
///     fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
///         f.iter_mut().zip(x).for_each(|(f, x)| *f = -self.k * x);
///         Ok(())
///     }
///     fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
///         df.iter_mut().zip(dx).for_each(|(df, dx)| *df -= self.k * dx);
///     }
/// }
///
/// let mut be = BackwardEuler::new(BackwardEulerParams::default())
///     .with_linear_solver(Box::new(PlainCg::default()));
/// assert_eq!(be.linear_solver().name(), "plain-cg");
/// let mut system = Spring { masses: vec![1.0; 3], k: 100.0 };
/// let (mut x, mut v) = (vec![0.1, 0.0, 0.0], vec![0.0; 3]);
/// let info = be.step(&mut system, 0.0, 0.01, &mut x, &mut v, None)?;
/// assert!(info.converged);
/// // Backward Euler on a linear spring: v1 = -dt k x0 / (m + dt^2 k).
/// assert!((v[0] - (-0.01 * 100.0 * 0.1 / (1.0 + 1e-4 * 100.0))).abs() < 1e-9);
/// # Ok::<(), balloon_integrate::implicit::IntegrateError>(())
/// ```
#[derive(Debug)]
pub struct BackwardEuler {
    /// Parameters (may be changed between steps; a change of the linear-solver settings makes
    /// a new solver of the configured kind, unless a solver was plugged in with
    /// [`BackwardEuler::with_linear_solver`]).
    pub params: BackwardEulerParams,
    x_n: Vec<f64>,
    v_n: Vec<f64>,
    f: Vec<f64>,
    f_ext: Vec<f64>,
    b: Vec<f64>,
    dv: Vec<f64>,
    tmp: Vec<f64>,
    kv: Vec<f64>,
    /// The velocities of a line-search trial.
    v_trial: Vec<f64>,
    /// The floor `F_0` of the force scale in this step, N (module docs).
    scale_floor: f64,
    /// `|kinetic| + |W| + |external|` parts of the last incremental potential evaluated, J:
    /// the magnitude its round-off is relative to.
    energy_magnitude: f64,
    triplets: Vec<(usize, usize, f64)>,
    assembler: SparseAssembler,
    /// The linear solver of Eq. 23.
    solver: Box<dyn LinearSolver>,
    /// The settings `solver` was built from; `None` for a solver plugged in by the user.
    solver_settings: Option<SolverSettings>,
    /// The preconditioner of the last successful linear solve.
    last_preconditioner: Preconditioner,
    /// Whether the assembler holds the matrix of the last linear solve.
    assembled_last: bool,
    /// `(m_coef, k_coef)` of the matrix in the assembler when the next step's first Newton
    /// iteration may reuse it ([`BackwardEulerParams::tangent_reuse_steps`]); `None` when not.
    reusable_matrix: Option<(f64, f64)>,
    /// Steps in a row whose first iteration reused the matrix.
    reused_steps: usize,
    /// The low-rank terms that go with the assembled matrix (for its reuse).
    kept_low_rank: Vec<LowRankTerm>,
    /// The mass shift of the last successful linear solve (0 without regularisation).
    last_shift: f64,
    /// The system gave its stiffness as element blocks (`self.triplets` holds only the rest).
    use_blocks: bool,
    /// Running total of the time per phase over every step (also failed ones).
    times: PhaseTimes,
}

impl Default for BackwardEuler {
    fn default() -> Self {
        Self::new(BackwardEulerParams::default())
    }
}

/// The stiffness of a [`ForceSystem`] as a matrix-free operator: `K p = -df(p)` from its force
/// differentials (low-rank terms included), and the diagonal of its sparse part when offered.
struct SystemStiffness<'a, S>(&'a S);

impl<S: ForceSystem> StiffnessOperator for SystemStiffness<'_, S> {
    fn apply(&self, p: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        self.0.add_force_differential(p, out);
        for o in out.iter_mut() {
            *o = -*o;
        }
    }

    fn add_diagonal(&self, diagonal: &mut [f64]) -> bool {
        self.0.add_stiffness_diagonal(diagonal).is_ok()
    }
}

/// Sufficient-decrease constant of the Armijo line search: a step of length `s` along `dv` is
/// accepted when `E(v + s dv) <= E(v) - ARMIJO s (b . dv)` (or, for the residual-norm search,
/// `|b(v + s dv)| <= (1 - ARMIJO s) |b(v)|`).
pub(crate) const ARMIJO: f64 = 1e-4;

/// Halvings of the Newton step the line search tries before giving up (shortest step
/// `2^-20`).
pub(crate) const MAX_LINE_SEARCH_CUTS: usize = 20;

/// Relative round-off of the incremental potential: energy changes below this times the
/// magnitude of its parts are not resolved, and the residual decides instead.
pub(crate) const ENERGY_ROUNDOFF: f64 = 1e-12;

/// Upper bound on [`BackwardEulerParams::newton_iterations`].
pub const MAX_NEWTON_ITERATIONS: usize = 1000;

/// Newton iterations over which the relative residual must at least halve. When it does not
/// (and is still above the tolerance) the solve has stalled, typically because the time step
/// is far longer than the time scale of the motion, so that the incremental potential is
/// strongly non-convex along the way: the step stops at once as
/// [`IntegrateError::NotConverged`], and the caller's step halving takes over instead of
/// spending the remaining iterations. Not applied in the paper's mode.
pub const NEWTON_STALL_WINDOW: usize = 8;

/// How the Newton step is shortened in one iteration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LineSearch {
    /// Armijo backtracking on the incremental potential.
    Energy,
    /// Backtracking on the norm of the residual (no potential with stiffness damping, or a
    /// direction that is not a descent direction of the potential).
    Residual,
    /// Full Newton steps (a system without a potential).
    Off,
}

/// The Newton residual at one iterate: `|b|` (N s) and the force scale (N) it is relative to.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Residual {
    pub(crate) norm: f64,
    pub(crate) scale: f64,
    pub(crate) dt: f64,
}

impl Residual {
    /// `|b| / (dt F)`: the residual force relative to the force scale `F` (module docs).
    pub(crate) fn relative(&self) -> f64 {
        let force = self.norm / self.dt;
        if force == 0.0 {
            0.0
        } else if self.scale > 0.0 {
            force / self.scale
        } else {
            f64::INFINITY
        }
    }
}

/// Retries of an indefinite linear solve with a growing mass shift before giving up.
pub(crate) const MAX_REGULARIZATION_RETRIES: usize = 14;

/// The next mass shift `tau` after an indefinite solve: from CG's Rayleigh quotient when there
/// is one (enough to make that direction positive with margin), otherwise 1% of the mass
/// coefficient, and tenfold the previous shift on later retries.
fn next_shift(previous: f64, m_coef: f64, err: &SolveError, masses: &[f64]) -> f64 {
    if previous > 0.0 {
        return previous * 10.0;
    }
    let m_min = masses
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min)
        .max(f64::MIN_POSITIVE);
    match err {
        SolveError::NonPositiveCurvature {
            curvature,
            direction_norm_squared,
            ..
        } if *direction_norm_squared > 0.0 => {
            (2.0 * curvature.abs() / (direction_norm_squared * m_min)).max(1e-2 * m_coef)
        }
        _ => 1e-2 * m_coef,
    }
}

/// A regularised Newton iteration hands this fraction of its mass shift to the next one as
/// the shift to try first ([`start_shift`]).
pub(crate) const SHIFT_DECAY: f64 = 0.25;

/// The mass shift the next Newton iteration of a step tries first after one that needed
/// `last` (relative to the mass matrix, like `m_coef`): `SHIFT_DECAY * last`, or 0 (no
/// regularisation) once that falls below `1e-3 m_coef`. Measured on the built-in teddy's first
/// five default steps (`balloon inflate --steps 5`): starting every iteration from 0 took 137
/// Newton iterations, 4 rejected sub-steps and 11.8 s; this 68, none and 5.6 s.
pub(crate) fn start_shift(last: f64, m_coef: f64) -> f64 {
    let next = SHIFT_DECAY * last;
    if next < 1e-3 * m_coef { 0.0 } else { next }
}

/// The floor of the force scale relative to `|m| L / dt^2` (module docs).
const SCALE_FLOOR: f64 = 1e-3;

pub(crate) fn norm(v: &[f64]) -> f64 {
    v.iter().map(|a| a * a).sum::<f64>().sqrt()
}

/// The diagonal of the bounding box of `x` read as 3D points (the range of the values when the
/// length is not a multiple of 3), m.
pub(crate) fn extent(x: &[f64]) -> f64 {
    if !x.len().is_multiple_of(3) {
        let (lo, hi) = x
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        return if hi >= lo { hi - lo } else { 0.0 };
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in x.chunks_exact(3) {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    (0..3)
        .map(|c| (hi[c] - lo[c]).max(0.0).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Copies `terms` into `kept`, re-using its buffers.
fn keep_low_rank(kept: &mut Vec<LowRankTerm>, terms: &[LowRankTerm]) {
    kept.resize_with(terms.len(), LowRankTerm::default);
    for (k, t) in kept.iter_mut().zip(terms) {
        k.coefficient = t.coefficient;
        k.vector.clear();
        k.vector.extend_from_slice(&t.vector);
    }
}

pub(crate) fn first_non_finite(v: &[f64]) -> Option<usize> {
    v.iter().position(|a| !a.is_finite())
}

impl BackwardEuler {
    /// A new integrator.
    pub fn new(params: BackwardEulerParams) -> Self {
        let settings = params.solver_settings();
        Self {
            params,
            x_n: Vec::new(),
            v_n: Vec::new(),
            f: Vec::new(),
            f_ext: Vec::new(),
            b: Vec::new(),
            dv: Vec::new(),
            tmp: Vec::new(),
            kv: Vec::new(),
            v_trial: Vec::new(),
            scale_floor: 0.0,
            energy_magnitude: 0.0,
            triplets: Vec::new(),
            assembler: SparseAssembler::new(),
            solver: settings.build(),
            solver_settings: Some(settings),
            last_preconditioner: Preconditioner::Unreported,
            assembled_last: false,
            reusable_matrix: None,
            reused_steps: 0,
            kept_low_rank: Vec::new(),
            last_shift: 0.0,
            use_blocks: false,
            times: PhaseTimes::default(),
        }
    }

    /// Wall-clock time per phase (forces, energies, assembly, factorisations, solves) summed
    /// over every step this integrator took, including steps that failed: the difference of
    /// two readings is the time of what happened in between (a step retried at half the size
    /// counts both attempts). [`StepInfo::times`] is one successful step's share.
    pub fn phase_times(&self) -> PhaseTimes {
        self.times
    }

    /// Uses `solver` for the linear solves from now on, in place of the kind named by
    /// [`BackwardEulerParams::linear`] (which is then ignored; see
    /// [`BackwardEuler::use_configured_linear_solver`] to go back).
    pub fn with_linear_solver(mut self, solver: Box<dyn LinearSolver>) -> Self {
        self.set_linear_solver(solver);
        self
    }

    /// Uses `solver` for the linear solves from now on (see
    /// [`BackwardEuler::with_linear_solver`]).
    pub fn set_linear_solver(&mut self, solver: Box<dyn LinearSolver>) {
        self.solver = solver;
        self.solver_settings = None;
    }

    /// Goes back to the solver [`BackwardEulerParams::linear`] names (built at the next step).
    pub fn use_configured_linear_solver(&mut self) {
        let settings = self.params.solver_settings();
        self.solver = settings.build();
        self.solver_settings = Some(settings);
    }

    /// The linear solver in use.
    pub fn linear_solver(&self) -> &dyn LinearSolver {
        self.solver.as_ref()
    }

    /// The sparse part of the Newton matrix of the last linear solve,
    /// `A = m_coef M + k_coef K_sparse` (Eq. 23, with `m_coef = 1 + dt alpha` plus any
    /// regularisation shift, `k_coef = dt^2 + dt beta`), as a `sprs` matrix; the dense low-rank
    /// terms of `K` ([`ForceSystem::low_rank_terms`]) are not included. `None` when the last
    /// solve was matrix-free (nothing was assembled) or before the first step.
    pub fn newton_matrix(&self) -> Option<CsMat<f64>> {
        if self.assembled_last {
            self.assembler.to_csmat().ok()
        } else {
            None
        }
    }

    /// Writes [`BackwardEuler::newton_matrix`] to `path` in Matrix Market format. Errors with
    /// [`SolveError::NotAssembled`] when there is none.
    pub fn write_newton_matrix(&self, path: impl AsRef<Path>) -> Result<(), SolveError> {
        let a = self.newton_matrix().ok_or(SolveError::NotAssembled)?;
        balloon_linalg::write_matrix_market(&a, path)
    }

    /// Rebuilds the configured solver if its settings changed (not for a user's solver).
    fn refresh_solver(&mut self) {
        if let Some(built) = self.solver_settings {
            let settings = self.params.solver_settings();
            if settings != built {
                self.solver = settings.build();
                self.solver_settings = Some(settings);
            }
        }
    }

    /// How many times the sparse pattern (and with it the symbolic Cholesky factorisation) has
    /// been built; stays at 1 across Newton iterations and steps while the pattern is unchanged.
    pub fn sparse_pattern_builds(&self) -> u64 {
        self.assembler.pattern_version()
    }

    /// Whether the last matrix-free CG solve used the stiffness diagonal
    /// ([`ForceSystem::add_stiffness_diagonal`]) in its Jacobi preconditioner.
    pub fn stiffness_preconditioned(&self) -> bool {
        self.last_preconditioner == Preconditioner::DiagonalJacobi
    }

    fn validate(
        &self,
        n: usize,
        dt: f64,
        x: &[f64],
        v: &[f64],
        masses: &[f64],
        ext: Option<&[f64]>,
    ) -> Result<(), IntegrateError> {
        let p = &self.params;
        check_time_step(dt)?;
        let param = |name, value: f64, ok: bool, allowed| {
            if ok {
                Ok(())
            } else {
                Err(IntegrateError::InvalidParameter {
                    name,
                    value,
                    allowed,
                })
            }
        };
        param(
            "mass_damping",
            p.mass_damping,
            p.mass_damping.is_finite() && p.mass_damping >= 0.0,
            "finite and non-negative (1/s)",
        )?;
        param(
            "inexact_forcing",
            p.inexact_forcing,
            p.inexact_forcing.is_finite() && (0.0..=1.0).contains(&p.inexact_forcing),
            "in [0, 1] (0: every linear solve to its own tolerance)",
        )?;
        param(
            "stiffness_damping",
            p.stiffness_damping,
            p.stiffness_damping.is_finite() && p.stiffness_damping >= 0.0,
            "finite and non-negative (s)",
        )?;
        param(
            "newton_tolerance",
            p.newton_tolerance,
            p.newton_tolerance.is_finite() && p.newton_tolerance >= 0.0,
            "finite and non-negative",
        )?;
        param(
            "newton_iterations",
            p.newton_iterations as f64,
            (1..=MAX_NEWTON_ITERATIONS).contains(&p.newton_iterations),
            "an integer from 1 to 1000",
        )?;
        if let Some(g) = p.gravity.iter().find(|g| !g.is_finite()) {
            param("gravity", *g, false, "finite in every component (m/s^2)")?;
        }
        let lengths = [("x", x.len()), ("v", v.len()), ("masses", masses.len())];
        let ext = ext.map(|e| ("external_forces", e.len()));
        if let Some((what, len)) = lengths.into_iter().chain(ext).find(|&(_, len)| len != n) {
            return Err(IntegrateError::LengthMismatch {
                what,
                len,
                expected: n,
            });
        }
        if let Some(dof) = masses.iter().position(|m| !(m.is_finite() && *m > 0.0)) {
            return Err(IntegrateError::InvalidMass {
                dof,
                vertex: dof / 3,
                mass: masses[dof],
            });
        }
        Ok(())
    }

    /// Advances `x` (m) and `v` (m/s) from `time` to `time + dt` (s) by backward Euler with
    /// Newton (Eq. 18-23). `external_forces` (N, per dof) are added to gravity.
    ///
    /// With `newton_tolerance > 0` Newton runs until the relative residual (see
    /// [`StepInfo::relative_residual`]) is at most the tolerance, at most `newton_iterations`
    /// times, each step cut back by the line search (see the module docs); a step that does not
    /// converge is [`IntegrateError::NotConverged`], never `Ok`. With `newton_tolerance = 0`
    /// (the paper's mode) exactly `newton_iterations` full Newton steps are taken and the step
    /// is accepted whatever its residual.
    ///
    /// On error `x` and `v` are left at the last Newton iterate (the caller should keep its own
    /// copy to roll back).
    pub fn step<S: ForceSystem>(
        &mut self,
        system: &mut S,
        time: f64,
        dt: f64,
        x: &mut [f64],
        v: &mut [f64],
        external_forces: Option<&[f64]>,
    ) -> Result<StepInfo, IntegrateError> {
        let n = system.num_dofs();
        self.validate(n, dt, x, v, system.masses(), external_forces)?;
        let p = self.params;
        system
            .set_tangent(p.tangent)
            .map_err(|source| IntegrateError::System {
                iteration: 0,
                source,
            })?;
        let (alpha, beta) = (p.mass_damping, p.stiffness_damping);
        let m_coef = 1.0 + dt * alpha;
        let k_coef = dt * dt + dt * beta;
        for buf in [
            &mut self.f,
            &mut self.f_ext,
            &mut self.b,
            &mut self.dv,
            &mut self.tmp,
            &mut self.kv,
            &mut self.v_trial,
        ] {
            buf.resize(n, 0.0);
        }
        self.x_n.clear();
        self.x_n.extend_from_slice(x);
        self.v_n.clear();
        self.v_n.extend_from_slice(v);
        {
            let m = system.masses();
            for i in 0..n {
                self.f_ext[i] = m[i] * p.gravity[i % 3] + external_forces.map_or(0.0, |e| e[i]);
            }
        }
        self.scale_floor = SCALE_FLOOR * norm(system.masses()) * extent(x) / (dt * dt);
        let t1 = time + dt;
        let paper_mode = p.newton_tolerance == 0.0;
        let mut info = StepInfo {
            converged: true,
            ..Default::default()
        };
        self.refresh_solver();
        let factorizations_before = self.solver.factorizations();
        let times_before = self.times;
        // Whether the first Newton iteration reuses the last step's matrix (a chord step).
        let reusable = self.reusable_matrix.take();
        // (At least two iterations allowed: a dropped chord step uses one up.)
        let mut chord = !paper_mode
            && p.newton_iterations >= 2
            && beta == 0.0
            && self.reused_steps < p.tangent_reuse_steps
            && self.solver.needs_assembled_matrix()
            && self.assembled_last
            && reusable == Some((m_coef, k_coef));
        let mut last_solve_reused = false;
        let mut chord_taken = false;
        let mut accepted_steps = 0;

        // The first iterate, v_(0) = v^n (its stiffness only when it is needed).
        let wants_energy = !paper_mode && beta == 0.0;
        let (mut res, mut energy) = if wants_energy && chord && self.fused_energy(system) {
            self.evaluate_with_energy(system, (t1, dt, 0), v, x)?
        } else {
            (self.evaluate(system, t1, dt, v, x, 0, !chord)?, None)
        };
        if wants_energy && energy.is_none() {
            energy = self.incremental_potential(system, t1, dt, v, x)?;
        }
        if let Some(e) = energy {
            info.energies.push(e);
        }
        info.newton_residuals.push(res.norm);
        info.relative_residuals.push(res.relative());
        let mut newton_converged = paper_mode;
        for k in 0..p.newton_iterations {
            // At least one Newton iteration: the first iterate is only the prediction
            // `v^n`, and stopping there would let a nearly balanced state creep.
            if !paper_mode && accepted_steps > 0 && res.relative() <= p.newton_tolerance {
                newton_converged = true;
                break;
            }
            if res.norm == 0.0 {
                newton_converged = true;
                break;
            }
            if !paper_mode {
                // Inexact Newton (`inexact_forcing`); the paper's mode keeps the configured
                // tolerance.
                self.solver.set_relative_tolerance(forcing_tolerance(
                    p.inexact_forcing,
                    p.newton_tolerance,
                    res.relative(),
                    p.linear.relative_tolerance,
                ));
            }
            let lin = if chord {
                match self.reused_direction(system, m_coef, k_coef) {
                    Ok(lin) => lin,
                    Err(_) => {
                        // The reused matrix does not give a direction: a fresh one from here
                        // (the stiffness at this iterate is still to be computed).
                        chord = false;
                        self.newton_direction(system, m_coef, k_coef, k, &mut info)?
                    }
                }
            } else {
                self.newton_direction(system, m_coef, k_coef, k, &mut info)?
            };
            last_solve_reused = chord;
            info.newton_iterations += 1;
            info.linear_iterations.push(lin.iterations);
            info.linear_residuals.push(lin.relative_residual);
            if paper_mode {
                info.converged &= lin.converged;
                for i in 0..n {
                    v[i] += self.dv[i];
                }
                if let Some(dof) = first_non_finite(v) {
                    return Err(IntegrateError::NonFinite {
                        quantity: "velocity",
                        dof,
                        vertex: dof / 3,
                        iteration: k,
                    });
                }
                if k + 1 < p.newton_iterations {
                    res = self.evaluate(system, t1, dt, v, x, k + 1, true)?;
                    info.newton_residuals.push(res.norm);
                    info.relative_residuals.push(res.relative());
                }
                continue;
            }
            // Line search along dv (module docs). `slope = b . dv` is minus the directional
            // derivative of the incremental potential along dv.
            let slope: f64 = self.b.iter().zip(&self.dv).map(|(b, d)| b * d).sum();
            let mode = if energy.is_some() && slope > 0.0 {
                LineSearch::Energy
            } else if beta != 0.0 || energy.is_some() {
                LineSearch::Residual
            } else {
                LineSearch::Off
            };
            let mut step_length = 1.0;
            let mut accepted = false;
            // A chord step is taken whole or not at all.
            let max_cuts = if chord { 0 } else { MAX_LINE_SEARCH_CUTS };
            for cut in 0..=max_cuts {
                if cut > 0 {
                    step_length *= 0.5;
                    info.line_search_cuts += 1;
                }
                let mut trial_v = std::mem::take(&mut self.v_trial);
                for i in 0..n {
                    trial_v[i] = v[i] + step_length * self.dv[i];
                }
                let outcome = self.try_step(
                    system,
                    mode,
                    (t1, dt, k + 1),
                    &trial_v,
                    x,
                    (energy, slope, step_length, &res),
                    !chord && cut == MAX_LINE_SEARCH_CUTS,
                );
                self.v_trial = trial_v;
                if let Some((e1, r)) = outcome? {
                    v.copy_from_slice(&self.v_trial);
                    res = r;
                    energy = match (e1, energy) {
                        (Some(e1), _) => Some(e1),
                        // A residual-searched step of a system with a potential: keep the
                        // energy current for the next iteration.
                        (None, Some(_)) => self.incremental_potential(system, t1, dt, v, x)?,
                        (None, None) => None,
                    };
                    if let Some(e) = energy {
                        info.energies.push(e);
                    }
                    accepted = true;
                    break;
                }
            }
            if !accepted && chord {
                // The line search would cut the chord step: go on from the same iterate with
                // its own tangent (the next iteration), as if the matrix had not been reused.
                chord = false;
                last_solve_reused = false;
                res = self.evaluate(system, t1, dt, v, x, k, true)?;
                continue;
            }
            chord_taken |= chord;
            chord = false;
            accepted_steps += accepted as usize;
            if !accepted {
                return Err(IntegrateError::NotConverged {
                    iterations: info.newton_iterations,
                    residual: res.relative(),
                    tolerance: p.newton_tolerance,
                });
            }
            info.newton_residuals.push(res.norm);
            info.relative_residuals.push(res.relative());
            let r = &info.relative_residuals;
            if r.len() > NEWTON_STALL_WINDOW
                && res.relative() > p.newton_tolerance
                && res.relative() > 0.5 * r[r.len() - 1 - NEWTON_STALL_WINDOW]
            {
                return Err(IntegrateError::NotConverged {
                    iterations: info.newton_iterations,
                    residual: res.relative(),
                    tolerance: p.newton_tolerance,
                });
            }
        }
        // The paper's mode does not evaluate its result (see `StepInfo::relative_residual`).
        if !paper_mode && !newton_converged && res.relative() <= p.newton_tolerance {
            newton_converged = true;
        }
        for i in 0..n {
            x[i] = self.x_n[i] + dt * v[i];
        }
        if let Some(dof) = first_non_finite(x) {
            return Err(IntegrateError::NonFinite {
                quantity: "position",
                dof,
                vertex: dof / 3,
                iteration: info.newton_iterations,
            });
        }
        info.relative_residual = res.relative();
        info.factorizations = (self.solver.factorizations() - factorizations_before) as usize;
        if !newton_converged {
            return Err(IntegrateError::NotConverged {
                iterations: info.newton_iterations,
                residual: info.relative_residual,
                tolerance: p.newton_tolerance,
            });
        }
        if !paper_mode {
            info.converged = true;
        }
        info.times = self.times - times_before;
        info.reused_tangent = chord_taken;
        // The matrix of the last solve may serve the next step's first iteration.
        self.reused_steps = if last_solve_reused {
            self.reused_steps + 1
        } else {
            0
        };
        // Only after a step that one Newton iteration settled: where steps need more, a chord
        // step would add iterations rather than save linearisations.
        if self.assembled_last && self.last_shift == 0.0 && info.newton_iterations == 1 {
            self.reusable_matrix = Some((m_coef, k_coef));
        }
        Ok(info)
    }

    /// One trial of the line search at `v = trial_v` (`ctx = (t1, dt, iteration)`;
    /// `current = (energy, slope b . dv, step length, residual)` of the current
    /// iterate). Returns the accepted iterate's incremental potential (energy search) and
    /// residual, `None` to cut the step, or an error that ends the step. On acceptance the
    /// system's last force evaluation is at the trial point.
    #[allow(clippy::too_many_arguments)]
    fn try_step<S: ForceSystem>(
        &mut self,
        system: &mut S,
        mode: LineSearch,
        (t1, dt, iteration): (f64, f64, usize),
        trial_v: &[f64],
        x: &mut [f64],
        (energy, slope, step_length, current): (Option<f64>, f64, f64, &Residual),
        last_cut: bool,
    ) -> Result<Option<(Option<f64>, Residual)>, IntegrateError> {
        if first_non_finite(trial_v).is_some() {
            return Ok(None);
        }
        match (mode, energy) {
            (LineSearch::Energy, Some(e0)) => {
                // An undefined energy (inverted element, non-positive volume) counts as
                // infinite: cut. With a fused evaluation the trial's forces come with its
                // energy, and a failure of either is a cut.
                let (e1, fused) = if self.fused_energy(system) {
                    match self.evaluate_with_energy(system, (t1, dt, iteration), trial_v, x) {
                        Ok((r, Some(e))) if e.is_finite() => (e, Some(r)),
                        _ => return Ok(None),
                    }
                } else {
                    match self.incremental_potential(system, t1, dt, trial_v, x) {
                        Ok(Some(e)) if e.is_finite() => (e, None),
                        _ => return Ok(None),
                    }
                };
                let armijo = e1 <= e0 - ARMIJO * step_length * slope;
                // Within round-off of the energy (close to convergence the decrease is below
                // what f64 resolves in E): accept if the residual falls instead.
                let roundoff = !armijo && e1 <= e0 + ENERGY_ROUNDOFF * self.energy_magnitude;
                if !(armijo || roundoff) {
                    return Ok(None);
                }
                let r = match fused {
                    Some(r) => Ok(r),
                    None => self.evaluate(system, t1, dt, trial_v, x, iteration, false),
                };
                if armijo {
                    return r.map(|r| Some((Some(e1), r)));
                }
                Ok(match r {
                    Ok(r) if r.norm < current.norm => Some((Some(e1), r)),
                    _ => None,
                })
            }
            (LineSearch::Off, _) => self
                .evaluate(system, t1, dt, trial_v, x, iteration, false)
                .map(|r| Some((None, r))),
            _ => Ok(
                match self.evaluate(system, t1, dt, trial_v, x, iteration, false) {
                    Ok(r) if r.norm <= (1.0 - ARMIJO * step_length) * current.norm => {
                        Some((None, r))
                    }
                    // The residual search found no decrease: take the shortest step and let the
                    // iteration limit decide.
                    Ok(r) if last_cut => Some((None, r)),
                    _ => None,
                },
            ),
        }
    }

    /// Evaluates the forces at `x = x^n + dt v` (written to `x`) and the Newton right-hand side
    /// `b` (Eq. 23) into `self.b`, with its norm and the force scale of the relative residual.
    /// With `linearize` false (a line-search trial, which Newton may stop at) the system may
    /// leave its stiffness for [`ForceSystem::refresh_stiffness`], which
    /// [`BackwardEuler::newton_direction`] calls before it needs it; stiffness damping needs
    /// `K v` here, so it always linearises.
    #[allow(clippy::too_many_arguments)]
    fn evaluate<S: ForceSystem>(
        &mut self,
        system: &mut S,
        t1: f64,
        dt: f64,
        v: &[f64],
        x: &mut [f64],
        iteration: usize,
        linearize: bool,
    ) -> Result<Residual, IntegrateError> {
        self.evaluate_full(system, (t1, dt, iteration), v, x, linearize, false)
            .map(|(r, _)| r)
    }

    /// [`BackwardEuler::evaluate`] without the linearisation, and the incremental potential at
    /// the same point from the same pass over the system
    /// ([`ForceSystem::residual_forces_and_energy`]; `None` without a potential). For a system
    /// that fuses the two ([`ForceSystem::fuses_forces_and_energy`]) and no stiffness damping.
    fn evaluate_with_energy<S: ForceSystem>(
        &mut self,
        system: &mut S,
        ctx: (f64, f64, usize),
        v: &[f64],
        x: &mut [f64],
    ) -> Result<(Residual, Option<f64>), IntegrateError> {
        self.evaluate_full(system, ctx, v, x, false, true)
    }

    /// Whether this step's line search evaluates a trial's energy and forces together.
    fn fused_energy<S: ForceSystem>(&self, system: &S) -> bool {
        self.params.stiffness_damping == 0.0 && system.fuses_forces_and_energy()
    }

    /// The body of [`BackwardEuler::evaluate`] and [`BackwardEuler::evaluate_with_energy`]
    /// (`ctx = (t1, dt, iteration)`; the energy only with `with_energy`, which needs
    /// `linearize` false and no stiffness damping).
    fn evaluate_full<S: ForceSystem>(
        &mut self,
        system: &mut S,
        (t1, dt, iteration): (f64, f64, usize),
        v: &[f64],
        x: &mut [f64],
        linearize: bool,
        with_energy: bool,
    ) -> Result<(Residual, Option<f64>), IntegrateError> {
        let n = v.len();
        let (alpha, beta) = (self.params.mass_damping, self.params.stiffness_damping);
        for i in 0..n {
            x[i] = self.x_n[i] + dt * v[i];
        }
        if let Some(dof) = first_non_finite(x) {
            return Err(IntegrateError::NonFinite {
                quantity: "position",
                dof,
                vertex: dof / 3,
                iteration,
            });
        }
        let started = Instant::now();
        let mut potential = None;
        let evaluated = if with_energy && !linearize && beta == 0.0 {
            system
                .residual_forces_and_energy(t1, x, &mut self.f)
                .map(|w| potential = w)
        } else if linearize || beta != 0.0 {
            system.forces(t1, x, &mut self.f)
        } else {
            system.residual_forces(t1, x, &mut self.f)
        };
        self.times.forces_ms += ms_since(started);
        evaluated.map_err(|source| IntegrateError::System { iteration, source })?;
        if let Some(dof) = first_non_finite(&self.f) {
            return Err(IntegrateError::NonFinite {
                quantity: "force",
                dof,
                vertex: dof / 3,
                iteration,
            });
        }
        // K v_(k) for stiffness damping.
        self.kv.fill(0.0);
        if beta != 0.0 {
            let started = Instant::now();
            self.tmp.fill(0.0);
            system.add_force_differential(v, &mut self.tmp);
            self.times.forces_ms += ms_since(started);
            for i in 0..n {
                self.kv[i] = -self.tmp[i];
            }
        }
        let m = system.masses();
        let (mut b2, mut inertia2, mut f2, mut ext2, mut damp2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for i in 0..n {
            let cv = alpha * m[i] * v[i] + beta * self.kv[i];
            let inertia = m[i] * (self.v_n[i] - v[i]);
            self.b[i] = inertia + dt * (self.f[i] + self.f_ext[i] - cv);
            b2 += self.b[i] * self.b[i];
            inertia2 += inertia * inertia;
            f2 += self.f[i] * self.f[i];
            ext2 += self.f_ext[i] * self.f_ext[i];
            damp2 += cv * cv;
        }
        let internal = system.force_scale().unwrap_or(f2.sqrt());
        let terms = inertia2.sqrt() / dt + internal + ext2.sqrt() + damp2.sqrt();
        let residual = Residual {
            norm: b2.sqrt(),
            scale: terms.max(self.scale_floor),
            dt,
        };
        let energy = potential.map(|w| self.incremental_from_potential(system.masses(), w, dt, v));
        Ok((residual, energy))
    }

    /// The incremental potential of the step at `x = x^n + dt v` (written to `x`), in the
    /// velocity form `m_coef/2 |v - v^n/m_coef|_M^2 + W(x) - dt f_ext . v` (the module docs'
    /// `E(x)` up to a constant), or `None` when the system has no potential. An error of the
    /// system (an undefined energy) is returned as such.
    fn incremental_potential<S: ForceSystem>(
        &mut self,
        system: &mut S,
        t1: f64,
        dt: f64,
        v: &[f64],
        x: &mut [f64],
    ) -> Result<Option<f64>, IntegrateError> {
        let n = v.len();
        for i in 0..n {
            x[i] = self.x_n[i] + dt * v[i];
        }
        let started = Instant::now();
        let w = system.potential_energy(t1, x);
        self.times.energy_ms += ms_since(started);
        let w = w.map_err(|source| IntegrateError::System {
            iteration: 0,
            source,
        })?;
        let Some(w) = w else {
            return Ok(None);
        };
        Ok(Some(self.incremental_from_potential(
            system.masses(),
            w,
            dt,
            v,
        )))
    }

    /// The incremental potential at velocity `v` given the system's potential energy `w` there
    /// (the kinetic and external terms of [`BackwardEuler::incremental_potential`]); records
    /// the energy's magnitude for the round-off test of the line search.
    fn incremental_from_potential(&mut self, m: &[f64], w: f64, dt: f64, v: &[f64]) -> f64 {
        let m_coef = 1.0 + dt * self.params.mass_damping;
        let (mut kinetic, mut external) = (0.0, 0.0);
        for i in 0..v.len() {
            let d = v[i] - self.v_n[i] / m_coef;
            kinetic += m[i] * d * d;
            external += self.f_ext[i] * v[i];
        }
        let kinetic = 0.5 * m_coef * kinetic;
        let external = dt * external;
        self.energy_magnitude = kinetic + w.abs() + external.abs();
        kinetic + w - external
    }

    /// Solves for the Newton direction `dv` (into `self.dv`) at the current iterate, assembling
    /// `K` first when the solver needs it and retrying an indefinite matrix with a mass shift.
    fn newton_direction<S: ForceSystem>(
        &mut self,
        system: &mut S,
        m_coef: f64,
        k_coef: f64,
        k: usize,
        info: &mut StepInfo,
    ) -> Result<SolveInfo, IntegrateError> {
        let started = Instant::now();
        let refreshed = system.refresh_stiffness();
        self.times.forces_ms += ms_since(started);
        refreshed.map_err(|source| IntegrateError::System {
            iteration: k,
            source,
        })?;
        if self.solver.needs_assembled_matrix() {
            let started = Instant::now();
            let collected = crate::system::collect_stiffness(&*system, &mut self.triplets);
            self.times.assembly_ms += ms_since(started);
            self.use_blocks = collected.map_err(|source| IntegrateError::System {
                iteration: k,
                source,
            })?;
        }
        // Levenberg-Marquardt memory: after a regularised iteration the next one starts from
        // a fraction of that shift instead of climbing the ladder from 0 again (each rung is
        // an assembly and a failed factorisation or CG run); it decays to 0 as the iterate
        // leaves the non-convex region. The first iteration of a step starts unshifted.
        let mut shift = if k > 0 {
            start_shift(self.last_shift, m_coef)
        } else {
            0.0
        };
        let mut retries = 0;
        loop {
            match self.solve(system, m_coef + shift, k_coef, false) {
                Ok(lin) => {
                    self.last_shift = shift;
                    info.max_regularization = info.max_regularization.max(shift);
                    return Ok(lin);
                }
                Err(err)
                    if err.is_indefinite()
                        && self.params.regularize_indefinite
                        && retries < MAX_REGULARIZATION_RETRIES =>
                {
                    shift = next_shift(shift, m_coef, &err, system.masses());
                    retries += 1;
                    info.regularized_solves += 1;
                    info.max_regularization = info.max_regularization.max(shift);
                }
                Err(source) => {
                    return Err(IntegrateError::Linear {
                        iteration: k,
                        source,
                    });
                }
            }
        }
    }
    /// Solves for the direction `dv` of a chord step: with the matrix still in the assembler
    /// (the last step's, `(m_coef, k_coef)` checked by the caller) and the low-rank terms kept
    /// with it, without the stiffness at the current iterate.
    fn reused_direction<S: ForceSystem>(
        &mut self,
        system: &S,
        m_coef: f64,
        k_coef: f64,
    ) -> Result<SolveInfo, SolveError> {
        let solved = self.solve(system, m_coef, k_coef, true);
        if solved.is_ok() {
            self.last_shift = 0.0;
        }
        solved
    }

    /// Solves `(m_coef M + k_coef K) dv = b` with the linear solver, assembling `A` first when
    /// the solver needs it (the triplets of `K` are already in `self.triplets` then), or with
    /// the matrix already in the assembler when `reuse` is set (a chord step).
    fn solve<S: ForceSystem>(
        &mut self,
        system: &S,
        m_coef: f64,
        k_coef: f64,
        reuse: bool,
    ) -> Result<SolveInfo, SolveError> {
        let masses = system.masses();
        self.dv.fill(0.0);
        let factor_before = self.solver.factorization_seconds();
        let started = Instant::now();
        let result = if self.solver.needs_assembled_matrix() {
            if !reuse {
                let blocks = if self.use_blocks {
                    system.stiffness_blocks()
                } else {
                    None
                };
                self.assembled_last = false;
                match blocks {
                    Some(b) => self.assembler.assemble_blocks(
                        masses,
                        m_coef,
                        &b,
                        &self.triplets,
                        k_coef,
                    )?,
                    None => self
                        .assembler
                        .assemble(masses, m_coef, &self.triplets, k_coef)?,
                };
                self.assembled_last = true;
                keep_low_rank(&mut self.kept_low_rank, system.low_rank_terms());
                self.times.assembly_ms += ms_since(started);
            }
            let started = Instant::now();
            // A chord step solves with the whole earlier tangent: its low-rank terms too (the
            // system's may wait for `refresh_stiffness` after `residual_forces`).
            let low_rank = if reuse {
                self.kept_low_rank.as_slice()
            } else {
                system.low_rank_terms()
            };
            let problem = LinearProblem::assembled(
                self.assembler.matrix(),
                self.assembler.pattern_version(),
                m_coef,
                k_coef,
                low_rank,
            );
            let solved = self.solver.solve(&problem, &self.b, &mut self.dv);
            (solved, ms_since(started))
        } else {
            self.assembled_last = false;
            let stiffness = SystemStiffness(system);
            let low_rank = system.low_rank_terms();
            let problem = LinearProblem::matrix_free(m_coef, k_coef, masses, &stiffness, low_rank);
            let solved = self.solver.solve(&problem, &self.b, &mut self.dv);
            (solved, ms_since(started))
        };
        let factor_ms = (self.solver.factorization_seconds() - factor_before) * 1e3;
        self.times.factorization_ms += factor_ms;
        self.times.solve_ms += (result.1 - factor_ms).max(0.0);
        let result = result.0;
        if let Ok(info) = &result {
            self.last_preconditioner = info.preconditioner;
        }
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linear::LinearSolverKind;
    use crate::system::LowRankTerm;
    use balloon_test_support::{Rng, check_jacobian};
    use nalgebra::{DMatrix, DVector};

    /// Chain of 3D springs (nonlinear, with rest lengths) plus a nonlinear rank-1 potential
    /// `phi(u . x) = s^4 / 4` (its Hessian `3 s^2 u u^T` plays the role of the gas term), plus
    /// an optional linear quadratic part `1/2 x^T K0 x`.
    #[derive(Debug, Clone)]
    struct Chain {
        masses: Vec<f64>,
        springs: Vec<(usize, usize, f64, f64)>,
        u: Vec<f64>,
        x: Vec<f64>,
        low_rank: Vec<LowRankTerm>,
        nonlinear: bool,
        /// Linear part (dense, small) for the linear tests.
        k0: Option<DMatrix<f64>>,
        poison: bool,
        offers_diagonal: bool,
    }

    impl Chain {
        fn new(nv: usize, nonlinear: bool, seed: u64) -> Self {
            let mut rng = Rng::new(seed);
            let n = 3 * nv;
            let masses = (0..n).map(|i| 0.1 + 0.01 * (i / 3) as f64).collect();
            let mut springs = Vec::new();
            for i in 0..nv - 1 {
                springs.push((i, i + 1, 50.0 + 10.0 * rng.next_f64(), 0.1));
                if i + 2 < nv {
                    springs.push((i, i + 2, 20.0, 0.2));
                }
            }
            let u = rng.vector(n).iter().map(|v| 0.3 * v).collect();
            Self {
                masses,
                springs,
                u,
                x: vec![0.0; n],
                low_rank: vec![],
                nonlinear,
                k0: None,
                poison: false,
                offers_diagonal: false,
            }
        }

        fn positions(nv: usize, seed: u64) -> Vec<f64> {
            let mut rng = Rng::new(seed);
            (0..3 * nv)
                .map(|i| if i % 3 == 0 { 0.1 * (i / 3) as f64 } else { 0.0 } + 0.02 * rng.next_f64())
                .collect()
        }

        fn s(&self, x: &[f64]) -> f64 {
            self.u.iter().zip(x).map(|(a, b)| a * b).sum()
        }

        fn energy(&self, x: &[f64]) -> f64 {
            let mut e = 0.0;
            if self.nonlinear {
                for &(i, j, k, l0) in &self.springs {
                    let d: f64 = (0..3)
                        .map(|c| (x[3 * i + c] - x[3 * j + c]).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    e += 0.5 * k * (d - l0).powi(2);
                }
                e += self.s(x).powi(4) / 4.0;
            }
            if let Some(k0) = &self.k0 {
                let xv = DVector::from_column_slice(x);
                e += 0.5 * xv.dot(&(k0 * &xv));
            }
            e
        }

        fn spring_block(
            &self,
            x: &[f64],
            i: usize,
            j: usize,
            k: f64,
            l0: f64,
        ) -> nalgebra::Matrix3<f64> {
            let d = nalgebra::Vector3::from_fn(|c, _| x[3 * i + c] - x[3 * j + c]);
            let l = d.norm();
            let nn = d * d.transpose() / (l * l);
            (nn + (nalgebra::Matrix3::identity() - nn) * (1.0 - l0 / l)) * k
        }
    }

    impl ForceSystem for Chain {
        fn num_dofs(&self) -> usize {
            self.masses.len()
        }
        fn masses(&self) -> &[f64] {
            &self.masses
        }
        fn forces(&mut self, _time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
            self.x.copy_from_slice(x);
            f.fill(0.0);
            self.low_rank.clear();
            if self.nonlinear {
                for &(i, j, k, l0) in &self.springs {
                    let d = nalgebra::Vector3::from_fn(|c, _| x[3 * i + c] - x[3 * j + c]);
                    let l = d.norm();
                    let fi = -k * (l - l0) * d / l;
                    for c in 0..3 {
                        f[3 * i + c] += fi[c];
                        f[3 * j + c] -= fi[c];
                    }
                }
                let s = self.s(x);
                for (fi, ui) in f.iter_mut().zip(&self.u) {
                    *fi -= s.powi(3) * ui;
                }
                self.low_rank.push(LowRankTerm {
                    coefficient: 3.0 * s * s,
                    vector: self.u.clone(),
                });
            }
            if let Some(k0) = &self.k0 {
                let kx = k0 * DVector::from_column_slice(x);
                for i in 0..f.len() {
                    f[i] -= kx[i];
                }
            }
            if self.poison {
                f[7] = f64::NAN;
            }
            Ok(())
        }
        fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
            let mut t = Vec::new();
            self.add_stiffness_triplets(&mut t).unwrap();
            for (r, c, v) in t {
                df[r] -= v * dx[c];
            }
            for lr in &self.low_rank {
                let s: f64 = lr.vector.iter().zip(dx).map(|(a, b)| a * b).sum();
                for i in 0..df.len() {
                    df[i] -= lr.coefficient * s * lr.vector[i];
                }
            }
        }
        fn add_stiffness_triplets(
            &self,
            t: &mut Vec<(usize, usize, f64)>,
        ) -> Result<(), SystemError> {
            if self.nonlinear {
                for &(i, j, k, l0) in &self.springs {
                    let b = self.spring_block(&self.x, i, j, k, l0);
                    for r in 0..3 {
                        for c in 0..3 {
                            t.push((3 * i + r, 3 * i + c, b[(r, c)]));
                            t.push((3 * j + r, 3 * j + c, b[(r, c)]));
                            t.push((3 * i + r, 3 * j + c, -b[(r, c)]));
                            t.push((3 * j + r, 3 * i + c, -b[(r, c)]));
                        }
                    }
                }
            }
            if let Some(k0) = &self.k0 {
                for r in 0..k0.nrows() {
                    for c in 0..k0.ncols() {
                        if k0[(r, c)] != 0.0 {
                            t.push((r, c, k0[(r, c)]));
                        }
                    }
                }
            }
            Ok(())
        }
        fn low_rank_terms(&self) -> &[LowRankTerm] {
            &self.low_rank
        }
        fn potential_energy(&mut self, _t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
            Ok(Some(self.energy(x)))
        }
        fn add_stiffness_diagonal(&self, diagonal: &mut [f64]) -> Result<(), SystemError> {
            if !self.offers_diagonal {
                return Err(SystemError::AssemblyUnsupported);
            }
            let mut t = Vec::new();
            self.add_stiffness_triplets(&mut t)?;
            for (r, c, v) in t {
                if r == c {
                    diagonal[r] += v;
                }
            }
            Ok(())
        }
    }

    /// Free particles: no forces at all (`.1`: whether it can assemble its (zero) stiffness).
    #[derive(Debug)]
    struct Free(Vec<f64>, bool);
    impl ForceSystem for Free {
        fn num_dofs(&self) -> usize {
            self.0.len()
        }
        fn masses(&self) -> &[f64] {
            &self.0
        }
        fn forces(&mut self, _t: f64, _x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
            f.fill(0.0);
            Ok(())
        }
        fn add_force_differential(&self, _dx: &[f64], _df: &mut [f64]) {}
        fn add_stiffness_triplets(
            &self,
            _t: &mut Vec<(usize, usize, f64)>,
        ) -> Result<(), SystemError> {
            if self.1 {
                Ok(())
            } else {
                Err(SystemError::AssemblyUnsupported)
            }
        }
    }

    fn linear_chain(nv: usize) -> Chain {
        let mut c = Chain::new(nv, false, 1);
        let n = 3 * nv;
        let mut k0 = DMatrix::zeros(n, n);
        for i in 0..n {
            k0[(i, i)] = 200.0;
            if i + 3 < n {
                k0[(i, i + 3)] = -80.0;
                k0[(i + 3, i)] = -80.0;
            }
        }
        c.k0 = Some(k0);
        c
    }

    fn params(kind: LinearSolverKind, iters: usize) -> BackwardEulerParams {
        BackwardEulerParams {
            newton_iterations: iters,
            newton_tolerance: 0.0,
            linear: LinearSolverParams {
                kind,
                max_iterations: 1000,
                relative_tolerance: 1e-12,
            },
            ..Default::default()
        }
    }

    #[test]
    fn bad_inputs_are_typed_errors_naming_the_parameter_and_value() {
        let mut sys = Free(vec![1.0; 6], true);
        let (mut x, mut v) = (vec![0.0; 6], vec![0.0; 6]);
        let mut be = BackwardEuler::new(params(LinearSolverKind::Cholesky, 1));
        for dt in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
            let err = be
                .step(&mut sys, 0.0, dt, &mut x, &mut v, None)
                .unwrap_err();
            assert!(
                matches!(err, IntegrateError::InvalidParameter { name: "dt", value, .. }
                    if value.to_bits() == dt.to_bits()),
                "{err}"
            );
        }
        be.params.mass_damping = -2.0;
        let err = be
            .step(&mut sys, 0.0, 1e-3, &mut x, &mut v, None)
            .unwrap_err();
        assert!(
            matches!(err, IntegrateError::InvalidParameter { name: "mass_damping", value, .. } if value == -2.0),
            "{err}"
        );
        be.params.mass_damping = 0.0;
        for bad in [-0.1, 1.5, f64::NAN] {
            be.params.inexact_forcing = bad;
            let err = be
                .step(&mut sys, 0.0, 1e-3, &mut x, &mut v, None)
                .unwrap_err();
            assert!(
                matches!(
                    err,
                    IntegrateError::InvalidParameter {
                        name: "inexact_forcing",
                        ..
                    }
                ),
                "{err}"
            );
        }
        be.params.inexact_forcing = DEFAULT_INEXACT_FORCING;
        be.params.mass_damping = 0.0;
        let mut short = vec![0.0; 5];
        let err = be
            .step(&mut sys, 0.0, 1e-3, &mut x, &mut short, None)
            .unwrap_err();
        assert_eq!(
            err,
            IntegrateError::LengthMismatch {
                what: "v",
                len: 5,
                expected: 6
            }
        );
        sys.0[4] = 0.0;
        let err = be
            .step(&mut sys, 0.0, 1e-3, &mut x, &mut v, None)
            .unwrap_err();
        assert_eq!(
            err,
            IntegrateError::InvalidMass {
                dof: 4,
                vertex: 1,
                mass: 0.0
            }
        );
        assert!(err.to_string().contains("dof 4 (vertex 1)"), "{err}");
    }

    #[test]
    fn forcing_tolerance_asks_for_a_tenth_of_the_target_within_bounds() {
        // Residual 1e-3, target 1e-6: a linearised residual of 1e-7, i.e. 1e-4 relative.
        assert!((forcing_tolerance(0.1, 1e-6, 1e-3, 1e-8) - 1e-4).abs() < 1e-18);
        // Near the target the solve may stop at 0.1, never looser.
        assert!((forcing_tolerance(0.1, 1e-6, 2e-6, 1e-8) - 0.05).abs() < 1e-15);
        assert_eq!(forcing_tolerance(0.1, 1e-6, 5e-7, 1e-8), 0.1);
        // Far from it, or with forcing 0, the solver's own tolerance.
        assert_eq!(forcing_tolerance(0.1, 1e-6, 1e3, 1e-8), 1e-8);
        assert_eq!(forcing_tolerance(0.0, 1e-6, 1e-3, 1e-8), 1e-8);
        // A zero residual (nothing to solve) gives the floor, not a NaN.
        assert_eq!(forcing_tolerance(0.1, 1e-6, 0.0, 1e-8), 1e-8);
        // A configured tolerance looser than 0.1 is capped.
        assert_eq!(forcing_tolerance(0.1, 1e-6, 1e-3, 0.5), 0.1);
    }

    #[test]
    fn test_system_differential_and_stiffness_match_finite_differences() {
        let nv = 6;
        let sys = Chain::new(nv, true, 3);
        let x = Chain::positions(nv, 4);
        let f = |x: &[f64]| {
            let mut s = sys.clone();
            let mut f = vec![0.0; x.len()];
            s.forces(0.0, x, &mut f).unwrap();
            f
        };
        check_jacobian(
            f,
            |x, dx| {
                let mut s = sys.clone();
                let mut tmp = vec![0.0; x.len()];
                s.forces(0.0, x, &mut tmp).unwrap();
                let mut df = vec![0.0; x.len()];
                s.add_force_differential(dx, &mut df);
                df
            },
            &x,
            1e-6,
            1e-6,
            5,
        );
        balloon_test_support::check_gradient(
            |x| sys.energy(x),
            |x| {
                let mut s = sys.clone();
                let mut f = vec![0.0; x.len()];
                s.forces(0.0, x, &mut f).unwrap();
                f.iter().map(|v| -v).collect()
            },
            &x,
            1e-6,
            1e-6,
        );
    }

    #[test]
    fn all_solvers_and_preconditioners_agree_on_a_nonlinear_step() {
        let nv = 8;
        let x0 = Chain::positions(nv, 8);
        let v0: Vec<f64> = Rng::new(9).vector(3 * nv);
        let mut results = Vec::new();
        for (kind, pre) in [
            (LinearSolverKind::MatrixFreeCg, PcgPreconditioner::Jacobi),
            (LinearSolverKind::Pcg, PcgPreconditioner::Jacobi),
            (LinearSolverKind::Pcg, PcgPreconditioner::IncompleteCholesky),
            (LinearSolverKind::Cholesky, PcgPreconditioner::Jacobi),
            (LinearSolverKind::FactorizedPcg, PcgPreconditioner::Jacobi),
        ] {
            let mut sys = Chain::new(nv, true, 3);
            let mut be = BackwardEuler::new(BackwardEulerParams {
                mass_damping: 0.5,
                stiffness_damping: 0.001,
                gravity: [0.0, -9.81, 0.0],
                pcg_preconditioner: pre,
                ..params(kind, 4)
            });
            let (mut x, mut v) = (x0.clone(), v0.clone());
            for s in 0..3 {
                let info = be
                    .step(&mut sys, 0.01 * s as f64, 0.01, &mut x, &mut v, None)
                    .unwrap();
                assert_eq!(info.newton_iterations, 4);
                assert!(info.converged, "{kind}: {info:?}");
                // Newton converges quadratically: the residual drops by orders of magnitude.
                let r = &info.newton_residuals;
                assert!(r[3] < 1e-6 * r[0], "{kind}: {r:?}");
            }
            if kind != LinearSolverKind::MatrixFreeCg {
                // 3 steps x 4 Newton iterations, one pattern (and symbolic factorisation) build.
                assert_eq!(be.sparse_pattern_builds(), 1);
            }
            results.push((x, v));
        }
        for (x, v) in &results[1..] {
            for i in 0..x.len() {
                assert!((x[i] - results[0].0[i]).abs() < 1e-9, "x[{i}]");
                assert!((v[i] - results[0].1[i]).abs() < 1e-7, "v[{i}]");
            }
        }
    }

    #[test]
    fn one_newton_iteration_is_exact_on_a_linear_system() {
        let nv = 5;
        let n = 3 * nv;
        let (dt, alpha, beta) = (0.02, 0.3, 0.004);
        let x0 = Chain::positions(nv, 2);
        let v0 = Rng::new(3).vector(n);
        let ext = Rng::new(4).vector(n);
        for kind in [
            LinearSolverKind::MatrixFreeCg,
            LinearSolverKind::Pcg,
            LinearSolverKind::Cholesky,
            LinearSolverKind::FactorizedPcg,
        ] {
            let mut sys = linear_chain(nv);
            let k0 = sys.k0.clone().unwrap();
            let m = DMatrix::from_diagonal(&DVector::from_column_slice(&sys.masses));
            let mut be = BackwardEuler::new(BackwardEulerParams {
                mass_damping: alpha,
                stiffness_damping: beta,
                ..params(kind, 1)
            });
            let (mut x, mut v) = (x0.clone(), v0.clone());
            be.step(&mut sys, 0.0, dt, &mut x, &mut v, Some(&ext))
                .unwrap();
            // (M + dt C + dt^2 K) v1 = M v0 + dt (-K x0 + f_ext), C = alpha M + beta K.
            let a = &m + (&m * alpha + &k0 * beta) * dt + &k0 * (dt * dt);
            let rhs = &m * DVector::from_column_slice(&v0)
                + (-(&k0 * DVector::from_column_slice(&x0)) + DVector::from_column_slice(&ext))
                    * dt;
            let v1 = a.lu().solve(&rhs).unwrap();
            for i in 0..n {
                assert!(
                    (v[i] - v1[i]).abs() < 1e-9 * (1.0 + v1[i].abs()),
                    "{kind} v[{i}]"
                );
                assert!((x[i] - (x0[i] + dt * v1[i])).abs() < 1e-11, "{kind} x[{i}]");
            }
            // A second iteration finds nothing left to correct.
            let mut sys = linear_chain(nv);
            let mut be = BackwardEuler::new(params(kind, 2));
            let (mut x, mut v) = (x0.clone(), v0.clone());
            let info = be.step(&mut sys, 0.0, dt, &mut x, &mut v, None).unwrap();
            assert!(
                info.newton_residuals[1] < 1e-9 * info.newton_residuals[0],
                "{info:?}"
            );
        }
    }

    #[test]
    fn newton_matrix_round_trips_through_matrix_market_and_equals_the_dense_assembly() {
        let nv = 5;
        let n = 3 * nv;
        let (dt, alpha, beta) = (0.02, 0.3, 0.004);
        let x0 = Chain::positions(nv, 2);
        let mut sys = linear_chain(nv);
        let k0 = sys.k0.clone().unwrap();
        let mut be = BackwardEuler::new(BackwardEulerParams {
            mass_damping: alpha,
            stiffness_damping: beta,
            ..params(LinearSolverKind::Cholesky, 1)
        });
        assert!(be.newton_matrix().is_none());
        let (mut x, mut v) = (x0.clone(), Rng::new(3).vector(n));
        be.step(&mut sys, 0.0, dt, &mut x, &mut v, None).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("newton.mtx");
        be.write_newton_matrix(&path).unwrap();
        let read = crate::linear::read_matrix_market(&path).unwrap();
        assert_eq!(read, be.newton_matrix().unwrap());
        // A = (1 + dt alpha) M + (dt^2 + dt beta) K (Eq. 23).
        let m = DMatrix::from_diagonal(&DVector::from_column_slice(&sys.masses));
        let expected = &m * (1.0 + dt * alpha) + &k0 * (dt * dt + dt * beta);
        let mut dense = DMatrix::<f64>::zeros(n, n);
        for (value, (r, c)) in read.iter() {
            dense[(r, c)] += *value;
        }
        for r in 0..n {
            for c in 0..n {
                approx::assert_relative_eq!(
                    dense[(r, c)],
                    expected[(r, c)],
                    epsilon = 1e-12,
                    max_relative = 1e-12
                );
            }
        }
        // The matrix-free solver assembles nothing: no Newton matrix, a typed error.
        let mut be = BackwardEuler::new(params(LinearSolverKind::MatrixFreeCg, 1));
        be.step(&mut sys, 0.0, dt, &mut x0.clone(), &mut vec![0.0; n], None)
            .unwrap();
        assert!(be.newton_matrix().is_none());
        assert_eq!(
            be.write_newton_matrix(&path).unwrap_err(),
            crate::linear::SolveError::NotAssembled
        );
    }

    #[test]
    fn stiffness_diagonal_preconditioner_cuts_cg_iterations_and_keeps_the_answer() {
        // Stiffness varying over four orders of magnitude: the mass-only Jacobi preconditioner is
        // blind to it, diag(A) is not.
        let nv = 20;
        let n = 3 * nv;
        let mut runs = Vec::new();
        for offers in [false, true] {
            let mut sys = linear_chain(nv);
            let k0 = sys.k0.as_mut().unwrap();
            for i in 0..n {
                let s = 10f64.powi((i % 5) as i32);
                k0[(i, i)] *= s;
            }
            sys.offers_diagonal = offers;
            let mut p = params(LinearSolverKind::MatrixFreeCg, 1);
            p.linear.relative_tolerance = 1e-13;
            let mut be = BackwardEuler::new(p);
            let (mut x, mut v) = (Chain::positions(nv, 3), Rng::new(6).vector(n));
            let info = be.step(&mut sys, 0.0, 0.05, &mut x, &mut v, None).unwrap();
            assert!(info.converged);
            assert_eq!(be.stiffness_preconditioned(), offers);
            runs.push((info.linear_iterations[0], v));
        }
        assert!(
            2 * runs[1].0 < runs[0].0,
            "iterations {} vs {}",
            runs[1].0,
            runs[0].0
        );
        for i in 0..n {
            assert!((runs[0].1[i] - runs[1].1[i]).abs() < 1e-7 * (1.0 + runs[0].1[i].abs()));
        }
    }

    #[test]
    fn indefinite_newton_matrix_is_regularized_or_reported() {
        // A negative stiffness (an unstable, buckling-like mode) makes A = M + dt^2 K indefinite.
        // With regularization the solve is retried with a mass shift and the step completes;
        // without it every solver reports the breakdown.
        let nv = 4;
        for kind in [
            LinearSolverKind::MatrixFreeCg,
            LinearSolverKind::Pcg,
            LinearSolverKind::Cholesky,
            LinearSolverKind::FactorizedPcg,
        ] {
            for regularize in [true, false] {
                let mut sys = linear_chain(nv);
                sys.k0.as_mut().unwrap()[(4, 4)] = -2e3;
                let mut be = BackwardEuler::new(BackwardEulerParams {
                    regularize_indefinite: regularize,
                    ..params(kind, 2)
                });
                let (mut x, mut v) = (Chain::positions(nv, 1), Rng::new(2).vector(3 * nv));
                let r = be.step(&mut sys, 0.0, 0.05, &mut x, &mut v, None);
                if regularize {
                    let info = r.unwrap();
                    assert!(
                        info.regularized_solves > 0 && info.max_regularization > 0.0,
                        "{kind}"
                    );
                    assert!(x.iter().chain(&v).all(|a| a.is_finite()));
                } else {
                    let e = r.unwrap_err();
                    assert!(
                        matches!(e, IntegrateError::Linear { iteration: 0, .. }),
                        "{kind}: {e}"
                    );
                }
            }
        }
    }

    #[test]
    fn falling_particle_matches_backward_euler_closed_form() {
        // Free fall: backward Euler gives v_n = v0 + n dt g and x_n = x0 + n dt v0 +
        // dt^2 g n (n + 1) / 2 (it uses the end-of-step velocity); mass damping alpha divides the
        // velocity update by (1 + dt alpha).
        let g = [0.0, 0.0, -9.81];
        let dt = 0.01;
        for kind in [LinearSolverKind::MatrixFreeCg, LinearSolverKind::Cholesky] {
            let mut sys = Free(vec![0.2; 3], true);
            let mut be = BackwardEuler::new(BackwardEulerParams {
                gravity: g,
                ..params(kind, 3)
            });
            let (x0, v0) = ([1.0, 2.0, 3.0], [0.5, 0.0, 1.0]);
            let (mut x, mut v) = (x0.to_vec(), v0.to_vec());
            let steps = 20;
            for s in 0..steps {
                let info = be
                    .step(&mut sys, s as f64 * dt, dt, &mut x, &mut v, None)
                    .unwrap();
                assert!(info.converged);
            }
            let nf = steps as f64;
            for c in 0..3 {
                let ve = v0[c] + nf * dt * g[c];
                let xe = x0[c] + nf * dt * v0[c] + dt * dt * g[c] * nf * (nf + 1.0) / 2.0;
                assert!((v[c] - ve).abs() < 1e-12, "{kind} v{c}");
                assert!((x[c] - xe).abs() < 1e-12, "{kind} x{c}");
            }
        }
        let mut sys = Free(vec![0.2; 3], true);
        let alpha = 2.0;
        let mut be = BackwardEuler::new(BackwardEulerParams {
            gravity: g,
            mass_damping: alpha,
            ..params(LinearSolverKind::MatrixFreeCg, 1)
        });
        let (mut x, mut v) = (vec![0.0; 3], vec![0.0, 0.0, 4.0]);
        be.step(&mut sys, 0.0, dt, &mut x, &mut v, None).unwrap();
        let ve = (4.0 + dt * g[2]) / (1.0 + dt * alpha);
        assert!((v[2] - ve).abs() < 1e-12 && (x[2] - dt * ve).abs() < 1e-14);
    }

    #[test]
    fn damping_reduces_energy() {
        // Backward Euler on a convex quadratic energy never creates energy, and Rayleigh damping
        // removes more: the total energy decreases monotonically and ends below the undamped run.
        let nv = 6;
        let run = |alpha: f64, beta: f64| {
            let mut sys = linear_chain(nv);
            let mut be = BackwardEuler::new(BackwardEulerParams {
                mass_damping: alpha,
                stiffness_damping: beta,
                ..params(LinearSolverKind::MatrixFreeCg, 1)
            });
            let mut x = Chain::positions(nv, 5);
            let mut v = vec![0.0; 3 * nv];
            let energy = |sys: &Chain, x: &[f64], v: &[f64]| {
                sys.energy(x)
                    + 0.5
                        * v.iter()
                            .zip(&sys.masses)
                            .map(|(v, m)| m * v * v)
                            .sum::<f64>()
            };
            let mut e = vec![energy(&sys, &x, &v)];
            for s in 0..30 {
                be.step(&mut sys, s as f64 * 0.01, 0.01, &mut x, &mut v, None)
                    .unwrap();
                e.push(energy(&sys, &x, &v));
            }
            e
        };
        let undamped = run(0.0, 0.0);
        for (a, b) in [(1.0, 0.0), (0.0, 0.01)] {
            let damped = run(a, b);
            assert!(
                damped.windows(2).all(|w| w[1] <= w[0] + 1e-12),
                "{damped:?}"
            );
            assert!(damped.last().unwrap() < undamped.last().unwrap());
        }
        assert!(undamped.windows(2).all(|w| w[1] <= w[0] + 1e-12));
    }

    /// A chain whose `residual_forces` leaves its linearisation at the previous point (as a
    /// lazy system may) until `refresh_stiffness`; every stiffness query panics while stale.
    struct LazyChain {
        inner: Chain,
        pending: Vec<f64>,
        pending_low_rank: Vec<LowRankTerm>,
        stale: bool,
        residual_calls: usize,
        refreshes: usize,
        /// Calls of `forces` (each linearises).
        linearizations: usize,
        /// Whether it offers `residual_forces_and_energy` as one fused evaluation.
        fuse: bool,
        /// Calls of `residual_forces_and_energy` and of `potential_energy` alone.
        fused_calls: usize,
        energy_calls: usize,
    }

    impl LazyChain {
        fn check(&self, what: &str) {
            assert!(!self.stale, "{what} asked while the stiffness is stale");
        }
    }

    impl ForceSystem for LazyChain {
        fn num_dofs(&self) -> usize {
            self.inner.num_dofs()
        }
        fn masses(&self) -> &[f64] {
            self.inner.masses()
        }
        fn forces(&mut self, t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
            self.stale = false;
            self.linearizations += 1;
            self.inner.forces(t, x, f)
        }
        fn residual_forces(&mut self, t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
            let (old_x, old_lr) = (self.inner.x.clone(), self.inner.low_rank.clone());
            self.inner.forces(t, x, f)?;
            self.pending = std::mem::replace(&mut self.inner.x, old_x);
            self.pending_low_rank = std::mem::replace(&mut self.inner.low_rank, old_lr);
            self.stale = true;
            self.residual_calls += 1;
            Ok(())
        }
        fn refresh_stiffness(&mut self) -> Result<(), SystemError> {
            if self.stale {
                self.inner.x.clone_from(&self.pending);
                self.inner.low_rank.clone_from(&self.pending_low_rank);
                self.stale = false;
                self.refreshes += 1;
            }
            Ok(())
        }
        fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
            self.check("the differential");
            self.inner.add_force_differential(dx, df);
        }
        fn add_stiffness_triplets(
            &self,
            t: &mut Vec<(usize, usize, f64)>,
        ) -> Result<(), SystemError> {
            self.check("the stiffness");
            self.inner.add_stiffness_triplets(t)
        }
        fn add_stiffness_diagonal(&self, diagonal: &mut [f64]) -> Result<(), SystemError> {
            self.check("the stiffness diagonal");
            self.inner.add_stiffness_diagonal(diagonal)
        }
        fn low_rank_terms(&self) -> &[LowRankTerm] {
            self.check("the low-rank terms");
            self.inner.low_rank_terms()
        }
        fn potential_energy(&mut self, t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
            self.energy_calls += 1;
            self.inner.potential_energy(t, x)
        }
        fn residual_forces_and_energy(
            &mut self,
            t: f64,
            x: &[f64],
            f: &mut [f64],
        ) -> Result<Option<f64>, SystemError> {
            self.fused_calls += 1;
            self.residual_forces(t, x, f)?;
            self.inner.potential_energy(t, x)
        }
        fn fuses_forces_and_energy(&self) -> bool {
            self.fuse
        }
    }

    fn lazy_chain(nv: usize) -> LazyChain {
        LazyChain {
            inner: Chain::new(nv, true, 7),
            pending: Vec::new(),
            pending_low_rank: Vec::new(),
            stale: false,
            residual_calls: 0,
            refreshes: 0,
            linearizations: 0,
            fuse: false,
            fused_calls: 0,
            energy_calls: 0,
        }
    }

    /// The settings of the chord tests: a damped chain settling to rest, Newton to 1e-6.
    fn chord_params(kind: LinearSolverKind, reuse: usize) -> BackwardEulerParams {
        let mut p = converging(kind, 30, 1e-6);
        p.tangent_reuse_steps = reuse;
        p.mass_damping = 10.0;
        p
    }

    /// Runs `steps` steps of the lazy chain (whose stale stiffness panics when asked for) with
    /// `tangent_reuse_steps = reuse`, calling `between(step, system)` before each; returns the
    /// states, whether each step was a chord step, the Newton iterations and the
    /// linearisations (`forces` calls and stiffness refreshes).
    fn chord_run(
        kind: LinearSolverKind,
        reuse: usize,
        steps: usize,
        mut between: impl FnMut(usize, &mut LazyChain),
    ) -> (Vec<f64>, Vec<f64>, Vec<bool>, usize, usize) {
        let nv = 10;
        let mut be = BackwardEuler::new(chord_params(kind, reuse));
        let mut sys = lazy_chain(nv);
        let mut x = Chain::positions(nv, 5);
        let mut v: Vec<f64> = Rng::new(4).vector(3 * nv);
        let (mut chords, mut newton) = (Vec::new(), 0);
        for s in 0..steps {
            between(s, &mut sys);
            let info = be
                .step(&mut sys, s as f64 * 0.01, 0.01, &mut x, &mut v, None)
                .unwrap();
            chords.push(info.reused_tangent);
            newton += info.newton_iterations;
        }
        (x, v, chords, newton, sys.refreshes + sys.linearizations)
    }

    /// Largest entry-wise difference of `a` and `b` over the largest entry of `b`.
    fn relative_gap(a: &[f64], b: &[f64]) -> f64 {
        let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        a.iter()
            .zip(b)
            .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()))
            / scale
    }

    #[test]
    fn chord_steps_reuse_the_last_matrix_and_reach_the_same_states() {
        // A chord step (the first Newton iteration with the last step's matrix and low-rank
        // terms, after a step one iteration settled) only picks the direction: every step
        // still stops on the residual, so 200 steps of a damped nonlinear chain settling to
        // rest end where the run with a fresh tangent at every iteration does, to the Newton
        // tolerance (1e-6). Chord steps are taken once the chain is near rest, they halve the
        // linearisations for a few more Newton iterations, and they never ask the lazy chain
        // for its stale stiffness or low-rank terms (it panics).
        for kind in [
            LinearSolverKind::Cholesky,
            LinearSolverKind::FactorizedPcg,
            LinearSolverKind::Pcg,
        ] {
            let (x1, v1, chords, newton1, lin1) = chord_run(kind, 8, 200, |_, _| {});
            let (x0, v0, none, newton0, lin0) = chord_run(kind, 0, 200, |_, _| {});
            let taken = chords.iter().filter(|&&c| c).count();
            assert!(
                !none.contains(&true),
                "{kind}: no chord steps when reuse is off"
            );
            assert!(!chords[0], "{kind}: no chord step without a last matrix");
            assert!(taken >= 100, "{kind}: {taken} chord steps of 200");
            assert!(
                2 * lin1 < lin0 + 20,
                "{kind}: linearisations {lin1} against {lin0}"
            );
            assert!(
                10 * newton1 < 11 * newton0,
                "{kind}: Newton {newton1} against {newton0}"
            );
            let (gx, gv) = (relative_gap(&x1, &x0), relative_gap(&v1, &v0));
            assert!(gx < 1e-6 && gv < 1e-4, "{kind}: gaps {gx:e} {gv:e}");
            // At most 8 chord steps in a row, then a fresh tangent.
            let longest = chords.split(|&c| !c).map(<[bool]>::len).max().unwrap_or(0);
            assert!(longest <= 8, "{kind}: {longest} chord steps in a row");
        }
    }

    #[test]
    fn a_chord_step_the_line_search_would_cut_is_not_taken() {
        // Stiffening the springs a thousandfold and lengthening them by 30 % between two steps
        // of the settled chain makes the last step's matrix a poor one far from the new rest:
        // its full step raises the incremental potential, so that step goes on with a fresh
        // tangent from the same iterate (no chord step counted) and lands where the run without
        // reuse does.
        let stiffen = |s: usize, sys: &mut LazyChain| {
            if s == 150 {
                for spring in &mut sys.inner.springs {
                    spring.2 *= 1000.0;
                    spring.3 *= 1.3;
                }
            }
        };
        let kind = LinearSolverKind::Cholesky;
        let (x1, v1, chords, _, _) = chord_run(kind, 1000, 152, stiffen);
        let (x0, v0, _, _, _) = chord_run(kind, 0, 152, stiffen);
        assert!(chords[149], "a chord step right before the change");
        assert!(!chords[150], "no chord step across the stiffening");
        let (gx, gv) = (relative_gap(&x1, &x0), relative_gap(&v1, &v0));
        assert!(gx < 1e-6 && gv < 1e-4, "gaps {gx:e} {gv:e}");
    }

    #[test]
    fn a_step_of_another_size_does_not_reuse_the_matrix() {
        let mut be = BackwardEuler::new(chord_params(LinearSolverKind::Cholesky, 1000));
        let mut sys = lazy_chain(10);
        let mut x = Chain::positions(10, 5);
        let mut v: Vec<f64> = Rng::new(4).vector(30);
        let mut last = false;
        for s in 0..150 {
            last = be
                .step(&mut sys, s as f64 * 0.01, 0.01, &mut x, &mut v, None)
                .unwrap()
                .reused_tangent;
        }
        assert!(last, "chord steps at the settled state");
        let info = be.step(&mut sys, 1.5, 0.005, &mut x, &mut v, None).unwrap();
        assert!(
            !info.reused_tangent,
            "the Newton matrix of dt = 0.005 differs"
        );
    }

    #[test]
    fn fused_trial_energies_and_forces_give_the_same_steps_in_fewer_passes() {
        // A system that evaluates a trial's forces and energy together
        // (`fuses_forces_and_energy`) takes the same Newton iterates, bit for bit, as one whose
        // line search asks for the energy first and the forces of an accepted trial after it;
        // the energy alone is then asked for only where Newton linearises (the first iterate
        // of a step that is not a chord step), never for a trial. With and without chord
        // steps, for every linear solver.
        let nv = 10;
        let x0 = Chain::positions(nv, 5);
        let v0: Vec<f64> = Rng::new(4).vector(3 * nv);
        for kind in [
            LinearSolverKind::Cholesky,
            LinearSolverKind::FactorizedPcg,
            LinearSolverKind::Pcg,
            LinearSolverKind::MatrixFreeCg,
        ] {
            for reuse in [0, 3] {
                let mut p = converging(kind, 30, 1e-10);
                p.tangent_reuse_steps = reuse;
                let run = |fuse: bool| {
                    let mut be = BackwardEuler::new(p);
                    let mut sys = lazy_chain(nv);
                    sys.fuse = fuse;
                    let (mut x, mut v) = (x0.clone(), v0.clone());
                    let (mut newton, mut cuts, mut linearized_starts) = (0, 0, 0);
                    for s in 0..8 {
                        let info = be
                            .step(&mut sys, s as f64 * 0.01, 0.01, &mut x, &mut v, None)
                            .unwrap();
                        newton += info.newton_iterations;
                        cuts += info.line_search_cuts;
                        linearized_starts += usize::from(!info.reused_tangent);
                    }
                    (x, v, newton, cuts, linearized_starts, sys)
                };
                let (xf, vf, nf, cf, starts, fused) = run(true);
                let (xs, vs, ns, cs, _, split) = run(false);
                assert_eq!((nf, cf), (ns, cs), "{kind}, reuse {reuse}");
                assert!(
                    xf.iter().zip(&xs).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{kind}, reuse {reuse}"
                );
                assert!(
                    vf.iter().zip(&vs).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{kind}, reuse {reuse}"
                );
                // Every trial is fused: at least one per Newton iteration.
                assert!(fused.fused_calls >= nf, "{kind}: {}", fused.fused_calls);
                assert_eq!(split.fused_calls, 0, "{kind}");
                assert_eq!(fused.energy_calls, starts, "{kind}, reuse {reuse}");
                assert!(
                    split.energy_calls >= nf + 8,
                    "{kind}: {} energies",
                    split.energy_calls
                );
            }
        }
    }

    #[test]
    fn line_search_trials_may_skip_the_stiffness_and_the_step_is_unchanged() {
        // The trials of the line search use `residual_forces`; before Newton goes on from one,
        // the integrator refreshes the stiffness (a stale query would panic). The states are
        // bit-identical to those of the same chain linearised at every evaluation, for every
        // linear solver, with and without stiffness damping (which needs `K v` at once).
        let nv = 10;
        let x0 = Chain::positions(nv, 5);
        let v0: Vec<f64> = Rng::new(4).vector(3 * nv);
        for kind in [
            LinearSolverKind::Cholesky,
            LinearSolverKind::FactorizedPcg,
            LinearSolverKind::Pcg,
            LinearSolverKind::MatrixFreeCg,
        ] {
            for beta in [0.0, 0.01] {
                let mut p = converging(kind, 30, 1e-10);
                p.stiffness_damping = beta;
                let run = |lazy: bool| {
                    let mut be = BackwardEuler::new(p);
                    let mut sys = lazy_chain(nv);
                    let (mut x, mut v) = (x0.clone(), v0.clone());
                    let mut newton = 0;
                    for s in 0..6 {
                        let info = if lazy {
                            be.step(&mut sys, s as f64 * 0.01, 0.01, &mut x, &mut v, None)
                        } else {
                            be.step(&mut sys.inner, s as f64 * 0.01, 0.01, &mut x, &mut v, None)
                        }
                        .unwrap();
                        newton += info.newton_iterations;
                    }
                    (x, v, newton, sys.residual_calls, sys.refreshes)
                };
                let (xl, vl, nl, calls, refreshes) = run(true);
                let (xe, ve, ne, _, _) = run(false);
                assert_eq!(nl, ne, "{kind}, beta {beta}");
                assert!(
                    xl.iter().zip(&xe).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{kind}"
                );
                assert!(
                    vl.iter().zip(&ve).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{kind}"
                );
                if beta == 0.0 {
                    // One trial per Newton iteration at least; a refresh only where Newton went
                    // on from a trial (not after the last one of each step).
                    assert!(
                        calls >= nl,
                        "{kind}: {calls} trials, {nl} Newton iterations"
                    );
                    assert!(
                        refreshes < calls && refreshes >= nl - 6,
                        "{kind}: {refreshes}"
                    );
                } else {
                    assert_eq!(
                        calls, 0,
                        "{kind}: stiffness damping linearises every evaluation"
                    );
                }
            }
        }
    }

    #[test]
    fn phase_times_account_for_the_step_without_double_counting() {
        // The phases are timed separately: per step they add up to at most the step's wall
        // time, a step without a factorisation has no factorisation time, a matrix-free solve
        // no assembly, and the running total is the sum of the steps'.
        let nv = 12;
        let x0 = Chain::positions(nv, 5);
        let v0: Vec<f64> = Rng::new(4).vector(3 * nv);
        for kind in [
            LinearSolverKind::FactorizedPcg,
            LinearSolverKind::MatrixFreeCg,
        ] {
            let mut sys = Chain::new(nv, true, 7);
            let mut p = converging(kind, 30, 1e-9);
            p.refactor_iterations = 6;
            let mut be = BackwardEuler::new(p);
            let (mut x, mut v) = (x0.clone(), v0.clone());
            let mut sum = PhaseTimes::default();
            let mut factorized_steps = 0;
            for s in 0..8 {
                let started = Instant::now();
                let info = be
                    .step(&mut sys, s as f64 * 0.002, 0.002, &mut x, &mut v, None)
                    .unwrap();
                let wall = ms_since(started);
                let t = info.times;
                assert!(t.total_ms() <= wall + 1e-9, "{kind}: {t} in {wall} ms");
                assert!(t.forces_ms > 0.0 && t.energy_ms > 0.0, "{kind}: {t}");
                assert!(t.solve_ms > 0.0 && t.projection_ms == 0.0, "{kind}: {t}");
                assert_eq!(
                    t.factorization_ms > 0.0,
                    info.factorizations > 0,
                    "{kind}: {t}"
                );
                if kind == LinearSolverKind::MatrixFreeCg {
                    assert_eq!(t.assembly_ms, 0.0, "{t}");
                } else {
                    assert!(t.assembly_ms > 0.0, "{t}");
                }
                factorized_steps += usize::from(info.factorizations > 0);
                sum += t;
            }
            let total = be.phase_times();
            assert!(
                (total.total_ms() - sum.total_ms()).abs() < 1e-9,
                "{total} vs {sum}"
            );
            if kind == LinearSolverKind::FactorizedPcg {
                // The lagged factor is reused: some steps factorise, some do not.
                assert!((1..8).contains(&factorized_steps), "{factorized_steps}");
            }
        }
    }

    #[test]
    fn factorized_pcg_reuses_its_factor_and_refreshes_it_when_stale() {
        // A chain whose stiffness barely changes: the factor of the first Newton matrix
        // preconditions all later solves, and the answer is the Cholesky one.
        let nv = 12;
        let x0 = Chain::positions(nv, 5);
        let v0: Vec<f64> = Rng::new(4).vector(3 * nv);
        let run = |kind: LinearSolverKind, dts: &[f64]| {
            let mut sys = Chain::new(nv, true, 7);
            let mut p = params(kind, 3);
            p.linear.relative_tolerance = 1e-11;
            p.refactor_iterations = 6;
            let mut be = BackwardEuler::new(p);
            let (mut x, mut v) = (x0.clone(), v0.clone());
            let mut infos = Vec::new();
            let mut t = 0.0;
            for &dt in dts {
                let info = be.step(&mut sys, t, dt, &mut x, &mut v, None).unwrap();
                assert!(info.converged, "{kind}: {info:?}");
                t += dt;
                infos.push(info);
            }
            (x, v, infos)
        };
        let dts = [0.002; 8];
        let (xc, vc, ic) = run(LinearSolverKind::Cholesky, &dts);
        let (xf, vf, inf) = run(LinearSolverKind::FactorizedPcg, &dts);
        assert!(ic.iter().all(|i| i.factorizations == 3));
        let total: usize = inf.iter().map(|i| i.factorizations).sum();
        assert!(inf[0].factorizations >= 1);
        assert!(total <= 2, "factorisations {total} of 24 solves");
        for i in 0..xc.len() {
            assert!((xf[i] - xc[i]).abs() < 1e-10, "x[{i}]");
            assert!((vf[i] - vc[i]).abs() < 1e-8 * (1.0 + vc[i].abs()), "v[{i}]");
        }
        // The time step jumps 100-fold: the old factor (of M + dt^2 K at the small dt) is a poor
        // preconditioner, so the solver refactorises and still converges.
        let (_, _, jumped) = run(
            LinearSolverKind::FactorizedPcg,
            &[0.0005, 0.0005, 0.05, 0.05, 0.05, 0.05],
        );
        assert!(jumped[1].factorizations == 0, "{:?}", jumped[1]);
        // After the slow solve the next six solves (the rest of step 2 and all of step 3)
        // refactorise first; then the lagged factor is tried again.
        let f: Vec<usize> = jumped.iter().map(|i| i.factorizations).collect();
        assert!(f[2] == 3 && f[3] == 3 && f[4] < 3, "{f:?}");
    }

    #[test]
    fn projected_tangent_is_passed_to_the_system_or_refused() {
        // The test chain only has the exact tangent: asking for the projected one is a clear
        // error before any work, not a silent fallback.
        let nv = 4;
        let mut sys = Chain::new(nv, true, 3);
        let mut be = BackwardEuler::new(BackwardEulerParams {
            tangent: TangentKind::Projected,
            ..params(LinearSolverKind::Cholesky, 2)
        });
        let (mut x, mut v) = (Chain::positions(nv, 1), vec![0.0; 3 * nv]);
        let e = be
            .step(&mut sys, 0.0, 0.01, &mut x, &mut v, None)
            .unwrap_err();
        assert!(
            matches!(
                e,
                IntegrateError::System {
                    source: SystemError::TangentUnsupported(TangentKind::Projected),
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("projected"), "{e}");
        assert_eq!(
            "Projected ".parse::<TangentKind>(),
            Ok(TangentKind::Projected)
        );
        assert_eq!(TangentKind::Exact.to_string(), "exact");
        assert!("psd".parse::<TangentKind>().unwrap_err().contains("psd"));
    }

    #[test]
    fn errors_are_reported_with_context() {
        let nv = 4;
        let x0 = Chain::positions(nv, 1);
        let mut sys = Chain::new(nv, true, 3);
        sys.poison = true;
        let mut be = BackwardEuler::new(params(LinearSolverKind::MatrixFreeCg, 3));
        let (mut x, mut v) = (x0.clone(), vec![0.0; 3 * nv]);
        let e = be
            .step(&mut sys, 0.0, 0.01, &mut x, &mut v, None)
            .unwrap_err();
        assert!(
            matches!(
                e,
                IntegrateError::NonFinite {
                    dof: 7,
                    vertex: 2,
                    ..
                }
            ),
            "{e}"
        );
        let mut free = Free(vec![1.0; 3], false);
        let mut be = BackwardEuler::new(BackwardEulerParams {
            gravity: [0.0, 0.0, -1.0],
            ..params(LinearSolverKind::Pcg, 1)
        });
        let e = be
            .step(&mut free, 0.0, 0.01, &mut [0.0; 3], &mut [0.0; 3], None)
            .unwrap_err();
        assert!(
            matches!(
                e,
                IntegrateError::System {
                    source: SystemError::AssemblyUnsupported,
                    ..
                }
            ),
            "{e}"
        );
        let e = be
            .step(&mut free, 0.0, -0.01, &mut [0.0; 3], &mut [0.0; 3], None)
            .unwrap_err();
        assert!(e.to_string().contains("dt"), "{e}");
        let e = be
            .step(&mut free, 0.0, 0.01, &mut [0.0; 2], &mut [0.0; 3], None)
            .unwrap_err();
        assert!(e.to_string().contains("`x`"), "{e}");
        // Too few CG iterations: the step still returns but says it did not converge.
        let mut sys = Chain::new(8, true, 3);
        let mut p = params(LinearSolverKind::MatrixFreeCg, 1);
        p.linear.max_iterations = 1;
        let mut be = BackwardEuler::new(p);
        let (mut x, mut v) = (Chain::positions(8, 2), Rng::new(1).vector(24));
        let info = be.step(&mut sys, 0.0, 0.01, &mut x, &mut v, None).unwrap();
        assert!(!info.converged && info.linear_residuals[0] > 1e-12);
    }

    /// Particles on stiff saturating springs to the origin, per coordinate
    /// `W = k l^2 (sqrt(1 + (x/l)^2) - 1)`: the force saturates at `k l` far from rest, so the
    /// quadratic model of Newton overshoots there (a full step from `x` lands near `-x^3/l^2`).
    /// `.potential` says whether it reports its energy.
    #[derive(Debug, Clone)]
    struct Saturating {
        masses: Vec<f64>,
        k: f64,
        l: f64,
        x: Vec<f64>,
        potential: bool,
    }

    impl Saturating {
        fn new(potential: bool) -> Self {
            Self {
                masses: vec![1e-3; 3],
                k: 1e4,
                l: 0.01,
                x: vec![0.0; 3],
                potential,
            }
        }
    }

    impl ForceSystem for Saturating {
        fn num_dofs(&self) -> usize {
            3
        }
        fn masses(&self) -> &[f64] {
            &self.masses
        }
        fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
            self.x.copy_from_slice(x);
            for (f, x) in f.iter_mut().zip(x) {
                *f = -self.k * x / (1.0 + (x / self.l).powi(2)).sqrt();
            }
            Ok(())
        }
        fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
            for ((df, dx), x) in df.iter_mut().zip(dx).zip(&self.x) {
                *df -= self.k / (1.0 + (x / self.l).powi(2)).powf(1.5) * dx;
            }
        }
        fn add_stiffness_triplets(
            &self,
            t: &mut Vec<(usize, usize, f64)>,
        ) -> Result<(), SystemError> {
            for (i, x) in self.x.iter().enumerate() {
                t.push((i, i, self.k / (1.0 + (x / self.l).powi(2)).powf(1.5)));
            }
            Ok(())
        }
        fn potential_energy(&mut self, _t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
            Ok(self.potential.then(|| {
                x.iter()
                    .map(|x| self.k * self.l * self.l * ((1.0 + (x / self.l).powi(2)).sqrt() - 1.0))
                    .sum()
            }))
        }
    }

    fn converging(kind: LinearSolverKind, iters: usize, tol: f64) -> BackwardEulerParams {
        BackwardEulerParams {
            newton_tolerance: tol,
            ..params(kind, iters)
        }
    }

    #[test]
    fn saturating_spring_potential_matches_its_forces() {
        let mut sys = Saturating::new(true);
        let x = vec![0.03, -0.002, 0.011];
        balloon_test_support::check_gradient(
            |x| sys.clone().potential_energy(0.0, x).unwrap().unwrap(),
            |x| {
                let mut f = vec![0.0; 3];
                sys.clone().forces(0.0, x, &mut f).unwrap();
                f.iter().map(|v| -v).collect()
            },
            &x,
            1e-7,
            1e-6,
        );
        let mut f = vec![0.0; 3];
        sys.forces(0.0, &x, &mut f).unwrap();
    }

    /// A solve that makes no headway stops after the stall window instead of spending every
    /// allowed iteration (the caller's step halving is the remedy), and says how far it got.
    #[test]
    fn a_stalled_newton_solve_stops_after_the_stall_window() {
        let (dt, x0) = (0.01, vec![0.3, -0.2, 0.25]);
        for kind in [LinearSolverKind::Cholesky, LinearSolverKind::MatrixFreeCg] {
            // No potential: the residual line search only asks for a small decrease.
            let mut sys = Saturating::new(false);
            let mut be = BackwardEuler::new(converging(kind, 500, 1e-10));
            let (mut x, mut v) = (x0.clone(), vec![0.0; 3]);
            match be.step(&mut sys, 0.0, dt, &mut x, &mut v, None) {
                Err(IntegrateError::NotConverged {
                    iterations,
                    residual,
                    ..
                }) => {
                    assert!(
                        (NEWTON_STALL_WINDOW..3 * NEWTON_STALL_WINDOW).contains(&iterations),
                        "{kind}: stopped after {iterations} iterations"
                    );
                    assert!(residual > 1e-10, "{kind}: {residual}");
                }
                other => panic!("{kind}: expected NotConverged, got {other:?}"),
            }
        }
    }

    #[test]
    fn line_search_converges_where_full_newton_steps_overshoot() {
        // Far out on the saturating spring (30 l) with a large step (k dt^2 / m = 1e3): the
        // full Newton step flies to the other side, farther out each time.
        let dt = 0.01;
        let x0 = vec![0.3, -0.2, 0.25];
        for kind in [LinearSolverKind::Cholesky, LinearSolverKind::MatrixFreeCg] {
            // With the energy line search: converged, every accepted iterate lowers E.
            let mut sys = Saturating::new(true);
            let mut be = BackwardEuler::new(converging(kind, 100, 1e-10));
            let (mut x, mut v) = (x0.clone(), vec![0.0; 3]);
            let info = be.step(&mut sys, 0.0, dt, &mut x, &mut v, None).unwrap();
            assert!(
                info.converged && info.relative_residual <= 1e-10,
                "{info:?}"
            );
            assert!(
                info.line_search_cuts > 0,
                "{kind}: no cut was needed: {info:?}"
            );
            assert_eq!(info.energies.len(), info.newton_iterations + 1, "{info:?}");
            for w in info.energies.windows(2) {
                assert!(w[1] < w[0], "{kind}: energy rose: {:?}", info.energies);
            }
            // The result is the backward Euler solution: m (x - x0) / dt^2 = f(x).
            let mut f = vec![0.0; 3];
            sys.forces(0.0, &x, &mut f).unwrap();
            for c in 0..3 {
                let r = 1e-3 * (x[c] - x0[c]) / (dt * dt) - f[c];
                assert!(r.abs() < 1e-8 * sys.k * sys.l, "{kind}: residual {r}");
            }
            // Without a potential (full Newton steps) it does not converge at all.
            let mut sys = Saturating::new(false);
            let mut be = BackwardEuler::new(converging(kind, 100, 1e-10));
            let (mut x, mut v) = (x0.clone(), vec![0.0; 3]);
            let e = be
                .step(&mut sys, 0.0, dt, &mut x, &mut v, None)
                .unwrap_err();
            assert!(
                matches!(
                    e,
                    IntegrateError::NotConverged { .. } | IntegrateError::NonFinite { .. }
                ),
                "{kind}: {e}"
            );
            // Nor does the paper's mode: its residual after many full steps is large.
            let mut sys = Saturating::new(true);
            let mut be = BackwardEuler::new(params(kind, 8));
            let (mut x, mut v) = (x0.clone(), vec![0.0; 3]);
            match be.step(&mut sys, 0.0, dt, &mut x, &mut v, None) {
                Ok(info) => assert!(
                    info.relative_residual.is_nan() || info.relative_residual >= 1e-2,
                    "{kind}: {info:?}"
                ),
                Err(e) => assert!(matches!(e, IntegrateError::NonFinite { .. }), "{e}"),
            }
        }
    }

    #[test]
    fn line_searched_newton_decreases_the_incremental_potential_on_the_chain() {
        // The nonlinear chain with gravity, mass damping and external forces, with the exact
        // incremental potential recomputed independently here.
        let nv = 8;
        let (dt, alpha) = (0.05, 3.0);
        let g = [0.0, -9.81, 0.0];
        let ext = Rng::new(12).vector(3 * nv);
        let mut sys = Chain::new(nv, true, 5);
        let mut be = BackwardEuler::new(BackwardEulerParams {
            mass_damping: alpha,
            gravity: g,
            ..converging(LinearSolverKind::Cholesky, 50, 1e-9)
        });
        let x0: Vec<f64> = Chain::positions(nv, 6).iter().map(|v| 1.5 * v).collect();
        let v0: Vec<f64> = Rng::new(7).vector(3 * nv).iter().map(|v| 3.0 * v).collect();
        let (mut x, mut v) = (x0.clone(), v0.clone());
        let info = be
            .step(&mut sys, 0.0, dt, &mut x, &mut v, Some(&ext))
            .unwrap();
        assert!(info.converged && info.relative_residual <= 1e-9, "{info:?}");
        // Non-increasing up to the round-off of E (the last iterates agree to ~1e-16).
        assert!(
            info.energies
                .windows(2)
                .all(|w| w[1] <= w[0] + 1e-14 * w[0].abs()),
            "{info:?}"
        );
        assert!(info.energies[1] < info.energies[0]);
        // E(x) of the module docs at the result is the minimum along random directions.
        let m_coef = 1.0 + dt * alpha;
        let e = |x: &[f64]| {
            let mut total = sys.energy(x);
            for i in 0..x.len() {
                let m = sys.masses[i];
                let d = x[i] - x0[i] - dt * v0[i] / m_coef;
                total += m_coef / (2.0 * dt * dt) * m * d * d;
                total -= (m * g[i % 3] + ext[i]) * x[i];
            }
            total
        };
        let e_min = e(&x);
        for seed in 0..4 {
            let d = Rng::new(100 + seed).vector(x.len());
            for h in [1e-4, -1e-4] {
                let xs: Vec<f64> = x.iter().zip(&d).map(|(a, b)| a + h * b).collect();
                assert!(e(&xs) > e_min, "not a minimum along direction {seed}");
            }
        }
        // The recorded energies differ from E(x) by a constant: their drop is E's drop.
        let e_first = e(&x0
            .iter()
            .zip(&v0)
            .map(|(x, v)| x + dt * v)
            .collect::<Vec<_>>());
        let drop = info.energies[0] - info.energies.last().unwrap();
        assert!(
            (drop - (e_first - e_min)).abs() < 1e-8 * drop.abs().max(1e-12),
            "{drop} vs {}",
            e_first - e_min
        );
    }

    #[test]
    fn too_few_iterations_are_not_converged_and_bounds_are_checked() {
        let nv = 6;
        let mut sys = Chain::new(nv, true, 3);
        let mut be = BackwardEuler::new(converging(LinearSolverKind::Cholesky, 1, 1e-12));
        let (mut x, mut v) = (Chain::positions(nv, 4), Rng::new(5).vector(3 * nv));
        let e = be
            .step(&mut sys, 0.0, 0.05, &mut x, &mut v, None)
            .unwrap_err();
        match e {
            IntegrateError::NotConverged {
                iterations,
                residual,
                tolerance,
            } => {
                assert_eq!(iterations, 1);
                assert!(residual > tolerance && residual.is_finite());
            }
            e => panic!("{e}"),
        }
        assert!(e.to_string().contains("did not converge"), "{e}");
        // Stiffness damping (no potential): the residual search still converges.
        let mut be = BackwardEuler::new(BackwardEulerParams {
            stiffness_damping: 0.01,
            ..converging(LinearSolverKind::Cholesky, 30, 1e-10)
        });
        let (mut x, mut v) = (Chain::positions(nv, 4), Rng::new(5).vector(3 * nv));
        let info = be.step(&mut sys, 0.0, 0.05, &mut x, &mut v, None).unwrap();
        assert!(info.energies.is_empty() && info.relative_residual <= 1e-10);
        for bad in [0, MAX_NEWTON_ITERATIONS + 1] {
            let mut be = BackwardEuler::new(converging(LinearSolverKind::Cholesky, bad, 1e-8));
            let e = be
                .step(&mut sys, 0.0, 0.05, &mut x, &mut v, None)
                .unwrap_err();
            assert!(e.to_string().contains("newton_iterations"), "{e}");
        }
    }

    #[test]
    fn the_relative_residual_does_not_depend_on_units() {
        // The same step in metres and in millimetres (forces scale with the length, masses
        // stay): the relative residuals agree.
        let run = |scale: f64| {
            let mut sys = Saturating::new(true);
            sys.l *= scale;
            let mut be = BackwardEuler::new(converging(LinearSolverKind::Cholesky, 100, 1e-10));
            let mut x: Vec<f64> = [0.03, -0.02, 0.025].iter().map(|v| v * scale).collect();
            let mut v = vec![0.0; 3];
            be.step(&mut sys, 0.0, 0.01, &mut x, &mut v, None)
                .unwrap()
                .relative_residuals
        };
        let (a, b) = (run(1.0), run(1e3));
        assert_eq!(a.len(), b.len());
        // Equal down to where round-off takes over.
        for (a, b) in a.iter().zip(&b).filter(|(a, _)| **a > 1e-10) {
            assert!((a - b).abs() <= 1e-6 * a, "{a} vs {b}");
        }
    }
}
