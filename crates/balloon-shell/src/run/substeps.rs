//! The sub-step driver of a running shell: [`ShellSubsteps`], the shell as
//! [`AdaptiveSubsteps`] drives it (save and restore the state, one sub-step, when a sub-step
//! was easy, which failures are retried), and the step's advance through it.

use balloon_gas::GasModel;
use balloon_integrate::implicit::{IntegrateError, StepInfo};
use balloon_integrate::substep::{Attempt, EASY_NEWTON_ITERATIONS, Substepper};

#[cfg(doc)]
use balloon_integrate::substep::{AdaptiveSubsteps, SubstepGrowth};

use super::stats::StepTotals;
use super::{ShellError, ShellSimulation};
use crate::ShellMaterial;

/// One shell simulation as the sub-step controller drives it (`step`: the step number for
/// the errors).
pub(crate) struct ShellSubsteps<'a, M: ShellMaterial, G: GasModel> {
    sim: &'a mut ShellSimulation<M, G>,
    step: usize,
}

impl<M: ShellMaterial, G: GasModel> Substepper for ShellSubsteps<'_, M, G> {
    /// Positions, velocities, thickness, the enclosed gas volume (so a rolled-back step
    /// reports the volume of the state it is back at, not the failed attempt's) and the
    /// second-order integrator's history.
    type State = (Vec<f64>, Vec<f64>, Vec<f64>, f64, super::History);
    type Info = (StepInfo, usize);
    type Error = ShellError;

    fn save(&self) -> Self::State {
        (
            self.sim.x.clone(),
            self.sim.v.clone(),
            self.sim.system.thickness.clone(),
            self.sim.gas_volume,
            self.sim.history.clone(),
        )
    }

    fn restore(&mut self, (x, v, thickness, gas_volume, history): Self::State) {
        (self.sim.x, self.sim.v, self.sim.system.thickness) = (x, v, thickness);
        self.sim.gas_volume = gas_volume;
        self.sim.history = history;
    }

    fn substep(&mut self, time: f64, dt: f64) -> Result<Self::Info, ShellError> {
        self.sim.x_prev.copy_from_slice(&self.sim.x);
        self.sim.step_inner(self.step, time, dt)
    }

    fn is_easy((info, _): &Self::Info) -> bool {
        info.newton_iterations <= EASY_NEWTON_ITERATIONS && info.line_search_cuts == 0
    }

    /// A physical runaway of the gas volume is not retried, nor a solve stopped by a request
    /// ([`balloon_integrate::newton::set_cancel_check`]).
    fn may_retry(error: &ShellError) -> bool {
        !matches!(
            error,
            ShellError::RunawayVolume { .. }
                | ShellError::Integrate {
                    source: IntegrateError::Interrupted { .. },
                    ..
                }
        )
    }
}

impl<M: ShellMaterial, G: GasModel> ShellSimulation<M, G> {
    /// Advances from `time` by `dt` in sub-steps that add up to `dt` exactly (so the step ends at
    /// the time the user asked for). A sub-step that fails numerically (Newton does not converge,
    /// the linear solver breaks down, a non-finite state, an element or thickness that degenerates
    /// in the projection) is rolled back and retried at half the size, at most `max_step_halvings`
    /// halvings below `dt` (the remedy of Diziol, Bender and Bayer 2011, Sec. 4, applied to the
    /// shell); after easy sub-steps (Newton converged in at most [`EASY_NEWTON_ITERATIONS`]
    /// iterations without line-search cuts) the size doubles again, up to `dt`, as
    /// [`SubstepGrowth`] says when. The size reached is where the next step starts. A physical
    /// runaway of the gas volume is not retried.
    pub(crate) fn advance(
        &mut self,
        step: usize,
        time: f64,
        dt: f64,
        totals: &mut StepTotals,
    ) -> Result<(), ShellError> {
        let mut substeps = self.substeps;
        let max_halvings = substeps.max_halvings();
        let advanced = substeps.advance(
            &mut ShellSubsteps { sim: self, step },
            time,
            dt,
            |attempt| match attempt {
                Attempt::Accepted {
                    info: (info, proj_iters),
                    ..
                } => {
                    totals.newton_iterations += info.newton_iterations;
                    totals.linear_iterations += info.total_linear_iterations();
                    totals.factorizations += info.factorizations;
                    totals.newton_residual = totals.newton_residual.max(info.relative_residual);
                    totals.line_search_cuts += info.line_search_cuts;
                    totals.regularized_solves += info.regularized_solves;
                    totals.projection_iterations += proj_iters;
                }
                Attempt::Failed {
                    error:
                        ShellError::Integrate {
                            source: IntegrateError::NotConverged { iterations, .. },
                            ..
                        },
                    ..
                } => totals.newton_iterations += iterations,
                Attempt::Failed { .. } => {}
            },
        );
        self.substeps = substeps;
        match advanced {
            Ok(report) => {
                totals.substeps = report.substeps;
                totals.halvings = report.halvings;
                totals.min_dt = report.min_dt;
                Ok(())
            }
            Err(failure) => Err(Self::explain(
                failure.error,
                failure.halvings,
                max_halvings,
                failure.dt,
            )),
        }
    }

