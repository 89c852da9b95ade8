//! The one Newton core of the crate, used by the backward Euler step
//! ([`crate::implicit::BackwardEuler`]) and by the static solve
//! ([`crate::statics::StaticSolver`]).
//!
//! Both minimise a potential over the unknowns `u` of a [`ForceSystem`]: the incremental
//! potential of a backward Euler step (`u` the end-of-step velocities, Wang et al. 2015,
//! Eq. 18-23) or the static energy `W(x) - f_ext . x` (`u = x`). Each iteration
//!
//! 1. tests convergence ([`convergence`]: the residual force relative to a force scale),
//! 2. linearises the system and solves `(m_coef M + k_coef K) du = r` with the configured
//!    linear solver ([`crate::linear::LinearSolver`]; inexact Newton: the solve is asked only
//!    for the accuracy the residual needs), regularised by a mass shift where the matrix is
//!    indefinite ([`regularization`]),
//! 3. searches along `du` ([`line_search`]: Armijo on the potential, or on the residual norm),
//!
//! and records what it did ([`NewtonRecord`]). A new globalisation, regularisation or
//! convergence test is written here once and serves both solvers.

mod cancel;
pub mod convergence;
mod error;
pub mod line_search;
mod linear;
mod objective;
pub mod regularization;
pub(crate) mod rigid;

pub use cancel::{cancel_requested, set_cancel_check, without_cancel};
pub use convergence::{MAX_NEWTON_ITERATIONS, NEWTON_STALL_WINDOW, Residual};
pub(crate) use error::check_parameter;
pub use error::{NewtonError, Stall};
pub(crate) use linear::{NewtonMatrix, SystemStiffness};
pub(crate) use objective::Objective;
pub(crate) use regularization::{NoStep, Regularization};

use balloon_linalg::{LinearSolver, SolveInfo};
use serde::{Deserialize, Serialize};

use crate::system::ForceSystem;
use crate::timing::PhaseTimes;
use convergence::{first_non_finite, forcing_tolerance, stalled};
use line_search::{Current, LineSearch, MAX_LINE_SEARCH_CUTS};
use regularization::MAX_REGULARIZATION_RETRIES;

/// How one Newton solve iterates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Settings {
    /// Relative residual at which the solve stops.
    pub(crate) tolerance: f64,
    /// Most iterations.
    pub(crate) max_iterations: usize,
    /// Accepted steps needed before the convergence test may stop the solve.
    pub(crate) min_accepted: usize,
    /// Inexact Newton: each linear solve is asked for this fraction of `tolerance`.
    pub(crate) inexact_forcing: f64,
    /// The linear solver's own relative tolerance (the tightest an inexact solve asks for).
    pub(crate) linear_tolerance: f64,
    /// Stop as not converged when the residual stalls ([`NEWTON_STALL_WINDOW`]).
    pub(crate) stall_test: bool,
    /// The paper's mode: `max_iterations` full Newton steps, no line search, no residual test.
    pub(crate) fixed_steps: bool,
    /// Stop at the last accepted iterate, without an error, when the line search finds no
    /// acceptable step and the regularisation would fail the solve.
    pub(crate) accept_unconverged: bool,
    /// Remove the rigid motions (about the current `u` read as points) from every direction,
    /// `M`-orthogonally: a free body in a static solve, whose residual has no component along
    /// them, so the slope `r . du` and the line search are unchanged.
    pub(crate) remove_rigid_motions: bool,
}

/// What one Newton solve did, iteration by iteration.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct NewtonRecord {
    /// Newton iterations (directions computed, retries from the same iterate included).
    pub iterations: usize,
    /// Linear-solver iterations per direction.
    pub linear_iterations: Vec<usize>,
    /// Final relative residual of each linear solve.
    pub linear_residuals: Vec<f64>,
    /// `|r|` at each iterate evaluated.
    pub residual_norms: Vec<f64>,
    /// Relative residual at each iterate evaluated.
    pub relative_residuals: Vec<f64>,
    /// The objective at the first and at every accepted iterate (with a potential).
    pub energies: Vec<f64>,
    /// Halvings of Newton steps by the line search.
    pub line_search_cuts: usize,
    /// Linear solves retried with a larger shift because the matrix was indefinite.
    pub regularized_solves: usize,
    /// Largest mass shift used (relative to the mass matrix).
    pub max_regularization: f64,
    /// Whether every linear solve met its tolerance.
    pub linear_converged: bool,
}

