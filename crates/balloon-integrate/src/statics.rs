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
//! what the shift leaves of round-off (the residual has no component along them).
//!
//! # Reused factorisations
//!
//! The default linear solver keeps its sparse Cholesky factor across Newton iterations and
//! across solves ([`LinearSolverKind::FactorizedPcg`]: CG on the current matrix preconditioned
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
//! [`LinearSolverKind::Cholesky`] (refactorise every iteration) remains an option.
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
//! let mut solver = StaticSolver::new(params);
//! let mut x = vec![0.0; 3];
//! let info = solver.solve(&mut system, 0.0, &mut x, Some(&[2.0, 0.0, -1.0]))?;
//! assert!(info.converged && info.relative_residual <= 1e-6);
//! // k x = f_ext.
//! assert!((x[0] - 0.02).abs() < 1e-9 && (x[2] + 0.01).abs() < 1e-9);
//! # Ok::<(), balloon_integrate::statics::StaticError>(())
//! ```

use std::time::Instant;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use balloon_linalg::{
    CgParams, FactorizedPcg, FactorizedPcgParams, LinearProblem, LinearSolver, LinearSolverKind,
    SolveError, SolveInfo, SolverSettings, SparseAssembler, StiffnessOperator,
};

use crate::implicit::{
    ARMIJO, DEFAULT_NEWTON_TOLERANCE, ENERGY_ROUNDOFF, MAX_LINE_SEARCH_CUTS, MAX_NEWTON_ITERATIONS,
    MAX_REGULARIZATION_RETRIES, Residual, extent, first_non_finite, norm,
};
use crate::system::{ForceSystem, SystemError, TangentKind};
/// Phase timings (moved to [`crate::timing`]; kept here under their old path).
pub use crate::timing::PhaseTimes;
use crate::timing::ms_since;

/// Default [`StaticParams::max_iterations`]: Newton iterations allowed per load stage.
pub const DEFAULT_STATIC_ITERATIONS: usize = 200;

/// Floor of the static force scale relative to `|diag K| L` (module docs).
const STATIC_SCALE_FLOOR: f64 = 1e-10;

/// A kept factorisation is refreshed before a solve whose shift differs from the factorised
/// one by more than this factor, unless both shifts are below [`SHIFT_NEGLIGIBLE`] `mu_ref`.
const SHIFT_REFRESH_RATIO: f64 = 3.0;

/// Shifts (relative to `mu_ref`) below which a change of the shift leaves a kept factor a good
/// preconditioner: measured on the peer sphere, a factor at `6e-5 mu_ref` preconditions the
/// matrix at a fourfold smaller shift in 3 CG iterations, one at `1e-2` the matrix at a fourfold
/// smaller shift in 17.
const SHIFT_NEGLIGIBLE: f64 = 1e-4;

/// Whether the shift moved from `factored` to `mu` (both 1/s^2) enough to refactorise.
fn shift_moved(factored: f64, mu: f64, scale: f64) -> bool {
    let (lo, hi) = if factored < mu {
        (factored, mu)
    } else {
        (mu, factored)
    };
    hi >= SHIFT_NEGLIGIBLE * scale && hi > SHIFT_REFRESH_RATIO * lo
}

/// The linear solver of `settings`; factorized PCG without the dynamic solver's forced
/// refreshes after a slow solve (the static solver refreshes the factor itself when the shift
/// moves, and a stale solve that stalls is continued with a fresh factor anyway).
fn build_solver(settings: &SolverSettings) -> Box<dyn LinearSolver> {
    match settings.linear.kind {
        LinearSolverKind::FactorizedPcg => Box::new(FactorizedPcg::new(FactorizedPcgParams {
            cg: CgParams::from(settings.linear),
            refactor_iterations: settings.refactor_iterations,
            fresh_solves_after_slow: 0,
            parallel: settings.parallel_factorization,
            refactor_cost: settings.refactor_cost,
            ..FactorizedPcgParams::default()
        })),
        _ => settings.build(),
    }
}

/// The largest shift relative to `mu_ref` before a stage is declared stuck.
const MAX_SHIFT: f64 = 1e12;

/// Parameters of [`StaticSolver`].
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
    /// Halvings of the continuation increment before the solve gives up (default 12).
    pub max_load_halvings: usize,
    /// Inexact Newton: each linear solve is asked for a linearised residual of this fraction
    /// of the stage's tolerance (as [`crate::implicit::BackwardEulerParams::inexact_forcing`];
    /// default [`crate::implicit::DEFAULT_INEXACT_FORCING`], `0`: every solve to the linear
    /// solver's own tolerance).
    pub inexact_forcing: f64,
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
            max_load_halvings: 12,
            inexact_forcing: crate::implicit::DEFAULT_INEXACT_FORCING,
        }
    }
}