    /// A Newton solve that still does not converge at the smallest sub-step becomes
    /// [`ShellError::NotConverged`] (with what to try); other errors pass unchanged.
    fn explain(e: ShellError, halvings: usize, max_halvings: usize, dt: f64) -> ShellError {
        match e {
            ShellError::Integrate {
                step,
                time,
                source:
                    IntegrateError::NotConverged {
                        iterations,
                        residual,
                        tolerance,
                        ..
                    },
            } => ShellError::NotConverged {
                step,
                time,
                dt,
                halvings,
                max_halvings,
                iterations,
                residual,
                tolerance,
            },
            other => other,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use balloon_gas::Gas;
    use balloon_material::StVenantKirchhoff;

    /// A rolled-back sub-step leaves the simulation as it was, its enclosed gas volume included
    /// (the volume is what `gas_volume()` reports after a failed step).
    #[test]
    fn a_rolled_back_substep_restores_the_gas_volume_with_the_positions() {
        let (system, x, integrator) = super::super::tests::parts();
        let mut sim =
            ShellSimulation::new(system, x.clone(), 950.0, integrator, None, 0.01, 10).unwrap();
        let v0 = sim.gas_volume();
        let mut stepper = ShellSubsteps {
            sim: &mut sim,
            step: 1,
        };
        let start = stepper.save();
        stepper.substep(0.0, 0.01).unwrap();
        let moved = stepper.sim.gas_volume();
        assert!(
            (moved / v0 - 1.0).abs() > 1e-9,
            "the sub-step moved the shell"
        );
        stepper.restore(start);
        assert_eq!(sim.gas_volume(), v0);
        assert_eq!(sim.positions(), &x[..]);
    }

    /// A state whose surface turned inside out (negative enclosed volume) is a numerical
    /// divergence that the sub-step controller retries at a smaller size; a volume grown beyond
    /// the runaway factor is the physical runaway, which it does not retry. (The dragged run of
    /// the viewer's `connect`, three fixed Newton iterations, once ended on a negative gas
    /// volume reported as a runaway.)
    #[test]
    fn an_inverted_surface_is_retried_and_a_runaway_is_not() {
        let (system, x, integrator) = super::super::tests::parts();
        let mut sim =
            ShellSimulation::new(system, x.clone(), 950.0, integrator, None, 0.01, 10).unwrap();
        // Point reflection: the same surface with every triangle's orientation reversed.
        sim.x = x.iter().map(|v| -v).collect();
        let e = sim.check_state(3, 0.02).unwrap_err();
        assert!(
            matches!(&e, ShellError::Diverged { quantity, .. } if quantity == "gas volume"),
            "{e}"
        );
        let msg = e.to_string();
        assert!(
            msg.contains("step 3") && msg.contains("inside out"),
            "{msg}"
        );
        assert!(ShellSubsteps::<'_, StVenantKirchhoff, Gas>::may_retry(&e));
        // Thirty times the size: 27000 times the volume, beyond the runaway factor.
        sim.x = x.iter().map(|v| 30.0 * v).collect();
        let e = sim.check_state(3, 0.02).unwrap_err();
        assert!(matches!(e, ShellError::RunawayVolume { .. }), "{e}");
        assert!(!ShellSubsteps::<'_, StVenantKirchhoff, Gas>::may_retry(&e));
        // The state itself passes.
        sim.x = x;
        assert!(sim.check_state(3, 0.02).is_ok());
    }
}