impl NewtonRecord {
    fn push_iterate(&mut self, residual: &Residual) {
        self.residual_norms.push(residual.norm);
        self.relative_residuals.push(residual.relative());
    }
}

/// How a Newton solve ended without an error.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Outcome {
    /// The residual test passed (always `false` in the paper's mode).
    pub(crate) converged: bool,
    /// The residual at the result.
    pub(crate) residual: Residual,
    /// A chord step (the reused matrix) was taken.
    pub(crate) chord_taken: bool,
    /// The last linear solve used the reused matrix.
    pub(crate) last_solve_reused: bool,
}

/// The state of the Newton core, reused across solves: the objective and its buffers, the
/// Newton matrix and its linear solver, the phase times.
#[derive(Debug)]
pub(crate) struct NewtonCore {
    pub(crate) objective: Objective,
    pub(crate) matrix: NewtonMatrix,
    /// Running total of the time per phase.
    pub(crate) times: PhaseTimes,
    /// The Newton direction `du`.
    direction: Vec<f64>,
    /// The unknowns of a line-search trial.
    trial: Vec<f64>,
    /// The rigid motions removed from a free body's directions (`Settings::remove_rigid_motions`).
    rigid: Vec<Vec<f64>>,
}

impl NewtonCore {
    /// A core solving with `solver`.
    pub(crate) fn new(solver: Box<dyn LinearSolver>) -> Self {
        Self {
            objective: Objective::default(),
            matrix: NewtonMatrix::new(solver),
            times: PhaseTimes::default(),
            direction: Vec::new(),
            trial: Vec::new(),
            rigid: Vec::new(),
        }
    }

    /// Sizes the buffers for `n` unknowns.
    pub(crate) fn resize(&mut self, n: usize) {
        self.objective.resize(n);
        self.direction.resize(n, 0.0);
        self.trial.resize(n, 0.0);
    }

    /// Evaluates the residual (and with `with_energy`, from the same pass, the objective) at
    /// `u`.
    pub(crate) fn evaluate<S: ForceSystem + ?Sized>(
        &mut self,
        system: &mut S,
        u: &[f64],
        iteration: usize,
        linearize: bool,
        with_energy: bool,
    ) -> Result<(Residual, Option<f64>), NewtonError> {
        self.objective.evaluate(
            system,
            u,
            iteration,
            linearize,
            with_energy,
            &mut self.times,
        )
    }

    /// The objective at `u` (`None` without a potential).
    pub(crate) fn energy<S: ForceSystem + ?Sized>(
        &mut self,
        system: &mut S,
        u: &[f64],
    ) -> Result<Option<f64>, NewtonError> {
        self.objective.energy(system, u, &mut self.times)
    }

