//! [`StaticSolver`]: one load stage of a static solve, Newton from the core of
//! [`crate::newton`] with the Levenberg-Marquardt shift, on the static energy.

use balloon_linalg::{
    CgParams, FactorizedPcg, FactorizedPcgParams, LinearSolver, LinearSolverKind, SolverSettings,
    StiffnessOperator,
};

use super::{StaticError, StaticInfo, StaticParams};
use crate::newton::convergence::{extent, first_non_finite, norm};
use crate::newton::{NewtonCore, NewtonRecord, Regularization, Settings, SystemStiffness};
use crate::system::ForceSystem;
use crate::timing::PhaseTimes;

/// Floor of the static force scale relative to `|diag K| L` (module docs).
const STATIC_SCALE_FLOOR: f64 = 1e-10;

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

/// Newton + Levenberg-Marquardt + line search for static equilibria (module docs), holding the
/// linear solver and its assembled pattern across iterations and solves.
#[derive(Debug)]
pub struct StaticSolver {
    /// Parameters, validated.
    params: StaticParams,
    /// The Newton core: objective, Newton matrix, linear solver, phase times.
    pub(super) core: NewtonCore,
    /// The Levenberg-Marquardt shift and its scale `mu_ref` (0 until the first linearisation
    /// of a solve sets it).
    pub(super) regularization: Regularization,
    /// Keep the shift (and its scale) of the last converged solve for the next one.
    warm_start: bool,
    /// Whether the last solve converged (its shift is then a warm start).
    pub(super) last_converged: bool,
    /// Linear iterations of the solve under way.
    linear_iterations: usize,
    /// Newton iterations of the last solve, converged or not.
    pub(super) last_iterations: usize,
    /// Whether the last load stage stopped as stalled ([`StaticParams::stall_window`]).
    pub(super) last_stalled: bool,
    /// The last iterate of the stalled stage that ended the last solve with
    /// [`StaticError::NoEquilibrium`] (empty otherwise).
    pub(super) stalled_iterate: Vec<f64>,
}

impl Default for StaticSolver {
    fn default() -> Self {
        Self::new(StaticParams::default()).expect("the default parameters are valid")
    }
}

