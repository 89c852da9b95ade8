//! The job of a shell run (`balloon inflate`): the output folder, the steps (or the static
//! solve, [`super::statics`]), the summary.

use super::shell_frame::shell_frame;
use crate::output::{ColorField, Frame, OutputDir, PictureStyle};
use crate::run::{Finished, FramePolicy, RunHooks, RunPlan, RunRecord, run_simulation};
use anyhow::Result;
use balloon::integrate::PhaseTimes;
use balloon::mesh::TriMesh;
use balloon::shell::{ShellMaterial, ShellMaterialModel, ShellSimulation, ShellStepStats};
use balloon::{SimulationError, SimulationStats};
use balloon_render::UpAxis;
use balloon_scenario::file::resolve_shell_record;
use balloon_scenario::gas::GasControl;
use balloon_scenario::selection::ShellLoads;
use balloon_scenario::shell::{SHELL_COLORS, ShellRun, ShellScenario, ShellSim};
use serde::Serialize;

/// The run summary (`summary.json`, and the `json` line).
#[derive(Debug, Default, Serialize)]
pub struct InflateSummary {
    /// The mesh (`mesh.path`).
    pub mesh: String,
    /// Vertices.
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Steps completed.
    pub steps: usize,
    /// Whether `until_converged` reached its tolerances.
    pub converged: bool,
    /// Simulated time, s.
    pub sim_time_s: f64,
    /// Gas volume at rest, m^3.
    pub initial_gas_volume: f64,
    /// Gas volume at the end, m^3.
    pub final_gas_volume: f64,
    /// Gauge pressure at the end, Pa.
    pub final_gauge_pressure: f64,
    /// Shell material volume ratio at the end.
    pub shell_volume_ratio_final: f64,
    /// Largest |ratio - 1| over the run.
    pub shell_volume_ratio_max_deviation: f64,
    /// Mean wall-clock ms per step.
    pub mean_step_ms: f64,
    /// Where the run's time went, ms summed over the steps: forces, line-search energies,
    /// assembly, factorisations, linear solves and the shell-volume projection (each step's
    /// `times` in stats.jsonl).
    pub phase_times_ms: PhaseTimes,
    /// Newton iterations over the run.
    pub newton_iterations_total: usize,
    /// Linear iterations over the run.
    pub linear_iterations_total: usize,
    /// Steps that had to be split into smaller sub-steps after a numerical failure.
    pub split_steps: usize,
    /// Newton's relative-residual tolerance of the run (0: the paper's fixed iterations).
    pub newton_tolerance: f64,
    /// Largest final relative Newton residual of any accepted step.
    pub newton_residual_max: f64,
    /// Line-search cuts over the run.
    pub line_search_cuts_total: usize,
    /// Smallest sub-step taken, s.
    pub min_dt_used: f64,
    /// Mean, min and max final thickness, m.
    pub final_thickness_mean: f64,
    /// Minimum final thickness, m.
    pub final_thickness_min: f64,
    /// Maximum final thickness, m.
    pub final_thickness_max: f64,
    /// Material model.
    pub material: String,
    /// The material with its parameters, as the scenario format writes it (e.g.
    /// `{"model": "membrane-gent", "mu": 4e5, "jm": 40}`).
    pub material_parameters: Option<ShellMaterialModel>,
    /// Linear solver.
    pub linear_solver: String,
    /// Newton tangent (`exact` or `projected`).
    pub tangent: String,
    /// Whether the tangent includes the pressure follower term (`follower_term`, resolved:
    /// on by default with the residual test, off in the paper's mode).
    pub follower_term: bool,
    /// The error that stopped the run, if any.
    pub error: Option<String>,
    /// Settings the run suggests changing, in words (e.g. a `newton_iters` cap too low for
    /// `newton_tol`, which splits steps into sub-steps); also printed after the run.
    pub warnings: Vec<String>,
}

/// How shell balloons are drawn: the mesh's +y is up (the teddy stands along +y).
pub(crate) fn style() -> PictureStyle {
    PictureStyle {
        // Validated closed and outward oriented by the builder.
        closed: true,
        ..PictureStyle::new("inflate", UpAxis::Y, ColorField::Thickness, SHELL_COLORS)
    }
}

/// What a shell run adds to the shared run loop: the summary's running totals, convergence
/// (`until_converged`), the progress message and the named final frame.
struct InflateHooks<'a> {
    summary: InflateSummary,
    /// Wall-clock ms of the steps as the simulation measured them.
    total_ms: f64,
    args: &'a ShellScenario,
    /// Anchor springs and scheduled loads.
    loads: ShellLoads,
    /// The resolved scenario ([`resolved_record`]), repeated in the summary.
    record: Option<String>,
}