/// What a static solve did.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StaticInfo {
    /// Whether the full-load stage reached the tolerance (always `true` for a returned
    /// solve: a non-converged one is [`StaticError::NotConverged`]).
    pub converged: bool,
    /// Relative residual of the result (module docs).
    pub relative_residual: f64,
    /// Newton iterations over all load stages, failed attempts included.
    pub iterations: usize,
    /// Load stages solved: 1 when the full load converged directly, more with continuation.
    pub load_steps: usize,
    /// Continuation increments rolled back and halved.
    pub load_halvings: usize,
    /// Halvings of Newton steps by the line search, over all stages.
    pub line_search_cuts: usize,
    /// Linear solves retried with a larger shift because the shifted matrix was indefinite.
    pub regularized_solves: usize,
    /// The static energy `E` (J, up to a constant) at the first and at every accepted iterate
    /// of the last stage; non-increasing by construction.
    pub energies: Vec<f64>,
    /// Relative residual at every iterate of the last stage.
    pub relative_residuals: Vec<f64>,
    /// Final Levenberg-Marquardt shift relative to `mu_ref`.
    pub shift: f64,
    /// Numeric factorisations done by the linear solver.
    pub factorizations: usize,
    /// Linear-solver iterations over all Newton iterations (CG iterations; for Cholesky 1 +
    /// iterative-refinement steps per solve).
    #[serde(default)]
    pub linear_iterations: usize,
    /// Wall-clock time per phase over all load stages.
    #[serde(default)]
    pub times: PhaseTimes,
}

/// Errors of [`StaticSolver`].
#[derive(Debug, Error, Clone, PartialEq)]
pub enum StaticError {
    /// A parameter or array is invalid (message names it).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// The system has no potential energy, so there is nothing to minimise.
    #[error(
        "the force system has no potential energy; the static solve needs one (a gas model without a potential cannot be solved statically)"
    )]
    NoPotential,
    /// The force system failed (inverted element, non-positive gas volume, ...).
    #[error("force system error in Newton iteration {iteration}: {source}")]
    System {
        /// Newton iteration of the stage (0-based).
        iteration: usize,
        /// The system's error.
        #[source]
        source: SystemError,
    },
    /// The linear solver failed for another reason than an indefinite matrix.
    #[error("linear solver failed in Newton iteration {iteration}: {source}")]
    Linear {
        /// Newton iteration of the stage (0-based).
        iteration: usize,
        /// The solver's error.
        #[source]
        source: SolveError,
    },
    /// A position or force became NaN or infinite.
    #[error("non-finite {quantity} at dof {dof} (vertex {vertex}) in Newton iteration {iteration}")]
    NonFinite {
        /// "position" or "force".
        quantity: &'static str,
        /// Degree of freedom.
        dof: usize,
        /// Vertex `dof / 3`.
        vertex: usize,
        /// Newton iteration of the stage (0-based).
        iteration: usize,
    },
    /// Newton did not reach the tolerance, even with load continuation.
    #[error(
        "static solve did not converge: relative residual {residual:.3e} after {iterations} Newton iterations (tolerance {tolerance:e}) at load factor {load_factor}"
    )]
    NotConverged {
        /// Newton iterations done over all stages.
        iterations: usize,
        /// Relative residual of the last iterate of the failing stage.
        residual: f64,
        /// The tolerance of that stage.
        tolerance: f64,
        /// The load factor reached (1 = the full load).
        load_factor: f64,
    },
}

impl StaticError {
    /// Whether a continuation stage that failed this way may be retried with a smaller load
    /// increment (numerical failures), as opposed to bad input.
    fn is_recoverable(&self) -> bool {
        !matches!(self, Self::InvalidInput(_) | Self::NoPotential)
    }
}

/// A force system whose load can be scaled by a factor in `[0, 1]` (the gas load of the
/// shell, for example), for [`StaticSolver::solve_with_continuation`].
pub trait LoadScaling: ForceSystem {
    /// Scales the load from the next [`ForceSystem::forces`] call on (`1` = the full load).
    fn set_load_factor(&mut self, factor: f64);
}

/// The stiffness of a [`ForceSystem`] as a matrix-free operator.
struct Stiffness<'a, S>(&'a S);

impl<S: ForceSystem> StiffnessOperator for Stiffness<'_, S> {
    fn apply(&self, p: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        self.0.add_force_differential(p, out);
        out.iter_mut().for_each(|o| *o = -*o);
    }

    fn add_diagonal(&self, diagonal: &mut [f64]) -> bool {
        self.0.add_stiffness_diagonal(diagonal).is_ok()
    }
}

/// Newton + Levenberg-Marquardt + line search for static equilibria (module docs), holding the
/// linear solver and its assembled pattern across iterations and solves.
#[derive(Debug)]
pub struct StaticSolver {
    /// Parameters.
    pub params: StaticParams,
    solver: Box<dyn LinearSolver>,
    assembler: SparseAssembler,
    triplets: Vec<(usize, usize, f64)>,
    use_blocks: bool,
    f: Vec<f64>,
    f_ext: Vec<f64>,
    r: Vec<f64>,
    dx: Vec<f64>,
    trial: Vec<f64>,
    /// `mu_ref` (1/s^2), set at the first linearisation of a solve.
    shift_scale: f64,
    /// The current shift relative to `shift_scale`.
    shift: f64,
    /// The force-scale floor of this solve, N.
    scale_floor: f64,
    /// `|W| + |f_ext . x|` at the last energy evaluation, J.
    energy_magnitude: f64,
    /// Keep the shift (and its scale) of the last converged solve for the next one.
    warm_start: bool,
    /// Whether the last solve converged (its shift is then a warm start).
    last_converged: bool,
    /// Phase times of the solve under way.
    times: PhaseTimes,
    /// Linear iterations of the solve under way.
    linear_iterations: usize,
    /// The shift `mu` (1/s^2) of the matrix the linear solver last factorised.
    factor_mu: Option<f64>,
}

impl Default for StaticSolver {
    fn default() -> Self {
        Self::new(StaticParams::default())
    }
}

