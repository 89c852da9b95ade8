//! [`BackwardEulerParams`]: the parameters of a backward Euler step, with their defaults and
//! their validation (done once, when the integrator is made or its parameters set).

use serde::{Deserialize, Serialize};

use balloon_linalg::{LinearSolverParams, PcgPreconditioner, SolverSettings};

use crate::newton::{MAX_NEWTON_ITERATIONS, NewtonError, check_parameter};
use crate::system::TangentKind;

/// Default [`BackwardEulerParams::newton_iterations`]: the most Newton iterations a step may
/// take.
pub const DEFAULT_NEWTON_ITERATIONS: usize = 30;

/// Default [`BackwardEulerParams::newton_tolerance`] (relative residual). Newton always takes
/// at least one iteration.
pub const DEFAULT_NEWTON_TOLERANCE: f64 = 1e-6;

/// Parameters of [`BackwardEuler`](super::BackwardEuler).
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
    /// `newton_iterations` is [`IntegrateError::NotConverged`](super::IntegrateError::NotConverged). `0` is the paper's mode:
    /// `newton_iterations` full Newton steps, no line search, no residual test.
    pub newton_tolerance: f64,
    /// With `newton_tolerance > 0`: a step that has not met the tolerance after
    /// `newton_iterations` line-searched iterations (or whose line search finds no decrease)
    /// is accepted at its last iterate, reported with [`StepInfo::converged`](super::StepInfo::converged) `false`, instead
    /// of [`IntegrateError::NotConverged`](super::IntegrateError::NotConverged); the stall test is off. Every accepted
    /// iterate still lowers the incremental potential (the line search of the module docs),
    /// so, unlike the paper's mode of full steps, a few iterations cannot pump energy into the
    /// system. For interactive use, where a step must end in a bounded time (default
    /// `false`).
    pub accept_unconverged: bool,
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
    /// no regularisation retries). Passed to [`ForceSystem::set_tangent`](crate::ForceSystem::set_tangent) at every step.
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

/// Default [`BackwardEulerParams::tangent_reuse_steps`].
pub const DEFAULT_TANGENT_REUSE_STEPS: usize = 8;

impl BackwardEulerParams {
    /// Checks every parameter against its range (each field's docs); the error names the
    /// first one out of range with its value. [`crate::implicit::BackwardEuler::new`] and
    /// [`crate::implicit::BackwardEuler::set_params`] call it, so a step never runs with
    /// parameters out of range.
    pub fn validate(&self) -> Result<(), NewtonError> {
        check_parameter(
            "mass_damping",
            self.mass_damping,
            self.mass_damping.is_finite() && self.mass_damping >= 0.0,
            "finite and non-negative (1/s)",
        )?;
        check_parameter(
            "inexact_forcing",
            self.inexact_forcing,
            self.inexact_forcing.is_finite() && (0.0..=1.0).contains(&self.inexact_forcing),
            "in [0, 1] (0: every linear solve to its own tolerance)",
        )?;
        check_parameter(
            "stiffness_damping",
            self.stiffness_damping,
            self.stiffness_damping.is_finite() && self.stiffness_damping >= 0.0,
            "finite and non-negative (s)",
        )?;
        check_parameter(
            "newton_tolerance",
            self.newton_tolerance,
            self.newton_tolerance.is_finite() && self.newton_tolerance >= 0.0,
            "finite and non-negative",
        )?;
        check_parameter(
            "newton_iterations",
            self.newton_iterations as f64,
            (1..=MAX_NEWTON_ITERATIONS).contains(&self.newton_iterations),
            "an integer from 1 to 1000",
        )?;
        if let Some(g) = self.gravity.iter().find(|g| !g.is_finite()) {
            check_parameter("gravity", *g, false, "finite in every component (m/s^2)")?;
        }
        Ok(())
    }

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
            accept_unconverged: false,
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
