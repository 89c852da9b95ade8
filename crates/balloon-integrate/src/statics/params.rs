//! [`StaticParams`]: the parameters of a static solve, with their defaults and their
//! validation (done once, when the solver is made or its parameters set).

use serde::{Deserialize, Serialize};

use balloon_linalg::{LinearSolverKind, SolverSettings};

use crate::implicit::{DEFAULT_INEXACT_FORCING, DEFAULT_NEWTON_TOLERANCE};
use crate::newton::{MAX_NEWTON_ITERATIONS, NewtonError, check_parameter};
use crate::system::TangentKind;

/// Default [`StaticParams::max_iterations`]: Newton iterations allowed per load stage, the
/// core's limit ([`MAX_NEWTON_ITERATIONS`]); a stage that stops making progress ends
/// earlier, after [`StaticParams::stall_window`] iterations without halving its residual.
pub const DEFAULT_STATIC_ITERATIONS: usize = MAX_NEWTON_ITERATIONS;

/// Parameters of [`StaticSolver`](super::StaticSolver).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct StaticParams {
    /// Relative residual at which the full-load stage stops (default
    /// [`DEFAULT_NEWTON_TOLERANCE`], the dynamic Newton's; module docs). Positive.
    pub tolerance: f64,
    /// Relative residual at which an intermediate continuation stage stops (default `1e-3`; the
    /// tighter of this and `tolerance` is used).
    pub continuation_tolerance: f64,
    /// Newton iterations allowed per load stage (default [`DEFAULT_STATIC_ITERATIONS`], at most
    /// [`MAX_NEWTON_ITERATIONS`]).
    pub max_iterations: usize,
    /// The linear solver (default [`LinearSolverKind::FactorizedPcg`]: CG preconditioned by a
    /// kept sparse Cholesky factor, the low-rank terms by Sherman-Morrison, factorised on the
    /// thread pool for large matrices; module docs, "Reused factorisations").
    /// [`LinearSolverKind::Cholesky`] refactorises at every iteration.
    pub solver: SolverSettings,
    /// Which tangent the system linearises with (default exact: quadratic convergence, the
    /// shift handles indefiniteness).
    pub tangent: TangentKind,
    /// First Levenberg-Marquardt shift relative to `mu_ref` (default `1e-2`).
    pub initial_shift: f64,
    /// Smallest shift relative to `mu_ref` (default `1e-9`; keeps the rigid motions of a free
    /// body regular).
    pub min_shift: f64,
    /// The system is a free body (nothing pinned, no net external force): remove the six rigid
    /// motions from every Newton direction (default `false`). They cost no energy, so only the
    /// shift holds them, and a preconditioner rounded to single precision
    /// ([`balloon_linalg::FactorizedPcgParams::single_precision_factorization`]) would let the
    /// body turn by about `1e-5` rad over a solve (the peer sphere: 3.3e-6 of the diagonal, the
    /// shape itself unchanged to 8.5e-10). Must stay `false` when vertices are pinned (the
    /// rigid motions then move the body against its pins).
    pub remove_rigid_motions: bool,
    /// Halvings of the continuation increment before the solve gives up (default 12).
    pub max_load_halvings: usize,
    /// Inexact Newton: each linear solve is asked for a linearised residual of this fraction
    /// of the stage's tolerance (as [`crate::implicit::BackwardEulerParams::inexact_forcing`];
    /// default [`crate::implicit::DEFAULT_INEXACT_FORCING`], `0`: every solve to the linear
    /// solver's own tolerance).
    pub inexact_forcing: f64,
    /// A load stage whose best relative residual has not halved over this many Newton
    /// iterations is stopped as stalled (default [`DEFAULT_STALL_WINDOW`]; `0`: never, the
    /// stage runs to [`StaticParams::max_iterations`]). A converging stage halves its residual
    /// in a few iterations; a stage that wanders for this long is on a flat, indefinite
    /// energy (a wrinkling or buckling membrane, module docs "Stalled stages").
    pub stall_window: usize,
    /// Continuation increments in a row that stall (above) before the solve stops with
    /// [`NewtonError::NoEquilibrium`] (default 3; `0`: a stall is handled like any failed
    /// increment, up to [`StaticParams::max_load_halvings`]).
    pub max_stalled_stages: usize,
}

/// Default [`StaticParams::stall_window`]: Newton iterations over which a stage's best
/// relative residual must halve.
pub const DEFAULT_STALL_WINDOW: usize = 100;

impl StaticParams {
    /// Checks every parameter against its range (each field's docs); the error names the
    /// first one out of range with its value. [`super::StaticSolver::new`] and
    /// [`super::StaticSolver::set_params`] call it.
    pub fn validate(&self) -> Result<(), NewtonError> {
        for (name, value) in [
            ("tolerance", self.tolerance),
            ("continuation_tolerance", self.continuation_tolerance),
            ("initial_shift", self.initial_shift),
            ("min_shift", self.min_shift),
        ] {
            check_parameter(
                name,
                value,
                value.is_finite() && value > 0.0,
                "positive and finite",
            )?;
        }
        check_parameter(
            "inexact_forcing",
            self.inexact_forcing,
            self.inexact_forcing.is_finite() && (0.0..=1.0).contains(&self.inexact_forcing),
            "in [0, 1] (0: every linear solve to its own tolerance)",
        )?;
        check_parameter(
            "max_iterations",
            self.max_iterations as f64,
            (1..=MAX_NEWTON_ITERATIONS).contains(&self.max_iterations),
            "an integer from 1 to 1000",
        )
    }
}

impl Default for StaticParams {
    fn default() -> Self {
        let mut solver = SolverSettings::default();
        solver.linear.kind = LinearSolverKind::FactorizedPcg;
        solver.parallel_factorization = false;
        Self {
            tolerance: DEFAULT_NEWTON_TOLERANCE,
            continuation_tolerance: 1e-3,
            max_iterations: DEFAULT_STATIC_ITERATIONS,
            solver,
            tangent: TangentKind::Exact,
            initial_shift: 1e-2,
            min_shift: 1e-9,
            remove_rigid_motions: false,
            max_load_halvings: 12,
            inexact_forcing: DEFAULT_INEXACT_FORCING,
            stall_window: DEFAULT_STALL_WINDOW,
            max_stalled_stages: 3,
        }
    }
}