impl StaticSolver {
    /// A solver with `params` (checked first, [`StaticParams::validate`]) and the linear
    /// solver they name.
    pub fn new(params: StaticParams) -> Result<Self, StaticError> {
        params.validate()?;
        let mut core = NewtonCore::new(build_solver(&params.solver));
        core.objective.inertia = None;
        Ok(Self {
            params,
            core,
            regularization: Regularization::LevenbergMarquardt {
                shift: 0.0,
                scale: 0.0,
                min: params.min_shift,
            },
            warm_start: false,
            last_converged: false,
            linear_iterations: 0,
            last_iterations: 0,
            last_stalled: false,
            stalled_iterate: Vec::new(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &StaticParams {
        &self.params
    }

    /// Replaces the parameters from the next solve on, after checking them (on error nothing
    /// changes). The linear solver stays the one made at construction (or plugged in).
    pub fn set_params(&mut self, params: StaticParams) -> Result<(), StaticError> {
        params.validate()?;
        self.params = params;
        if let Regularization::LevenbergMarquardt { min, .. } = &mut self.regularization {
            *min = params.min_shift;
        }
        Ok(())
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
        self.core.matrix.set_solver(solver);
        self
    }

    /// The linear solver in use.
    pub fn linear_solver(&self) -> &dyn LinearSolver {
        self.core.matrix.solver.as_ref()
    }

    /// Checks the inputs of a solve: one entry per degree of freedom, all finite.
    pub(super) fn check_inputs(
        n: usize,
        x: &[f64],
        ext: Option<&[f64]>,
    ) -> Result<(), StaticError> {
        let arrays = [("x", Some(x)), ("external_forces", ext)];
        for (what, a) in arrays {
            let Some(a) = a else { continue };
            if a.len() != n {
                return Err(StaticError::LengthMismatch {
                    what,
                    len: a.len(),
                    expected: n,
                });
            }
            if let Some(dof) = first_non_finite(a) {
                return Err(StaticError::NonFiniteInput {
                    what,
                    dof,
                    vertex: dof / 3,
                });
            }
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
        self.last_iterations = 0;
        let n = system.num_dofs();
        Self::check_inputs(n, x, external_forces)?;
        self.prepare(system, n, time)?;
        let mut info = StaticInfo::default();
        let before = self.core.matrix.solver.factorizations();
        self.set_external(n, external_forces, 1.0);
        let tol = self.params.tolerance;
        let result = self.stage(system, x, tol, &mut info);
        self.last_converged = result.is_ok();
        self.finish_info(before, &mut info);
        result.map(|()| {
            info.load_steps = 1;
            info
        })
    }

    /// Newton iterations of the last [`StaticSolver::solve`] or
    /// [`StaticSolver::solve_with_continuation`], whether it converged or failed (a failed
    /// solve's error may count only some of them: an interrupted one counts its last stage's).
    pub fn last_iterations(&self) -> usize {
        self.last_iterations
    }

    /// The last iterate of the stalled load stage when the last solve ended with
    /// [`StaticError::NoEquilibrium`] (`None` otherwise): where to look at the stiffness
    /// ([`StaticSolver::stability`]) for the evidence of a wrinkling or buckling wall.
    pub fn stalled_iterate(&self) -> Option<&[f64]> {
        (!self.stalled_iterate.is_empty()).then_some(self.stalled_iterate.as_slice())
    }

    /// Moves the counters of the solve into `info`: factorisations since `before`, linear
    /// iterations and phase times.
    pub(super) fn finish_info(&mut self, before: u64, info: &mut StaticInfo) {
        self.last_iterations = info.iterations;
        info.factorizations = (self.core.matrix.solver.factorizations() - before) as usize;
        info.linear_iterations = std::mem::take(&mut self.linear_iterations);
        info.times = std::mem::take(&mut self.core.times);
    }

    /// Sizes the buffers, selects the tangent, and keeps the warm-start shift or resets it.
    pub(super) fn prepare<S: ForceSystem>(
        &mut self,
        system: &mut S,
        n: usize,
        time: f64,
    ) -> Result<(), StaticError> {
        system
            .set_tangent(self.params.tangent)
            .map_err(|source| StaticError::System {
                iteration: 0,
                source,
            })?;
        self.core.resize(n);
        self.core.objective.time = time;
        self.core.times = PhaseTimes::default();
        self.linear_iterations = 0;
        self.stalled_iterate.clear();
        let initial = self.params.initial_shift;
        if let Regularization::LevenbergMarquardt { shift, scale, .. } = &mut self.regularization
            && !(self.warm_start && self.last_converged && *scale > 0.0)
        {
            *scale = 0.0;
            *shift = initial;
        }
        self.last_converged = false;
        Ok(())
    }

    /// The external forces of the stage: `factor` times `ext`.
    pub(super) fn set_external(&mut self, n: usize, ext: Option<&[f64]>, factor: f64) {
        for i in 0..n {
            self.core.objective.f_ext[i] = ext.map_or(0.0, |e| factor * e[i]);
        }
    }

    /// The current shift relative to `mu_ref`.
    pub(super) fn shift(&self) -> f64 {
        self.regularization.current()
    }

    /// Sets the current shift relative to `mu_ref`.
    pub(super) fn set_shift(&mut self, value: f64) {
        if let Regularization::LevenbergMarquardt { shift, .. } = &mut self.regularization {
            *shift = value;
        }
    }

    /// `mu_ref = |diag K| / |m|` at the current linearisation ([`stiffness_norm`]) and the
    /// force-scale floor `1e-10 |diag K| L`.
    fn set_scales<S: ForceSystem>(&mut self, system: &S, x: &[f64]) {
        let k = stiffness_norm(system, x);
        if let Regularization::LevenbergMarquardt { scale, .. } = &mut self.regularization {
            *scale = stiffness_scale(system, k);
        }
        self.core.objective.scale_floor = STATIC_SCALE_FLOOR * k * extent(x);
    }

    /// One load stage: Newton from `x` to the relative residual `tol`.
    pub(super) fn stage<S: ForceSystem>(
        &mut self,
        system: &mut S,
        x: &mut [f64],
        tol: f64,
        info: &mut StaticInfo,
    ) -> Result<(), StaticError> {
        let p = self.params;
        info.energies.clear();
        info.relative_residuals.clear();
        let (mut res, _) = self.core.evaluate(system, x, 0, true, false)?;
        if matches!(
            self.regularization,
            Regularization::LevenbergMarquardt { scale, .. } if scale == 0.0
        ) {
            self.set_scales(system, x);
            res.scale = res.scale.max(self.core.objective.scale_floor);
        }
        let energy = self
            .core
            .energy(system, x)?
            .ok_or(StaticError::NoPotential)?;
        let window = match p.stall_window {
            0 => p.max_iterations,
            w => w.min(p.max_iterations),
        };
        let mut settings = Settings {
            tolerance: tol,
            max_iterations: window,
            min_accepted: 0,
            inexact_forcing: p.inexact_forcing,
            linear_tolerance: p.solver.linear.relative_tolerance,
            stall_test: false,
            fixed_steps: false,
            accept_unconverged: false,
            remove_rigid_motions: p.remove_rigid_motions,
        };
        self.last_stalled = false;
        // Newton in windows of `stall_window` iterations (the same iterates as one call: the
        // core's state between calls is `x`, its residual and energy, and the shift), so that
        // a stage whose best residual did not halve over a window can be stopped.
        let mut record = NewtonRecord::default();
        let mut start = (res, Some(energy));
        let mut best_before = res.relative();
        let mut done = 0;
        let outcome = loop {
            settings.max_iterations = window.min(p.max_iterations - done);
            let mut chunk = NewtonRecord::default();
            let outcome = self.core.minimize(
                system,
                x,
                start,
                &settings,
                &mut self.regularization,
                false,
                &mut chunk,
            );
            done += chunk.iterations;
            let continued = !record.relative_residuals.is_empty();
            merge(&mut record, chunk, continued);
            let Ok(outcome) = outcome else {
                break outcome;
            };
            if outcome.converged || done >= p.max_iterations {
                break Ok(outcome);
            }
            let best = record
                .relative_residuals
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min);
            if p.stall_window > 0 && best > 0.5 * best_before {
                self.last_stalled = true;
                break Ok(outcome);
            }
            best_before = best;
            let energy = record.energies.last().copied();
            start = (outcome.residual, energy);
        };
        info.iterations += record.iterations;
        info.line_search_cuts += record.line_search_cuts;
        info.regularized_solves += record.regularized_solves;
        self.linear_iterations += record.linear_iterations.iter().sum::<usize>();
        info.relative_residual = record.relative_residuals.last().copied().unwrap_or(0.0);
        info.energies = record.energies;
        info.relative_residuals = record.relative_residuals;
        info.shift = self.shift();
        let outcome = outcome?;
        info.relative_residual = outcome.residual.relative();
        if outcome.converged {
            info.converged = true;
            return Ok(());
        }
        Err(StaticError::NotConverged {
            iterations: info.iterations,
            residual: outcome.residual.relative(),
            tolerance: tol,
            load_factor: Some(1.0),
        })
    }

    /// Where the residual of the last evaluation concentrates: the vertex with the largest
    /// residual force, its position in `x`, and the share of `|r|^2` on the 5 % of vertices
    /// with the largest residual force.
    pub(super) fn residual_concentration(&self, x: &[f64]) -> (usize, [f64; 3], f64) {
        let r = &self.core.objective.rhs;
        let mut per: Vec<(f64, usize)> = r
            .chunks_exact(3)
            .enumerate()
            .map(|(v, c)| (c.iter().map(|a| a * a).sum::<f64>(), v))
            .collect();
        let total: f64 = per.iter().map(|p| p.0).sum();
        per.sort_by(|a, b| b.0.total_cmp(&a.0));
        let Some(&(_, vertex)) = per.first() else {
            return (0, [0.0; 3], 0.0);
        };
        let top = per.len().div_ceil(20);
        let share = if total > 0.0 {
            per[..top].iter().map(|p| p.0).sum::<f64>() / total
        } else {
            0.0
        };
        let position = [x[3 * vertex], x[3 * vertex + 1], x[3 * vertex + 2]];
        (vertex, position, share)
    }
}

/// Appends the record of a later window of Newton iterations to `total` (`continued`: its
/// first iterate is `total`'s last, already recorded).
fn merge(total: &mut NewtonRecord, chunk: NewtonRecord, continued: bool) {
    let skip = usize::from(continued);
    total.iterations += chunk.iterations;
    total.linear_iterations.extend(chunk.linear_iterations);
    total.linear_residuals.extend(chunk.linear_residuals);
    total
        .residual_norms
        .extend(chunk.residual_norms.into_iter().skip(skip));
    total
        .relative_residuals
        .extend(chunk.relative_residuals.into_iter().skip(skip));
    total.energies.extend(chunk.energies.into_iter().skip(skip));
    total.line_search_cuts += chunk.line_search_cuts;
    total.regularized_solves += chunk.regularized_solves;
    total.max_regularization = total.max_regularization.max(chunk.max_regularization);
    total.linear_converged = if continued {
        total.linear_converged && chunk.linear_converged
    } else {
        chunk.linear_converged
    };
}

/// `mu_ref = k / |m|` for the stiffness norm `k` ([`stiffness_norm`]), 1/s^2; 1 when that is
/// not positive and finite.
pub(super) fn stiffness_scale<S: ForceSystem + ?Sized>(system: &S, k: f64) -> f64 {
    let m = norm(system.masses()).max(f64::MIN_POSITIVE);
    if k > 0.0 && k.is_finite() { k / m } else { 1.0 }
}

/// `|diag K|` of `system` at its current linearisation (the Rayleigh quotient of `K` along the
/// centred positions `x`, scaled like a diagonal norm, when the system gives no diagonal), N/m.
pub(super) fn stiffness_norm<S: ForceSystem + ?Sized>(system: &S, x: &[f64]) -> f64 {
    let n = x.len();
    let mut diag = vec![0.0; n];
    if system.add_stiffness_diagonal(&mut diag).is_ok() {
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
        SystemStiffness(system).apply(&probe, &mut kp);
        let pp: f64 = probe.iter().map(|v| v * v).sum();
        let pkp: f64 = probe.iter().zip(&kp).map(|(a, b)| a * b).sum();
        if pp > 0.0 {
            (pkp / pp).abs() * (n as f64).sqrt()
        } else {
            0.0
        }
    }
}
