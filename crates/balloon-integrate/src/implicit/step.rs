//! [`BackwardEuler`]: one backward Euler step (Wang et al. 2015, Eq. 18-23) as the
//! minimisation of its incremental potential by the Newton core ([`crate::newton`]), with the
//! reuse of the last step's Newton matrix (module docs of [`crate::implicit`]).

use std::path::Path;

use balloon_linalg::sprs::CsMat;
use balloon_linalg::{LinearSolver, Preconditioner, SolveError, SolverSettings};

use super::reuse::TangentReuse;
use super::{BackwardEulerParams, IntegrateError, StepInfo, check_time_step};
use crate::newton::convergence::{extent, first_non_finite, norm};
use crate::newton::{NewtonCore, NewtonRecord, Regularization, Residual, Settings};
use crate::system::ForceSystem;
use crate::timing::PhaseTimes;

/// The floor of the force scale relative to `|m| L / dt^2` (module docs of
/// [`crate::implicit`]).
const SCALE_FLOOR: f64 = 1e-3;

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
/// let mut be = BackwardEuler::new(BackwardEulerParams::default())?
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
    /// Parameters, validated ([`BackwardEuler::set_params`]).
    params: BackwardEulerParams,
    /// The Newton core: objective, Newton matrix, linear solver, phase times.
    core: NewtonCore,
    /// The settings the configured solver was built from; `None` for a solver plugged in by
    /// the user.
    solver_settings: Option<SolverSettings>,
    /// The mass-shift memory across iterations and steps.
    regularization: Regularization,
    /// When the next step's first iteration may reuse the Newton matrix.
    reuse: TangentReuse,
}

impl Default for BackwardEuler {
    fn default() -> Self {
        Self::new(BackwardEulerParams::default()).expect("the default parameters are valid")
    }
}