impl StaticSolver {
    /// A solver with `params` and the linear solver they name.
    pub fn new(params: StaticParams) -> Self {
        Self {
            params,
            solver: build_solver(&params.solver),
            assembler: SparseAssembler::new(),
            triplets: Vec::new(),
            use_blocks: false,
            f: Vec::new(),
            f_ext: Vec::new(),
            r: Vec::new(),
            dx: Vec::new(),
            trial: Vec::new(),
            shift_scale: 0.0,
            shift: 0.0,
            scale_floor: 0.0,
            energy_magnitude: 0.0,
            warm_start: false,
            last_converged: false,
            times: PhaseTimes::default(),
            linear_iterations: 0,
            factor_mu: None,
        }
    }

    /// With `true`, a solve that follows a converged one starts from that solve's final
    /// Levenberg-Marquardt shift and shift scale instead of [`StaticParams::initial_shift`]
    /// (default `false`). For a sequence of nearby problems (an outer fixed point on a
    /// parameter, a continuation path): near the solution the shift is small, and restarting
    /// it at `initial_shift` would cost the iterations it takes to fall back (fourfold per
    /// full step). A poor warm start is corrected as usual (the shift rises after line-search
    /// cuts and on indefinite matrices).
    pub fn set_warm_start(&mut self, warm_start: bool) {
        self.warm_start = warm_start;
    }

    /// Uses `solver` for the linear solves (any [`LinearSolver`], e.g. a user's own).
    pub fn with_linear_solver(mut self, solver: Box<dyn LinearSolver>) -> Self {
        self.solver = solver;
        self.factor_mu = None;
        self
    }

    /// The linear solver in use.
    pub fn linear_solver(&self) -> &dyn LinearSolver {
        self.solver.as_ref()
    }

