//! Load continuation of the static solve: the full load first, then adaptive load increments
//! when it does not converge directly (module docs of [`crate::statics`]).

use super::{LoadScaling, StaticError, StaticInfo, StaticSolver};
use crate::newton::Stall;

impl StaticSolver {
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
        self.last_iterations = 0;
        let n = system.num_dofs();
        Self::check_inputs(n, x, external_forces)?;
        system.set_load_factor(1.0);
        self.prepare(system, n, time)?;
        let before = self.core.matrix.solver.factorizations();
        let mut info = StaticInfo::default();
        let start = x.to_vec();
        let tol = self.params().tolerance;
        self.set_external(n, external_forces, 1.0);
        let first_shift = self.shift();
        let direct = self.stage(system, x, tol, &mut info);
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
                self.set_shift(first_shift.max(self.params().initial_shift));
                self.continuation(system, x, external_forces, &mut info)
            }
        };
        self.last_converged = outcome.is_ok();
        self.finish_info(before, &mut info);
        outcome.map(|()| info)
    }

    /// The adaptive load increments of [`StaticSolver::solve_with_continuation`]: an increment
    /// that converges (to [`super::StaticParams::continuation_tolerance`]) lets the next one
    /// double, one that fails is rolled back and halved, at most
    /// [`super::StaticParams::max_load_halvings`] times.
    fn continuation<S: LoadScaling>(
        &mut self,
        system: &mut S,
        x: &mut [f64],
        external_forces: Option<&[f64]>,
        info: &mut StaticInfo,
    ) -> Result<(), StaticError> {
        let n = x.len();
        let p = *self.params();
        let (mut done, mut increment) = (0.0f64, 0.5f64);
        let mut halvings = 1;
        let mut stalls = 0;
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
            let saved_shift = self.shift();
            match self.stage(system, x, tol, info) {
                Ok(()) => {
                    info.load_steps += 1;
                    if target == 1.0 {
                        return Ok(());
                    }
                    done = target;
                    stalls = 0;
                    saved.copy_from_slice(x);
                    increment = (2.0 * increment).min(1.0 - done);
                }
                Err(e) if !e.is_recoverable() => return Err(e),
                Err(e) => {
                    stalls = if self.last_stalled { stalls + 1 } else { 0 };
                    if p.max_stalled_stages > 0 && stalls >= p.max_stalled_stages {
                        // Smaller increments did not help: stop with the evidence, at the
                        // last converged load factor.
                        let (vertex, position, share) = self.residual_concentration(x);
                        let residual = info.relative_residual;
                        self.stalled_iterate = x.to_vec();
                        x.copy_from_slice(&saved);
                        system.set_load_factor(done);
                        return Err(StaticError::NoEquilibrium(Box::new(Stall {
                            iterations: info.iterations,
                            residual,
                            load_factor: done,
                            stalled_stages: stalls,
                            vertex,
                            position,
                            share,
                            smallest_eigenvalue: None,
                            relative_eigenvalue: None,
                        })));
                    }
                    x.copy_from_slice(&saved);
                    self.set_shift(saved_shift);
                    halvings += 1;
                    info.load_halvings += 1;
                    if halvings > p.max_load_halvings {
                        system.set_load_factor(done);
                        // Whatever stopped the last increment (no step, a shift that could not
                        // make the matrix definite), the solve ends where the load path ends:
                        // at the last converged load factor, with the residual it reached.
                        let (residual, tolerance) = match e {
                            StaticError::NotConverged {
                                residual,
                                tolerance,
                                ..
                            } => (residual, tolerance),
                            _ => (info.relative_residual, tol),
                        };
                        return Err(StaticError::NotConverged {
                            iterations: info.iterations,
                            residual,
                            tolerance,
                            load_factor: Some(done),
                        });
                    }
                    increment *= 0.5;
                }
            }
        }
    }
}