impl BackwardEuler {
    /// A new integrator with `params`, which are checked first
    /// ([`BackwardEulerParams::validate`]).
    pub fn new(params: BackwardEulerParams) -> Result<Self, IntegrateError> {
        params.validate()?;
        let settings = params.solver_settings();
        Ok(Self {
            params,
            core: NewtonCore::new(settings.build()),
            solver_settings: Some(settings),
            regularization: Regularization::RetryShift {
                enabled: params.regularize_indefinite,
                last: 0.0,
            },
            reuse: TangentReuse::default(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &BackwardEulerParams {
        &self.params
    }

    /// Replaces the parameters from the next step on, after checking them
    /// ([`BackwardEulerParams::validate`]; on error nothing changes). A change of the
    /// linear-solver settings makes a new solver of the configured kind at the next step,
    /// unless a solver was plugged in with [`BackwardEuler::with_linear_solver`].
    pub fn set_params(&mut self, params: BackwardEulerParams) -> Result<(), IntegrateError> {
        params.validate()?;
        self.params = params;
        if let Regularization::RetryShift { enabled, .. } = &mut self.regularization {
            *enabled = params.regularize_indefinite;
        }
        Ok(())
    }

    /// Forgets what the last step leaves for the next: the offer to reuse its Newton matrix
    /// in the next step's first iteration and the mass shift it needed. For a state set from
    /// outside (a simulation restored to an earlier state), where neither belongs to the
    /// state the next step starts from. The parameters and the linear solver are kept.
    pub fn forget_last_step(&mut self) {
        self.reuse = TangentReuse::default();
        if let Regularization::RetryShift { last, .. } = &mut self.regularization {
            *last = 0.0;
        }
    }

    /// Wall-clock time per phase (forces, energies, assembly, factorisations, solves) summed
    /// over every step this integrator took, including steps that failed: the difference of
    /// two readings is the time of what happened in between (a step retried at half the size
    /// counts both attempts). [`StepInfo::times`] is one successful step's share.
    pub fn phase_times(&self) -> PhaseTimes {
        self.core.times
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
        self.core.matrix.set_solver(solver);
        self.solver_settings = None;
    }

    /// Goes back to the solver [`BackwardEulerParams::linear`] names (built at the next step).
    pub fn use_configured_linear_solver(&mut self) {
        let settings = self.params.solver_settings();
        self.core.matrix.set_solver(settings.build());
        self.solver_settings = Some(settings);
    }

    /// The linear solver in use.
    pub fn linear_solver(&self) -> &dyn LinearSolver {
        self.core.matrix.solver.as_ref()
    }

    /// The sparse part of the Newton matrix of the last linear solve,
    /// `A = m_coef M + k_coef K_sparse` (Eq. 23, with `m_coef = 1 + dt alpha` plus any
    /// regularisation shift, `k_coef = dt^2 + dt beta`), as a `sprs` matrix; the dense low-rank
    /// terms of `K` ([`ForceSystem::low_rank_terms`]) are not included. `None` when the last
    /// solve was matrix-free (nothing was assembled), before the first step, or when the
    /// system split its stiffness for the solver ([`ForceSystem::set_stiffness_split`]: the
    /// matrix then only preconditions; a direct solver gets the whole matrix).
    pub fn newton_matrix(&self) -> Option<CsMat<f64>> {
        self.core.matrix.matrix()
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
                self.core.matrix.set_solver(settings.build());
                self.solver_settings = Some(settings);
            }
        }
    }

    /// How many times the sparse pattern (and with it the symbolic Cholesky factorisation) has
    /// been built; stays at 1 across Newton iterations and steps while the pattern is unchanged.
    pub fn sparse_pattern_builds(&self) -> u64 {
        self.core.matrix.pattern_builds()
    }

    /// Whether the last matrix-free CG solve used the stiffness diagonal
    /// ([`ForceSystem::add_stiffness_diagonal`]) in its Jacobi preconditioner.
    pub fn stiffness_preconditioned(&self) -> bool {
        self.core.matrix.last_preconditioner == Preconditioner::DiagonalJacobi
    }

    /// Checks the inputs of one step: the time step, one entry per degree of freedom in every
    /// array, positive masses.
    fn check_inputs(
        n: usize,
        dt: f64,
        x: &[f64],
        v: &[f64],
        masses: &[f64],
        ext: Option<&[f64]>,
    ) -> Result<(), IntegrateError> {
        check_time_step(dt)?;
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

    /// The residual at the first iterate `v` (the stiffness too, unless the first direction
    /// reuses the last step's matrix: `chord`) and, with `wants_energy`, the incremental
    /// potential there.
    fn first_iterate<S: ForceSystem>(
        &mut self,
        system: &mut S,
        v: &[f64],
        chord: bool,
        wants_energy: bool,
    ) -> Result<(Residual, Option<f64>), IntegrateError> {
        let (res, mut energy) = if wants_energy && chord && self.core.fuses_energy(system) {
            self.core.evaluate(system, v, 0, false, true)?
        } else {
            (self.core.evaluate(system, v, 0, !chord, false)?.0, None)
        };
        if wants_energy && energy.is_none() {
            energy = self.core.energy(system, v)?;
        }
        Ok((res, energy))
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
        Self::check_inputs(n, dt, x, v, system.masses(), external_forces)?;
        let p = self.params;
        system
            .set_tangent(p.tangent)
            .map_err(|source| IntegrateError::System {
                iteration: 0,
                source,
            })?;
        let beta = p.stiffness_damping;
        self.core.resize(n);
        {
            let objective = &mut self.core.objective;
            let mut inertia = objective.inertia.take().unwrap_or_default();
            inertia.x_n.clear();
            inertia.x_n.extend_from_slice(x);
            inertia.v_n.clear();
            inertia.v_n.extend_from_slice(v);
            inertia.dt = dt;
            inertia.alpha = p.mass_damping;
            inertia.beta = beta;
            objective.inertia = Some(inertia);
            objective.time = time + dt;
            let m = system.masses();
            for i in 0..n {
                objective.f_ext[i] =
                    m[i] * p.gravity[i % 3] + external_forces.map_or(0.0, |e| e[i]);
            }
            objective.scale_floor = SCALE_FLOOR * norm(system.masses()) * extent(x) / (dt * dt);
        }
        let (m_coef, k_coef) = self.core.objective.coefficients();
        let paper_mode = p.newton_tolerance == 0.0;
        self.refresh_solver();
        let factorizations_before = self.core.matrix.solver.factorizations();
        let times_before = self.core.times;
        // Whether the first Newton iteration reuses the last step's matrix (a chord step).
        let chord = self.reuse.first_iteration_may_reuse(
            &p,
            (m_coef, k_coef),
            self.core.matrix.solver.needs_assembled_matrix() && self.core.matrix.assembled_last,
        );

        // The first iterate, v_(0) = v^n, or v_(0) = 0 where the system cannot be evaluated at
        // the predictor (module docs, "First iterate").
        let wants_energy = !paper_mode && beta == 0.0;
        let mut started_at_rest = false;
        let (res, energy) = match self.first_iterate(system, v, chord, wants_energy) {
            Err(IntegrateError::System { .. }) if v.iter().any(|&a| a != 0.0) => {
                v.fill(0.0);
                started_at_rest = true;
                self.first_iterate(system, v, chord, wants_energy)?
            }
            first => first?,
        };
        let settings = Settings {
            tolerance: p.newton_tolerance,
            max_iterations: p.newton_iterations,
            min_accepted: 1,
            inexact_forcing: p.inexact_forcing,
            linear_tolerance: p.linear.relative_tolerance,
            stall_test: !paper_mode && !p.accept_unconverged,
            fixed_steps: paper_mode,
            accept_unconverged: p.accept_unconverged,
            remove_rigid_motions: false,
        };
        let mut record = NewtonRecord::default();
        let outcome = self.core.minimize(
            system,
            v,
            (res, energy),
            &settings,
            &mut self.regularization,
            chord,
            &mut record,
        );
        let last = self.core.objective.inertia.as_ref().expect("set above");
        for i in 0..n {
            x[i] = last.x_n[i] + dt * v[i];
        }
        let outcome = outcome?;
        if let Some(dof) = first_non_finite(x) {
            return Err(IntegrateError::NonFinite {
                quantity: "position",
                dof,
                vertex: dof / 3,
                iteration: record.iterations,
            });
        }
        let relative_residual = outcome.residual.relative();
        if !paper_mode && !outcome.converged && !p.accept_unconverged {
            return Err(IntegrateError::NotConverged {
                iterations: record.iterations,
                residual: relative_residual,
                tolerance: p.newton_tolerance,
                load_factor: None,
            });
        }
        let info = StepInfo {
            newton_iterations: record.iterations,
            linear_iterations: record.linear_iterations,
            linear_residuals: record.linear_residuals,
            newton_residuals: record.residual_norms,
            relative_residuals: record.relative_residuals,
            relative_residual,
            line_search_cuts: record.line_search_cuts,
            energies: record.energies,
            converged: if paper_mode {
                record.linear_converged
            } else {
                outcome.converged
            },
            regularized_solves: record.regularized_solves,
            max_regularization: record.max_regularization,
            factorizations: (self.core.matrix.solver.factorizations() - factorizations_before)
                as usize,
            times: self.core.times - times_before,
            reused_tangent: outcome.chord_taken,
            started_at_rest,
        };
        self.reuse.after_step(
            outcome.last_solve_reused,
            self.core.matrix.assembled_last && self.regularization.current() == 0.0,
            info.newton_iterations,
            (m_coef, k_coef),
        );
        Ok(info)
    }
}