impl<M: ShellMaterial> RunHooks<ShellSimulation<M>> for InflateHooks<'_> {
    type Summary = InflateSummary;

    fn scenario(&self) -> Option<String> {
        self.record.clone()
    }

    fn frame(&self, sim: &ShellSimulation<M>, step: usize) -> Result<Frame> {
        shell_frame(sim, step)
    }

    fn before_step(&mut self, sim: &mut ShellSimulation<M>) -> Result<()> {
        Ok(self.loads.before_step(sim)?)
    }

    fn after_step(
        &mut self,
        _sim: &ShellSimulation<M>,
        stats: &SimulationStats<ShellStepStats>,
        _out: Option<&mut OutputDir>,
        _regular: bool,
    ) -> Result<bool> {
        let (s, d) = (&mut self.summary, &stats.detail);
        self.total_ms += d.step_ms;
        s.phase_times_ms += d.times;
        s.newton_iterations_total += d.newton_iterations;
        s.linear_iterations_total += d.linear_iterations;
        s.split_steps += usize::from(d.substeps > 1);
        s.newton_residual_max = s.newton_residual_max.max(d.newton_residual);
        s.line_search_cuts_total += d.line_search_cuts;
        s.min_dt_used = if s.min_dt_used > 0.0 {
            s.min_dt_used.min(d.dt_used)
        } else {
            d.dt_used
        };
        s.shell_volume_ratio_max_deviation = s
            .shell_volume_ratio_max_deviation
            .max((d.shell_volume_ratio - 1.0).abs());
        s.converged = self.args.run.until_converged
            && d.max_speed < self.args.run.speed_tol
            && d.volume_change < self.args.run.volume_tol;
        Ok(s.converged)
    }

    fn progress(&self, stats: &SimulationStats<ShellStepStats>) -> Option<String> {
        Some(format!(
            "V = {:.4e} m^3, p = {:.0} Pa",
            stats.detail.gas_volume, stats.detail.gauge_pressure
        ))
    }

    fn finish_extras(&mut self, out: &mut OutputDir, last: &Frame) -> Result<()> {
        out.write_named_frame("final", last)?;
        Ok(())
    }

    fn summary(&self, sim: &ShellSimulation<M>, run: &RunRecord<ShellStepStats>) -> InflateSummary {
        let th = sim.thickness();
        InflateSummary {
            mesh: self.summary.mesh.clone(),
            material: self.summary.material.clone(),
            material_parameters: self.summary.material_parameters.clone(),
            linear_solver: self.summary.linear_solver.clone(),
            tangent: self.summary.tangent.clone(),
            follower_term: sim.follower_term(),
            steps: run.steps,
            sim_time_s: sim.time(),
            final_gas_volume: sim.gas_volume(),
            final_gauge_pressure: sim.gauge_pressure(),
            shell_volume_ratio_final: sim.shell_volume() / sim.rest_shell_volume(),
            mean_step_ms: if run.steps > 0 {
                self.total_ms / run.steps as f64
            } else {
                0.0
            },
            final_thickness_mean: th.iter().sum::<f64>() / th.len() as f64,
            final_thickness_min: th.iter().copied().fold(f64::INFINITY, f64::min),
            final_thickness_max: th.iter().copied().fold(0.0, f64::max),
            error: run.failure.as_ref().map(|e| e.to_string()),
            warnings: newton_cap_warning(&self.args.run, &self.summary, run.steps)
                .into_iter()
                .collect(),
            ..self.summary
        }
    }

    fn no_progress(
        &self,
        sim: &ShellSimulation<M>,
        run: &RunRecord<ShellStepStats>,
    ) -> Option<String> {
        let loaded = match self.args.gas.model {
            GasControl::Pump => self.args.gas.pump_rate.is_none_or(|r| r > 0.0),
            _ => self.args.gas.pressure != 0.0,
        };
        // Moved: some vertex left its rest position by more than round-off (1e-12 of the
        // rest shape's size).
        let rest = sim.rest_positions();
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in rest.chunks_exact(3) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let size = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
        let moved = sim
            .positions()
            .iter()
            .zip(rest)
            .any(|(x, x0)| (x - x0).abs() > 1e-12 * size || !x.is_finite());
        (run.steps > 0 && loaded && !moved).then(|| {
            format!(
                "no progress: the shell did not move (beyond round-off) in {} step(s) although the gas loads it \
                 (a linear solver that makes no progress, or a load too small to move any \
                 coordinate: check `linear_solver`, `cg_tol`, `cg_max_iters`, `pressure`, \
                 `pump_rate`)",
                run.steps
            )
        })
    }

    fn print(
        &self,
        summary: &InflateSummary,
        out: Option<&OutputDir>,
        w: &mut dyn std::io::Write,
    ) -> std::io::Result<()> {
        writeln!(
            w,
            "{} steps, t = {:.3} s: gas volume {:.4e} -> {:.4e} m^3 (x{:.3}), gauge pressure {:.1} Pa, shell volume ratio {:.10}, {:.1} ms/step{}",
            summary.steps,
            summary.sim_time_s,
            summary.initial_gas_volume,
            summary.final_gas_volume,
            summary.final_gas_volume / summary.initial_gas_volume,
            summary.final_gauge_pressure,
            summary.shell_volume_ratio_final,
            summary.mean_step_ms,
            if summary.converged { ", converged" } else { "" }
        )?;
        for warning in &summary.warnings {
            writeln!(w, "warning: {warning}")?;
        }
        if let Some(o) = out {
            writeln!(w, "output written to {}", o.path().display())?;
        }
        Ok(())
    }

    fn print_after_failure(&self) -> bool {
        true
    }

    fn failure(&self, error: SimulationError, step: usize) -> anyhow::Error {
        crate::run::step_failure(
            error,
            &format!("the simulation of `{}`", self.args.mesh.path),
            step,
            self.args.output.out.as_deref(),
        )
    }
}