    fn validate(&self, n: usize, x: &[f64], ext: Option<&[f64]>) -> Result<(), StaticError> {
        let p = &self.params;
        let bad = |s: String| Err(StaticError::InvalidInput(s));
        for (name, v) in [
            ("tolerance", p.tolerance),
            ("continuation_tolerance", p.continuation_tolerance),
            ("initial_shift", p.initial_shift),
            ("min_shift", p.min_shift),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!("{name} = {v:e} must be positive and finite"));
            }
        }
        if !(p.inexact_forcing.is_finite() && (0.0..=1.0).contains(&p.inexact_forcing)) {
            return bad(format!(
                "inexact_forcing = {:e} must be in [0, 1] (0: every linear solve to its own \
                 tolerance)",
                p.inexact_forcing
            ));
        }
        if !(1..=MAX_NEWTON_ITERATIONS).contains(&p.max_iterations) {
            return bad(format!(
                "max_iterations = {} must be between 1 and {MAX_NEWTON_ITERATIONS}",
                p.max_iterations
            ));
        }
        if x.len() != n {
            return bad(format!(
                "`x` has length {}, the system has {n} dofs",
                x.len()
            ));
        }
        if let Some(e) = ext {
            if e.len() != n {
                return bad(format!(
                    "`external_forces` has length {}, the system has {n} dofs",
                    e.len()
                ));
            }
            if let Some(i) = first_non_finite(e) {
                return bad(format!("external force {i} is not finite"));
            }
        }
        if let Some(i) = first_non_finite(x) {
            return bad(format!("position {i} is not finite"));
        }
        Ok(())
    }

    /// Solves for the equilibrium at the load as the system has it, from `x` (m, overwritten
    /// with the equilibrium), with `external_forces` (N per dof) added. No continuation. On error
    /// `x` is left at the last accepted iterate.
    pub fn solve<S: ForceSystem>(
        &mut self,
        system: &mut S,
        time: f64,
        x: &mut [f64],
        external_forces: Option<&[f64]>,
    ) -> Result<StaticInfo, StaticError> {
        let n = system.num_dofs();
        self.validate(n, x, external_forces)?;
        self.prepare(system, n)?;
        let mut info = StaticInfo::default();
        let before = self.solver.factorizations();
        self.set_external(n, external_forces, 1.0);
        let tol = self.params.tolerance;
        let result = self.stage(system, time, x, tol, &mut info);
        self.last_converged = result.is_ok();
        self.finish_info(before, &mut info);
        result.map(|()| {
            info.load_steps = 1;
            info
        })
    }

    /// Solves for the equilibrium at the full load (factor 1) from `x`, with load continuation
    /// when the full load does not converge directly (module docs). External forces are scaled
    /// with the load factor. On success the system's load factor is 1 and `x` the equilibrium;
    /// on error `x` is the last converged stage's shape (the given one if none converged).
    pub fn solve_with_continuation<S: LoadScaling>(
        &mut self,
        system: &mut S,
        time: f64,
        x: &mut [f64],
        external_forces: Option<&[f64]>,
    ) -> Result<StaticInfo, StaticError> {
        let n = system.num_dofs();
        self.validate(n, x, external_forces)?;
        system.set_load_factor(1.0);
        self.prepare(system, n)?;
        let before = self.solver.factorizations();
        let mut info = StaticInfo::default();
        let start = x.to_vec();
        let tol = self.params.tolerance;
        self.set_external(n, external_forces, 1.0);
        let first_shift = self.shift;
        let direct = self.stage(system, time, x, tol, &mut info);
        let outcome = match direct {
            Ok(()) => {
                info.load_steps = 1;
                Ok(())
            }
            Err(e) if !e.is_recoverable() => Err(e),
            Err(_) => {
                x.copy_from_slice(&start);
                // A warm-started shift was for a nearby problem's solution, not for the load
                // path from the start.
                self.shift = first_shift.max(self.params.initial_shift);
                self.continuation(system, time, x, external_forces, &mut info)
            }
        };
        self.last_converged = outcome.is_ok();
        self.finish_info(before, &mut info);
        outcome.map(|()| info)
    }

    /// The adaptive load increments of [`StaticSolver::solve_with_continuation`].
    fn continuation<S: LoadScaling>(
        &mut self,
        system: &mut S,
        time: f64,
        x: &mut [f64],
        external_forces: Option<&[f64]>,
        info: &mut StaticInfo,
    ) -> Result<(), StaticError> {
        let n = x.len();
        let p = self.params;
        let (mut done, mut increment) = (0.0f64, 0.5f64);
        let mut halvings = 1;
        info.load_halvings += 1;
        let mut saved = x.to_vec();
        loop {
            let target = if done + increment >= 1.0 - 1e-12 {
                1.0
            } else {
                done + increment
            };
            let tol = if target == 1.0 {
                p.tolerance
            } else {
                p.tolerance.max(p.continuation_tolerance)
            };
            system.set_load_factor(target);
            self.set_external(n, external_forces, target);
            let saved_shift = self.shift;
            match self.stage(system, time, x, tol, info) {
                Ok(()) => {
                    info.load_steps += 1;
                    if target == 1.0 {
                        return Ok(());
                    }
                    done = target;
                    saved.copy_from_slice(x);
                    increment = (2.0 * increment).min(1.0 - done);
                }
                Err(e) if !e.is_recoverable() => return Err(e),
                Err(e) => {
                    x.copy_from_slice(&saved);
                    self.shift = saved_shift;
                    halvings += 1;
                    info.load_halvings += 1;
                    if halvings > p.max_load_halvings {
                        system.set_load_factor(done);
                        return Err(match e {
                            StaticError::NotConverged {
                                residual,
                                tolerance,
                                ..
                            } => StaticError::NotConverged {
                                iterations: info.iterations,
                                residual,
                                tolerance,
                                load_factor: done,
                            },
                            other => other,
                        });
                    }
                    increment *= 0.5;
                }
            }
        }
    }

    /// Moves the counters of the solve into `info`: factorisations since `before`, linear
    /// iterations and phase times.
    fn finish_info(&mut self, before: u64, info: &mut StaticInfo) {
        info.factorizations = (self.solver.factorizations() - before) as usize;
        info.linear_iterations = std::mem::take(&mut self.linear_iterations);
        info.times = std::mem::take(&mut self.times);
    }

    /// Sizes the buffers, selects the tangent, and keeps the warm-start shift or resets it.
    fn prepare<S: ForceSystem>(&mut self, system: &mut S, n: usize) -> Result<(), StaticError> {
        system
            .set_tangent(self.params.tangent)
            .map_err(|source| StaticError::System {
                iteration: 0,
                source,
            })?;
        for buf in [
            &mut self.f,
            &mut self.f_ext,
            &mut self.r,
            &mut self.dx,
            &mut self.trial,
        ] {
            buf.resize(n, 0.0);
        }
        self.times = PhaseTimes::default();
        self.linear_iterations = 0;
        if !(self.warm_start && self.last_converged && self.shift_scale > 0.0) {
            self.shift_scale = 0.0;
            self.shift = self.params.initial_shift;
        }
        self.last_converged = false;
        Ok(())
    }

    fn set_external(&mut self, n: usize, ext: Option<&[f64]>, factor: f64) {
        for i in 0..n {
            self.f_ext[i] = ext.map_or(0.0, |e| factor * e[i]);
        }
    }

    /// `mu_ref = |diag K| / |m|` at the current linearisation (the Rayleigh quotient of `K`
    /// along the centred positions when the system gives no diagonal), and the force-scale
    /// floor `1e-10 |diag K| L`.
    fn set_scales<S: ForceSystem>(&mut self, system: &S, x: &[f64]) {
        let n = x.len();
        let mut diag = vec![0.0; n];
        let m = norm(system.masses()).max(f64::MIN_POSITIVE);
        let k = if system.add_stiffness_diagonal(&mut diag).is_ok() {
            norm(&diag)
        } else {
            // Rayleigh quotient along x - centroid, scaled like a diagonal norm.
            let mut c = [0.0; 3];
            for p in x.chunks_exact(3) {
                for d in 0..3 {
                    c[d] += p[d] / (n / 3).max(1) as f64;
                }
            }
            let probe: Vec<f64> = x
                .iter()
                .enumerate()
                .map(|(i, v)| {
                    if n.is_multiple_of(3) {
                        v - c[i % 3]
                    } else {
                        *v
                    }
                })
                .collect();
            let mut kp = vec![0.0; n];
            Stiffness(system).apply(&probe, &mut kp);
            let pp: f64 = probe.iter().map(|v| v * v).sum();
            let pkp: f64 = probe.iter().zip(&kp).map(|(a, b)| a * b).sum();
            if pp > 0.0 {
                (pkp / pp).abs() * (n as f64).sqrt()
            } else {
                0.0
            }
        };
        self.shift_scale = if k > 0.0 && k.is_finite() { k / m } else { 1.0 };
        self.scale_floor = STATIC_SCALE_FLOOR * k * extent(x);
    }

    /// One load stage: Newton from `x` to the relative residual `tol`.
    fn stage<S: ForceSystem>(
        &mut self,
        system: &mut S,
        time: f64,
        x: &mut [f64],
        tol: f64,
        info: &mut StaticInfo,
    ) -> Result<(), StaticError> {
        let n = x.len();
        let p = self.params;
        info.energies.clear();
        info.relative_residuals.clear();
        let mut res = self.evaluate(system, time, x, 0, true)?;
        if self.shift_scale == 0.0 {
            self.set_scales(system, x);
            res.scale = res.scale.max(self.scale_floor);
        }
        let mut energy = self.energy(system, time, x)?;
        info.energies.push(energy);
        info.relative_residuals.push(res.relative());
        info.relative_residual = res.relative();
        for k in 0..p.max_iterations {
            if res.relative() <= tol {
                info.converged = true;
                info.shift = self.shift;
                return Ok(());
            }
            info.iterations += 1;
            // Inexact Newton (module docs, `StaticParams::inexact_forcing`).
            self.solver
                .set_relative_tolerance(crate::implicit::forcing_tolerance(
                    p.inexact_forcing,
                    tol,
                    res.relative(),
                    p.solver.linear.relative_tolerance,
                ));
            let slope = self.direction(system, k, info)?;
            if !(slope > 0.0 && slope.is_finite()) {
                // Not a descent direction: more shift, same iterate.
                self.shift = (self.shift * 10.0).min(MAX_SHIFT);
                continue;
            }
            let mut step = 1.0;
            let mut accepted = None;
            for cut in 0..=MAX_LINE_SEARCH_CUTS {
                if cut > 0 {
                    step *= 0.5;
                    info.line_search_cuts += 1;
                }
                for i in 0..n {
                    self.trial[i] = x[i] + step * self.dx[i];
                }
                if first_non_finite(&self.trial).is_some() {
                    continue;
                }
                let trial = std::mem::take(&mut self.trial);
                let outcome = self.try_trial(system, time, &trial, (energy, slope, step), &res, k);
                self.trial = trial;
                if let Some((e1, r1)) = outcome? {
                    accepted = Some((cut, e1, r1));
                    break;
                }
            }
            match accepted {
                Some((cut, e1, r1)) => {
                    x.copy_from_slice(&self.trial);
                    energy = e1;
                    res = r1;
                    info.energies.push(energy);
                    info.relative_residuals.push(res.relative());
                    info.relative_residual = res.relative();
                    self.shift = if cut == 0 {
                        (self.shift * 0.25).max(p.min_shift)
                    } else {
                        (self.shift * 2f64.powi(cut as i32)).min(MAX_SHIFT)
                    };
                }
                None => {
                    // No acceptable step: the forces at `x` must be current for the next
                    // direction.
                    res = self.evaluate(system, time, x, k + 1, false)?;
                    if self.shift >= MAX_SHIFT {
                        break;
                    }
                    self.shift = (self.shift * 100.0).min(MAX_SHIFT);
                }
            }
        }
        if res.relative() <= tol {
            info.converged = true;
            info.shift = self.shift;
            return Ok(());
        }
        info.shift = self.shift;
        Err(StaticError::NotConverged {
            iterations: info.iterations,
            residual: res.relative(),
            tolerance: tol,
            load_factor: 1.0,
        })
    }

    /// One line-search trial at `trial`: the accepted energy and residual, or `None` to cut.
    /// On acceptance the system's last force evaluation is at `trial`.
    fn try_trial<S: ForceSystem>(
        &mut self,
        system: &mut S,
        time: f64,
        trial: &[f64],
        (e0, slope, step): (f64, f64, f64),
        current: &Residual,
        iteration: usize,
    ) -> Result<Option<(f64, Residual)>, StaticError> {
        let e1 = match self.energy(system, time, trial) {
            Ok(e) if e.is_finite() => e,
            Err(StaticError::NoPotential) => return Err(StaticError::NoPotential),
            _ => return Ok(None),
        };
        if e1 <= e0 - ARMIJO * step * slope {
            return match self.evaluate(system, time, trial, iteration + 1, false) {
                Ok(r) => Ok(Some((e1, r))),
                // A state with an energy but no forces (should not happen): cut.
                Err(_) => Ok(None),
            };
        }
        if e1 <= e0 + ENERGY_ROUNDOFF * self.energy_magnitude {
            return Ok(
                match self.evaluate(system, time, trial, iteration + 1, false) {
                    Ok(r) if r.norm < current.norm => Some((e1, r)),
                    _ => None,
                },
            );
        }
        Ok(None)
    }

    /// Forces at `x` into `self.f`, the residual `r = f + f_ext` into `self.r`, and its norm
    /// with the force scale. Without `linearize` (line-search trials, which Newton may stop at)
    /// the system may leave its stiffness for [`ForceSystem::refresh_stiffness`], which
    /// [`StaticSolver::direction`] calls.
    fn evaluate<S: ForceSystem>(
        &mut self,
        system: &mut S,
        time: f64,
        x: &[f64],
        iteration: usize,
        linearize: bool,
    ) -> Result<Residual, StaticError> {
        let started = Instant::now();
        let evaluated = if linearize {
            system.forces(time, x, &mut self.f)
        } else {
            system.residual_forces(time, x, &mut self.f)
        };
        self.times.forces_ms += ms_since(started);
        evaluated.map_err(|source| StaticError::System { iteration, source })?;
        if let Some(dof) = first_non_finite(&self.f) {
            return Err(StaticError::NonFinite {
                quantity: "force",
                dof,
                vertex: dof / 3,
                iteration,
            });
        }
        for i in 0..x.len() {
            self.r[i] = self.f[i] + self.f_ext[i];
        }
        let internal = system.force_scale().unwrap_or_else(|| norm(&self.f));
        Ok(Residual {
            norm: norm(&self.r),
            scale: (internal + norm(&self.f_ext)).max(self.scale_floor),
            dt: 1.0,
        })
    }

    /// The static energy `W(x) - f_ext . x`.
    fn energy<S: ForceSystem>(
        &mut self,
        system: &mut S,
        time: f64,
        x: &[f64],
    ) -> Result<f64, StaticError> {
        let started = Instant::now();
        let w = system.potential_energy(time, x);
        self.times.energy_ms += ms_since(started);
        let w = w
            .map_err(|source| StaticError::System {
                iteration: 0,
                source,
            })?
            .ok_or(StaticError::NoPotential)?;
        let ext: f64 = self.f_ext.iter().zip(x).map(|(f, x)| f * x).sum();
        self.energy_magnitude = w.abs() + ext.abs();
        Ok(w - ext)
    }

    /// Solves `(K + mu M) dx = r` into `self.dx`, raising the shift while the matrix is
    /// indefinite; returns the slope `r . dx`.
    fn direction<S: ForceSystem>(
        &mut self,
        system: &mut S,
        k: usize,
        info: &mut StaticInfo,
    ) -> Result<f64, StaticError> {
        let started = Instant::now();
        let refreshed = system.refresh_stiffness();
        self.times.forces_ms += ms_since(started);
        refreshed.map_err(|source| StaticError::System {
            iteration: k,
            source,
        })?;
        if self.solver.needs_assembled_matrix() {
            let started = Instant::now();
            let collected = crate::system::collect_stiffness(system, &mut self.triplets);
            self.times.assembly_ms += ms_since(started);
            self.use_blocks = collected.map_err(|source| StaticError::System {
                iteration: k,
                source,
            })?;
        }
        let mut retries = 0;
        loop {
            let mu = self.shift * self.shift_scale;
            match self.linear_solve(system, mu) {
                Ok(solved) => {
                    self.linear_iterations += solved.iterations;
                    break;
                }
                Err(err) if err.is_indefinite() && retries < MAX_REGULARIZATION_RETRIES => {
                    retries += 1;
                    info.regularized_solves += 1;
                    self.shift = (self.shift * 10.0).min(MAX_SHIFT);
                }
                Err(source) => {
                    return Err(StaticError::Linear {
                        iteration: k,
                        source,
                    });
                }
            }
        }
        Ok(self.r.iter().zip(&self.dx).map(|(a, b)| a * b).sum())
    }

    fn linear_solve<S: ForceSystem>(
        &mut self,
        system: &S,
        mu: f64,
    ) -> Result<SolveInfo, SolveError> {
        let masses = system.masses();
        let low_rank = system.low_rank_terms();
        self.dx.fill(0.0);
        let factor_before = self.solver.factorization_seconds();
        let factorizations = self.solver.factorizations();
        if self
            .factor_mu
            .is_some_and(|fm| shift_moved(fm, mu, self.shift_scale))
        {
            self.solver.invalidate_factorization();
        }
        let started = Instant::now();
        let result = if self.solver.needs_assembled_matrix() {
            match (self.use_blocks, system.stiffness_blocks()) {
                (true, Some(b)) => {
                    self.assembler
                        .assemble_blocks(masses, mu, &b, &self.triplets, 1.0)?
                }
                _ => self.assembler.assemble(masses, mu, &self.triplets, 1.0)?,
            };
            self.times.assembly_ms += ms_since(started);
            let started = Instant::now();
            let problem = LinearProblem::assembled(
                self.assembler.matrix(),
                self.assembler.pattern_version(),
                mu,
                1.0,
                low_rank,
            );
            let solved = self.solver.solve(&problem, &self.r, &mut self.dx);
            (solved, ms_since(started))
        } else {
            let stiffness = Stiffness(system);
            let problem = LinearProblem::matrix_free(mu, 1.0, masses, &stiffness, low_rank);
            let solved = self.solver.solve(&problem, &self.r, &mut self.dx);
            (solved, ms_since(started))
        };
        if self.solver.factorizations() != factorizations {
            self.factor_mu = Some(mu);
        }
        let factor_ms = (self.solver.factorization_seconds() - factor_before) * 1e3;
        self.times.factorization_ms += factor_ms;
        self.times.solve_ms += (result.1 - factor_ms).max(0.0);
        result.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A free chain of nonlinear springs in 3D (no anchor: six rigid modes), pulled at its ends
    /// by external forces `pull` (scaled by the continuation).
    #[derive(Debug, Clone)]
    struct Chain {
        masses: Vec<f64>,
        springs: Vec<(usize, usize, f64, f64)>,
        x: Vec<f64>,
        pull: Vec<f64>,
        /// The load factor last set (the system itself has no load of its own).
        factor: f64,
    }

    impl Chain {
        fn new(nv: usize) -> Self {
            let mut springs = Vec::new();
            for i in 0..nv - 1 {
                springs.push((i, i + 1, 50.0 + i as f64, 0.1));
                if i + 2 < nv {
                    springs.push((i, i + 2, 20.0, 0.2));
                }
            }
            // Opposite pulls on the ends (no resultant), a force beyond the spring's linear range.
            let mut pull = vec![0.0; 3 * nv];
            pull[0] = -30.0;
            pull[1] = 4.0;
            pull[3 * (nv - 1)] = 30.0;
            pull[3 * (nv - 1) + 1] = -4.0;
            Self {
                masses: vec![0.01; 3 * nv],
                springs,
                x: vec![0.0; 3 * nv],
                pull,
                factor: 1.0,
            }
        }
        fn positions(nv: usize) -> Vec<f64> {
            (0..3 * nv)
                .map(|i| match i % 3 {
                    0 => 0.1 * (i / 3) as f64,
                    1 => 0.003 * ((i * 7) % 5) as f64,
                    _ => 0.002 * ((i * 3) % 4) as f64,
                })
                .collect()
        }
        fn block(&self, i: usize, j: usize, k: f64, l0: f64) -> [[f64; 3]; 3] {
            let d: Vec<f64> = (0..3)
                .map(|c| self.x[3 * i + c] - self.x[3 * j + c])
                .collect();
            let l = norm(&d);
            let mut b = [[0.0; 3]; 3];
            for r in 0..3 {
                for c in 0..3 {
                    let nn = d[r] * d[c] / (l * l);
                    let id = if r == c { 1.0 } else { 0.0 };
                    b[r][c] = k * (nn + (id - nn) * (1.0 - l0 / l));
                }
            }
            b
        }
    }

    impl ForceSystem for Chain {
        fn num_dofs(&self) -> usize {
            self.masses.len()
        }
        fn masses(&self) -> &[f64] {
            &self.masses
        }
        fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
            self.x.copy_from_slice(x);
            f.fill(0.0);
            for &(i, j, k, l0) in &self.springs {
                let d: Vec<f64> = (0..3).map(|c| x[3 * i + c] - x[3 * j + c]).collect();
                let l = norm(&d);
                for c in 0..3 {
                    let fi = -k * (l - l0) * d[c] / l;
                    f[3 * i + c] += fi;
                    f[3 * j + c] -= fi;
                }
            }
            Ok(())
        }
        fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
            let mut t = Vec::new();
            self.add_stiffness_triplets(&mut t).unwrap();
            for (r, c, v) in t {
                df[r] -= v * dx[c];
            }
        }
        fn add_stiffness_triplets(
            &self,
            t: &mut Vec<(usize, usize, f64)>,
        ) -> Result<(), SystemError> {
            for &(i, j, k, l0) in &self.springs {
                let b = self.block(i, j, k, l0);
                for r in 0..3 {
                    for c in 0..3 {
                        t.push((3 * i + r, 3 * i + c, b[r][c]));
                        t.push((3 * j + r, 3 * j + c, b[r][c]));
                        t.push((3 * i + r, 3 * j + c, -b[r][c]));
                        t.push((3 * j + r, 3 * i + c, -b[r][c]));
                    }
                }
            }
            Ok(())
        }
        fn potential_energy(&mut self, _t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
            let mut e = 0.0;
            for &(i, j, k, l0) in &self.springs {
                let d: Vec<f64> = (0..3).map(|c| x[3 * i + c] - x[3 * j + c]).collect();
                e += 0.5 * k * (norm(&d) - l0).powi(2);
            }
            Ok(Some(e))
        }
    }

    impl LoadScaling for Chain {
        fn set_load_factor(&mut self, factor: f64) {
            self.factor = factor;
        }
    }

    fn check_equilibrium(sys: &mut Chain, x: &[f64]) {
        let mut f = vec![0.0; x.len()];
        sys.forces(0.0, x, &mut f).unwrap();
        let r: Vec<f64> = f.iter().zip(&sys.pull).map(|(f, p)| f + p).collect();
        assert!(
            norm(&r) < 1e-5 * norm(&sys.pull),
            "residual force {}",
            norm(&r)
        );
    }

    #[test]
    fn free_chain_reaches_equilibrium_with_every_solver_and_decreasing_energy() {
        let nv = 8;
        for kind in [
            LinearSolverKind::Cholesky,
            LinearSolverKind::MatrixFreeCg,
            LinearSolverKind::Pcg,
        ] {
            let mut params = StaticParams::default();
            params.solver.linear.kind = kind;
            params.solver.linear.relative_tolerance = 1e-10;
            params.tolerance = 1e-9;
            let mut solver = StaticSolver::new(params);
            let mut sys = Chain::new(nv);
            let mut x = Chain::positions(nv);
            let pull = sys.pull.clone();
            let info = solver.solve(&mut sys, 0.0, &mut x, Some(&pull)).unwrap();
            assert!(
                info.converged && info.relative_residual <= 1e-9,
                "{kind}: {info:?}"
            );
            assert!(info.energies.len() >= 2);
            for w in info.energies.windows(2) {
                assert!(
                    w[1] <= w[0] + 1e-13 * w[0].abs(),
                    "{kind}: {:?}",
                    info.energies
                );
            }
            check_equilibrium(&mut sys, &x);
            // A rigid body: the chain is stretched (the pulls exceed the linear range).
            let span = x[3 * (nv - 1)] - x[0];
            assert!(span > 0.75, "{kind}: span {span}");
        }
    }

    /// Any cloneable system made lazy: `residual_forces` evaluates a copy, leaving the
    /// linearisation at the earlier point until `refresh_stiffness`; a stale stiffness query
    /// panics.
    struct Lazy<S> {
        inner: S,
        pending: Option<(f64, Vec<f64>)>,
        trials: usize,
    }

    impl<S: ForceSystem + Clone> ForceSystem for Lazy<S> {
        fn num_dofs(&self) -> usize {
            self.inner.num_dofs()
        }
        fn masses(&self) -> &[f64] {
            self.inner.masses()
        }
        fn forces(&mut self, t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
            self.pending = None;
            self.inner.forces(t, x, f)
        }
        fn residual_forces(&mut self, t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
            self.inner.clone().forces(t, x, f)?;
            self.pending = Some((t, x.to_vec()));
            self.trials += 1;
            Ok(())
        }
        fn refresh_stiffness(&mut self) -> Result<(), SystemError> {
            if let Some((t, x)) = self.pending.take() {
                let mut f = vec![0.0; x.len()];
                self.inner.forces(t, &x, &mut f)?;
            }
            Ok(())
        }
        fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
            assert!(self.pending.is_none(), "stale differential");
            self.inner.add_force_differential(dx, df);
        }
        fn add_stiffness_triplets(
            &self,
            t: &mut Vec<(usize, usize, f64)>,
        ) -> Result<(), SystemError> {
            assert!(self.pending.is_none(), "stale stiffness");
            self.inner.add_stiffness_triplets(t)
        }
        fn add_stiffness_diagonal(&self, d: &mut [f64]) -> Result<(), SystemError> {
            assert!(self.pending.is_none(), "stale diagonal");
            self.inner.add_stiffness_diagonal(d)
        }
        fn low_rank_terms(&self) -> &[crate::LowRankTerm] {
            assert!(self.pending.is_none(), "stale low-rank terms");
            self.inner.low_rank_terms()
        }
        fn potential_energy(&mut self, t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
            self.inner.potential_energy(t, x)
        }
    }

    #[test]
    fn trials_may_skip_the_stiffness_and_the_solve_is_unchanged() {
        let nv = 8;
        for kind in [
            LinearSolverKind::Cholesky,
            LinearSolverKind::FactorizedPcg,
            LinearSolverKind::MatrixFreeCg,
            LinearSolverKind::Pcg,
        ] {
            let mut params = StaticParams::default();
            params.solver.linear.kind = kind;
            params.solver.linear.relative_tolerance = 1e-10;
            params.tolerance = 1e-9;
            let pull = Chain::new(nv).pull.clone();
            let mut eager = Chain::new(nv);
            let mut xe = Chain::positions(nv);
            let ie = StaticSolver::new(params)
                .solve(&mut eager, 0.0, &mut xe, Some(&pull))
                .unwrap();
            let mut lazy = Lazy {
                inner: Chain::new(nv),
                pending: None,
                trials: 0,
            };
            let mut xl = Chain::positions(nv);
            let il = StaticSolver::new(params)
                .solve(&mut lazy, 0.0, &mut xl, Some(&pull))
                .unwrap();
            assert!(
                il.converged && lazy.trials >= il.iterations,
                "{kind}: {il:?}"
            );
            assert_eq!(il.iterations, ie.iterations, "{kind}");
            assert!(
                xl.iter().zip(&xe).all(|(a, b)| a.to_bits() == b.to_bits()),
                "{kind}: the lazy solve differs"
            );
        }
    }

    #[test]
    fn continuation_reaches_the_full_load_when_the_direct_solve_cannot() {
        let nv = 8;
        // Too few iterations per stage for the full load from the rest shape.
        let params = StaticParams {
            max_iterations: 4,
            tolerance: 1e-8,
            continuation_tolerance: 1e-2,
            ..Default::default()
        };
        let mut sys = Chain::new(nv);
        for p in sys.pull.iter_mut() {
            *p *= 3.0;
        }
        let mut x = Chain::positions(nv);
        let pull = sys.pull.clone();
        let e = StaticSolver::new(params)
            .solve(&mut sys, 0.0, &mut x.clone(), Some(&pull))
            .unwrap_err();
        assert!(matches!(e, StaticError::NotConverged { .. }), "{e}");
        let info = StaticSolver::new(params)
            .solve_with_continuation(&mut sys, 0.0, &mut x, Some(&pull))
            .unwrap();
        assert!(info.load_steps > 1, "{info:?}");
        assert!(info.relative_residual <= 1e-8);
        assert_eq!(sys.factor, 1.0);
        check_equilibrium(&mut sys, &x);
    }

    #[test]
    fn bad_input_and_missing_potential_are_typed_errors() {
        struct NoPotential([f64; 3]);
        impl ForceSystem for NoPotential {
            fn num_dofs(&self) -> usize {
                3
            }
            fn masses(&self) -> &[f64] {
                &self.0
            }
            fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
                f.iter_mut().zip(x).for_each(|(f, x)| *f = 1.0 - x);
                Ok(())
            }
            fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
                df.iter_mut().zip(dx).for_each(|(df, dx)| *df -= dx);
            }
        }
        let mut solver = StaticSolver::default();
        let e = solver
            .solve(&mut NoPotential([1.0; 3]), 0.0, &mut [0.0; 3], None)
            .unwrap_err();
        assert_eq!(e, StaticError::NoPotential);
        let e = solver
            .solve(&mut NoPotential([1.0; 3]), 0.0, &mut [0.0; 2], None)
            .unwrap_err();
        assert!(e.to_string().contains("`x`"), "{e}");
        solver.params.tolerance = 0.0;
        let e = solver
            .solve(&mut NoPotential([1.0; 3]), 0.0, &mut [0.0; 3], None)
            .unwrap_err();
        assert!(e.to_string().contains("tolerance"), "{e}");
    }
}
