//! One step of a running shell (Algorithm 1 of Wang et al. 2015, lines 5-12): advanced in
//! sub-steps (`substeps.rs`), then the time, the gas's end of step and the statistics.

use balloon_gas::GasModel;

use super::stats::StepTotals;
use super::{ShellError, ShellSimulation, ShellStepStats};
use crate::ShellMaterial;

impl<M: ShellMaterial, G: GasModel> ShellSimulation<M, G> {
    /// Advances one time step (Algorithm 1, lines 5-12). On error the state is rolled back to the
    /// start of the step, so what was written before stays consistent.
    pub fn step(&mut self) -> Result<ShellStepStats, ShellError> {
        let start = std::time::Instant::now();
        // Steps are numbered from 1 (the first step is step 1), in the stats and the errors.
        let (step, time, dt) = (self.step + 1, self.time, self.dt);
        let volume_old = self.system.gas.state().volume;
        let mut totals = StepTotals::default();
        let mut times = self.integrator.phase_times();
        times.projection_ms = self.projection_ms;
        self.advance(step, time, dt, &mut totals)?;
        let mut now = self.integrator.phase_times();
        now.projection_ms = self.projection_ms;
        let times = now - times;
        self.time = time + dt;
        // A gas with a history (a leak, a supply pump) keeps the amount the step reached.
        let end_volume = self.gas_volume;
        self.system.gas.gas_mut().end_step(end_volume, self.time);
        self.step += 1;
        let gas = self.system.gas.state();
        let max_speed = self
            .v
            .chunks_exact(3)
            .map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt())
            .fold(0.0, f64::max);
        let th = &self.system.thickness;
        let (tmin, tmax) = th
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &h| (a.min(h), b.max(h)));
        let volume_now = self.gas_volume;
        Ok(ShellStepStats {
            step,
            time: self.time,
            gas_volume: volume_now,
            gauge_pressure: gas.gauge_pressure,
            shell_volume_ratio: self.shell_volume() / self.rest_shell_volume,
            newton_iterations: totals.newton_iterations,
            linear_iterations: totals.linear_iterations,
            factorizations: totals.factorizations,
            newton_residual: totals.newton_residual,
            line_search_cuts: totals.line_search_cuts,
            regularized_solves: totals.regularized_solves,
            dt_used: totals.min_dt,
            halvings: totals.halvings,
            projection_iterations: totals.projection_iterations,
            substeps: totals.substeps,
            max_speed,
            volume_change: if volume_old > 0.0 {
                (volume_now - volume_old).abs() / volume_old
            } else {
                0.0
            },
            thickness_mean: th.iter().sum::<f64>() / th.len() as f64,
            thickness_min: tmin,
            thickness_max: tmax,
            step_ms: start.elapsed().as_secs_f64() * 1e3,
            times,
        })
    }
}