    /// Newton from `u` (overwritten with the result), whose residual and objective `start`
    /// the caller evaluated (the system's last force evaluation is at `u`). `chord`: the first
    /// direction is solved with the matrix already assembled (a chord step; module docs of
    /// [`crate::implicit`], "Reused tangent"). Returns how the solve ended; a solve that cannot
    /// go on (no acceptable step under [`Regularization::RetryShift`], a stall) is
    /// [`NewtonError::NotConverged`]. On error `u` is the last accepted iterate.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn minimize<S: ForceSystem + ?Sized>(
        &mut self,
        system: &mut S,
        u: &mut [f64],
        start: (Residual, Option<f64>),
        settings: &Settings,
        regularization: &mut Regularization,
        mut chord: bool,
        record: &mut NewtonRecord,
    ) -> Result<Outcome, NewtonError> {
        let n = u.len();
        let (m_coef, k_coef) = self.objective.coefficients();
        let damped = self.objective.stiffness_damped();
        let (mut res, mut energy) = start;
        if let Some(e) = energy {
            record.energies.push(e);
        }
        record.push_iterate(&res);
        record.linear_converged = true;
        let mut converged = false;
        let mut accepted_steps = 0;
        let mut last_solve_reused = false;
        let mut chord_taken = false;
        for k in 0..settings.max_iterations {
            if res.norm == 0.0
                || (!settings.fixed_steps
                    && accepted_steps >= settings.min_accepted
                    && res.relative() <= settings.tolerance)
            {
                converged = true;
                break;
            }
            if cancel_requested() {
                return Err(NewtonError::Interrupted { iteration: k });
            }
            record.iterations += 1;
            if !settings.fixed_steps {
                self.matrix.solver.set_relative_tolerance(forcing_tolerance(
                    settings.inexact_forcing,
                    settings.tolerance,
                    res.relative(),
                    settings.linear_tolerance,
                ));
            }
            let lin = if chord {
                match self.reused_direction(system, m_coef, k_coef, regularization) {
                    Ok(lin) => lin,
                    Err(_) => {
                        // The reused matrix does not give a direction: a fresh one from here
                        // (the stiffness at this iterate is still to be computed).
                        chord = false;
                        self.direction(system, m_coef, k_coef, k, regularization, record)?
                    }
                }
            } else {
                self.direction(system, m_coef, k_coef, k, regularization, record)?
            };
            last_solve_reused = chord;
            if settings.remove_rigid_motions && n.is_multiple_of(3) {
                rigid::rigid_basis_into(system.masses(), u, &mut self.rigid);
                rigid::m_orthogonalize(system.masses(), &self.rigid, &mut self.direction);
            }
            record.linear_iterations.push(lin.iterations);
            record.linear_residuals.push(lin.relative_residual);
            if settings.fixed_steps {
                record.linear_converged &= lin.converged;
                for i in 0..n {
                    u[i] += self.direction[i];
                }
                if let Some(dof) = first_non_finite(u) {
                    return Err(NewtonError::NonFinite {
                        quantity: "velocity",
                        dof,
                        vertex: dof / 3,
                        iteration: k,
                    });
                }
                if k + 1 < settings.max_iterations {
                    res = self.evaluate(system, u, k + 1, true, false)?.0;
                    record.push_iterate(&res);
                }
                continue;
            }
            // Line search along du. `slope = r . du` is minus the directional derivative of
            // the objective along du.
            let slope: f64 = self
                .objective
                .rhs
                .iter()
                .zip(&self.direction)
                .map(|(r, d)| r * d)
                .sum();
            let descent = slope > 0.0 && slope.is_finite();
            let mode = if energy.is_some() && descent {
                LineSearch::Energy
            } else if energy.is_some() && regularization.not_descent() {
                // Not a descent direction: more shift, same iterate.
                continue;
            } else if damped || energy.is_some() {
                LineSearch::Residual
            } else {
                LineSearch::Off
            };
            let current = Current {
                energy,
                slope,
                residual: res,
            };
            let mut step = 1.0;
            let mut accepted = None;
            // A chord step is taken whole or not at all.
            let max_cuts = if chord { 0 } else { MAX_LINE_SEARCH_CUTS };
            for cut in 0..=max_cuts {
                if cut > 0 {
                    step *= 0.5;
                    record.line_search_cuts += 1;
                }
                let mut trial = std::mem::take(&mut self.trial);
                for i in 0..n {
                    trial[i] = u[i] + step * self.direction[i];
                }
                let outcome = self.try_step(
                    system,
                    mode,
                    &trial,
                    &current,
                    step,
                    k + 1,
                    !chord && cut == MAX_LINE_SEARCH_CUTS,
                );
                self.trial = trial;
                if let Some((e1, r)) = outcome? {
                    accepted = Some((cut, e1, r));
                    break;
                }
            }
            let Some((cuts, e1, r)) = accepted else {
                if chord {
                    // The line search would cut the chord step: go on from the same iterate
                    // with its own tangent (the next iteration), as if the matrix had not been
                    // reused.
                    chord = false;
                    last_solve_reused = false;
                    res = self.evaluate(system, u, k, true, false)?.0;
                    continue;
                }
                match regularization.no_step() {
                    NoStep::Fail if settings.accept_unconverged => {
                        // The forces at `u` must be current for the caller.
                        res = self.evaluate(system, u, k + 1, false, false)?.0;
                        break;
                    }
                    NoStep::Fail => {
                        return Err(NewtonError::NotConverged {
                            iterations: record.iterations,
                            residual: res.relative(),
                            tolerance: settings.tolerance,
                            load_factor: None,
                        });
                    }
                    NoStep::Stop => {
                        // The forces at `u` must be current for the caller.
                        res = self.evaluate(system, u, k + 1, false, false)?.0;
                        break;
                    }
                    NoStep::Retry => {
                        // The forces at `u` must be current for the next direction.
                        res = self.evaluate(system, u, k + 1, false, false)?.0;
                        continue;
                    }
                }
            };
            u.copy_from_slice(&self.trial);
            res = r;
            energy = match (e1, energy) {
                (Some(e1), _) => Some(e1),
                // A residual-searched step of a system with a potential: keep the objective
                // current for the next iteration.
                (None, Some(_)) => self.energy(system, u)?,
                (None, None) => None,
            };
            if let Some(e) = energy {
                record.energies.push(e);
            }
            regularization.accepted(cuts);
            accepted_steps += 1;
            chord_taken |= chord;
            chord = false;
            record.push_iterate(&res);
            if settings.stall_test && stalled(&record.relative_residuals, settings.tolerance) {
                return Err(NewtonError::NotConverged {
                    iterations: record.iterations,
                    residual: res.relative(),
                    tolerance: settings.tolerance,
                    load_factor: None,
                });
            }
        }
        // The paper's mode does not evaluate its result.
        if !settings.fixed_steps && !converged && res.relative() <= settings.tolerance {
            converged = true;
        }
        Ok(Outcome {
            converged: converged && !settings.fixed_steps,
            residual: res,
            chord_taken,
            last_solve_reused,
        })
    }

    /// Solves for the Newton direction at the current iterate (into `self.direction`),
    /// linearising the system first and retrying an indefinite matrix with a mass shift as
    /// `regularization` says.
    #[allow(clippy::too_many_arguments)]
    fn direction<S: ForceSystem + ?Sized>(
        &mut self,
        system: &mut S,
        m_coef: f64,
        k_coef: f64,
        k: usize,
        regularization: &mut Regularization,
        record: &mut NewtonRecord,
    ) -> Result<SolveInfo, NewtonError> {
        self.matrix.linearize(system, k, &mut self.times)?;
        self.matrix
            .solver
            .set_shift_retries(regularization.retries_with_mass(m_coef));
        let mut shift = regularization.first_shift(k, m_coef);
        let mut retries = 0;
        loop {
            let m = m_coef + shift;
            if self
                .matrix
                .factored_mass_coefficient
                .is_some_and(|factored| regularization.refactor(factored, m))
            {
                self.matrix.solver.invalidate_factorization();
            }
            let solved = self.matrix.solve(
                &*system,
                m,
                k_coef,
                &self.objective.rhs,
                &mut self.direction,
                false,
                &mut self.times,
            );
            match solved {
                Ok(lin) => {
                    regularization.solved(shift);
                    record.max_regularization = record.max_regularization.max(shift);
                    return Ok(lin);
                }
                Err(err) if err.is_indefinite() && retries < MAX_REGULARIZATION_RETRIES => {
                    match regularization.after_indefinite(shift, m_coef, &err, system.masses()) {
                        Some(next) => shift = next,
                        None => {
                            return Err(NewtonError::Linear {
                                iteration: k,
                                source: err,
                            });
                        }
                    }
                    retries += 1;
                    record.regularized_solves += 1;
                    record.max_regularization = record.max_regularization.max(shift);
                }
                Err(source) => {
                    return Err(NewtonError::Linear {
                        iteration: k,
                        source,
                    });
                }
            }
        }
    }

    /// Solves for the direction of a chord step: with the matrix still in the assembler (the
    /// last step's, `(m_coef, k_coef)` checked by the caller) and the low-rank terms kept with
    /// it, without the stiffness at the current iterate.
    fn reused_direction<S: ForceSystem + ?Sized>(
        &mut self,
        system: &S,
        m_coef: f64,
        k_coef: f64,
        regularization: &mut Regularization,
    ) -> Result<SolveInfo, balloon_linalg::SolveError> {
        let solved = self.matrix.solve(
            system,
            m_coef,
            k_coef,
            &self.objective.rhs,
            &mut self.direction,
            true,
            &mut self.times,
        );
        if solved.is_ok() {
            regularization.solved(0.0);
        }
        solved
    }
}