/// Runs a shell scenario as a job (call [`ShellScenario::validate`] first): checks the output
/// folder, builds the balloon ([`ShellScenario::build`]; `mesh` replaces loading
/// `mesh.path`), writes the resolved `record` (the recorded scenario's text, see
/// `balloon_scenario::file::record`) to `OUT/scenario.toml`, takes the steps or the static
/// solve, and writes and returns the summary with the final simulation, and the converged
/// points of a static run (one value per point, the `stats.jsonl` lines; empty for a step run).
/// `quiet` prints nothing (no progress bar, no summary line), for callers that take the
/// returned summary instead.
pub fn run(
    args: &ShellScenario,
    mesh: Option<TriMesh>,
    record: Option<&str>,
    quiet: bool,
) -> Result<(Finished<ShellSim>, Vec<serde_json::Value>)> {
    let material = args.material()?;
    let render_spec = args
        .output
        .check_pictures("inflate", SHELL_COLORS)
        .map_err(anyhow::Error::msg)?;
    if let Some(dir) = &args.output.out {
        crate::output::check_out_dir(dir, args.output.overwrite)?;
    }
    let (mut sim, loads) = args.build(mesh)?;
    let out = match &args.output.out {
        Some(dir) => {
            // The earlier run's files go only now that this run is set up.
            crate::output::prepare_out_dir(dir, args.output.overwrite)?;
            Some(OutputDir::create(dir, args.output.format)?.with_pictures(
                &args.output,
                render_spec,
                style(),
            )?)
        }
        None => None,
    };
    let record =
        record.map(|text| resolve_shell_record(text, args, &material, sim.rest_gas_volume()));
    if let (Some(o), Some(text)) = (&out, &record) {
        o.write_text("scenario.toml", text)?;
    }
    if args.run.static_solve {
        let run = super::statics::run(args, &mut sim, out, quiet, record.as_deref())?;
        return Ok((
            Finished {
                summary: Some(run.summary),
                sim,
            },
            run.points,
        ));
    }
    let plan = RunPlan {
        steps: args.run.steps,
        frames: FramePolicy {
            every: args.output.frame_every,
            last: false,
        },
        json: args.output.json,
        quiet,
    };
    let mut hooks = InflateHooks {
        summary: InflateSummary {
            mesh: args.mesh.path.clone(),
            vertices: sim.positions().len() / 3,
            triangles: sim.triangles().len(),
            initial_gas_volume: sim.rest_gas_volume(),
            shell_volume_ratio_final: 1.0,
            material: material.name(),
            material_parameters: Some(material),
            linear_solver: args.run.linear_solver.to_string(),
            tangent: args.run.tangent.to_string(),
            follower_term: sim.follower_term(),
            newton_tolerance: args.run.newton_tol,
            ..Default::default()
        },
        total_ms: 0.0,
        args,
        loads,
        record,
    };
    let summary = run_simulation(&mut sim, &mut hooks, &plan, out)?;
    Ok((
        Finished {
            summary: Some(summary),
            sim,
        },
        Vec::new(),
    ))
}

/// The summary's warning when a `newton_iters` cap below the default, with a residual test
/// (`newton_tol` > 0), made steps split into sub-steps: Newton stopped at the cap before the
/// tolerance, so the step was retried with a halved `dt`. (The paper's mode, exactly
/// `newton_iters` full Newton steps whatever the residual, is `newton_tol` = 0.)
fn newton_cap_warning(run: &ShellRun, summary: &InflateSummary, steps: usize) -> Option<String> {
    let default_cap = ShellRun::default().newton_iters;
    (run.newton_tol > 0.0 && run.newton_iters < default_cap && summary.split_steps > 0).then(|| {
        format!(
            "`newton_iters` = {} caps Newton below what `newton_tol` = {:e} needs: {} of {} \
             steps were split into sub-steps (the smallest {:.3e} s), which costs more than the \
             iterations saved. Raise `newton_iters` (default {default_cap}), or for the paper's \
             mode (exactly `newton_iters` full Newton steps, no residual test) set \
             `newton_tol` = 0",
            run.newton_iters, run.newton_tol, summary.split_steps, steps, summary.min_dt_used,
        )
    })
}
