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

    fn early_warning(
        &mut self,
        sim: &ShellSimulation<M>,
        step: usize,
        planned: usize,
    ) -> Option<String> {
        if step != EARLY_WARNING_STEP || planned < 2 * EARLY_WARNING_STEP {
            return None;
        }
        if newton_cap_warning(&self.args.run, &self.summary, step).is_some() {
            // A low cap splits steps by itself: as in the summary, the cap is named instead
            // (at the end of the run).
            return None;
        }
        let lead = format!("the first {step} of {planned} steps");
        floppy_wall_warning(
            &self.args.run,
            &self.summary,
            (&lead, step),
            sim.gauge_pressure(),
            &FloppyWall::of(sim, self.args.shell.density),
        )
        .map(|w| format!("{w}. Ctrl-C stops the run between steps and keeps what it wrote"))
    }

    fn progress(&self, stats: &SimulationStats<ShellStepStats>) -> Option<String> {
        let d = &stats.detail;
        Some(format!(
            "V = {:.4e} m^3, p = {:.0} Pa, Newton {}{}",
            d.gas_volume,
            d.gauge_pressure,
            d.newton_iterations,
            if d.substeps > 1 {
                format!(" in {} sub-steps", d.substeps)
            } else {
                String::new()
            }
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
            // A cap too low splits steps and inflates the iterations by itself: the floppy
            // wall is named only when the cap is not the cause.
            warnings: newton_cap_warning(&self.args.run, &self.summary, run.steps)
                .or_else(|| {
                    floppy_wall_warning(
                        &self.args.run,
                        &self.summary,
                        ("the steps", run.steps),
                        sim.gauge_pressure(),
                        &FloppyWall::of(sim, self.args.shell.density),
                    )
                })
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

/// The step after which a step run of at least twice as many steps warns of a floppy wall at
/// once ([`RunHooks::early_warning`]), not only in its summary.
const EARLY_WARNING_STEP: usize = 5;

/// Newton iterations per step, on average, above which a step run warns that its wall was
/// floppy ([`floppy_wall_warning`]). Steps under a load that stretches the wall take 1 to 3
/// (the paper's Teddy with its pressurised gas: 1.1); the default pump on the shared models
/// takes 13 to 32 at 1 m and 80 to 215 at 0.1 m while their gauge pressure is a few pascals.
const FLOPPY_NEWTON_PER_STEP: f64 = 10.0;

/// Newton iterations per [`FloppyWall::wave_crossing_time`] of simulated time while the wall is
/// floppy, fewest and most: over the first 10 default steps of the shared meshes and the
/// built-in teddy at 0.1 m and 1 m (the teddy at 0.1 m 0.18, the bunny at 1 m 1.12), and of
/// the bunny at 0.1 m with its rubber 10 and 100 times softer or denser (up to 1.31)
/// (docs/benchmarks.md, "The floppy phase follows the wall's elastic wave").
const FLOPPY_ITERATIONS_PER_CROSSING: (f64, f64) = (0.18, 1.3);

/// What [`floppy_wall_warning`] needs of the wall: its bending term, its membrane modulus, its
/// density and mean thickness (the thickness at the end of the run; a floppy wall has hardly
/// thinned) and the rest mesh's mean edge length.
#[derive(Clone, Copy, Debug)]
struct FloppyWall {
    /// The factor on the plate bending modulus (0: the paper's wall).
    bending: f64,
    /// The in-plane (plane-stress) modulus `Y / (1 - nu^2)`, or `4 mu` of an incompressible
    /// membrane, Pa ([`ShellMaterial::plate_modulus`]).
    membrane_modulus: f64,
    /// Density, kg/m^3.
    density: f64,
    /// Mean thickness, m.
    thickness: f64,
    /// Mean edge length of the rest mesh, m.
    edge_length: f64,
}

impl FloppyWall {
    fn of<M: ShellMaterial>(sim: &ShellSimulation<M>, density: f64) -> Self {
        let th = sim.thickness();
        let x = sim.rest_positions();
        let (mut sum, mut count) = (0.0, 0usize);
        for t in sim.triangles() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let d: f64 = (0..3).map(|c| (x[3 * a + c] - x[3 * b + c]).powi(2)).sum();
                sum += d.sqrt();
                count += 1;
            }
        }
        Self {
            bending: sim.system().wall_bending(),
            membrane_modulus: sim.system().material().plate_modulus(),
            density,
            thickness: th.iter().sum::<f64>() / th.len().max(1) as f64,
            edge_length: sum / count.max(1) as f64,
        }
    }

    /// `D dt^2 / (rho h l^4)`: the plate bending stiffness `D = E h^3 / 12` of the wall at the
    /// mesh scale `l` against the wall's inertia over one step. Above 1 a bending term holds
    /// wrinkles of the mesh scale within a step. Measured on the shared meshes (0.3 mm StVK
    /// wall, 10 ms, the default pump, 10 steps): 12 to 610 at 0.1 m, where `bending = 1` took
    /// the steps whole in 3 to 5 Newton iterations; spot at 0.3 m, 3.9: 4.7 instead of 39 per
    /// step, none split; the bunny at 0.3 m, 0.15: 13.5 instead of 39, half the steps still
    /// split; 1.2e-3 to 6e-2 at 1 m, where it changed the iterations by 0.7 to 0.9 times.
    fn bending_over_inertia(&self, dt: f64) -> f64 {
        let h = self.thickness;
        self.membrane_modulus * h * h * dt * dt / (12.0 * self.density * self.edge_length.powi(4))
    }

    /// The time the wall's in-plane elastic wave takes to cross an element, `l / c` with `c =
    /// sqrt(E / rho)` (`E` the membrane modulus). While the wall is floppy, Newton takes about
    /// one iteration per such time of simulated time, whatever `dt`
    /// ([`FLOPPY_ITERATIONS_PER_CROSSING`]).
    fn wave_crossing_time(&self) -> f64 {
        self.edge_length * (self.density / self.membrane_modulus).sqrt()
    }
}

/// The summary's warning when a step run with the residual test took more than
/// [`FLOPPY_NEWTON_PER_STEP`] Newton iterations per step on average: the mark of a floppy wall
/// (a load of a few pascals, far below what stretches it) that wrinkles at the mesh scale,
/// where Newton follows the motion in short iterations, about one per
/// [`FloppyWall::wave_crossing_time`] of simulated time whatever the step. The run's last
/// state need not be floppy any more: a long run's average is set by its floppy phase. Says
/// why and what would change it: a bending term where it holds mesh-scale wrinkles within a
/// step ([`FloppyWall::bending_over_inertia`] above 1), otherwise that the cost lasts until
/// the gas stretches the wall. `lead` names the steps counted (`"the steps"`, or the first
/// few while the run goes on) and `steps` their number.
fn floppy_wall_warning(
    run: &ShellRun,
    summary: &InflateSummary,
    (lead, steps): (&str, usize),
    gauge_pressure: f64,
    wall: &FloppyWall,
) -> Option<String> {
    if run.newton_tol <= 0.0 || steps == 0 || run.static_solve {
        return None;
    }
    let per_step = summary.newton_iterations_total as f64 / steps as f64;
    if per_step <= FLOPPY_NEWTON_PER_STEP {
        return None;
    }
    let ratio = wall.bending_over_inertia(run.dt);
    let cause = if wall.bending > 0.0 {
        "the wall buckles"
    } else {
        "the wall of Wang et al. 2015 has no bending stiffness and wrinkles at the mesh scale"
    };
    let remedy = if ratio >= 1.0 && wall.bending == 0.0 {
        format!(
            "a rubber plate's bending stiffness (`bending` = 1, `--bending 1`; another model: \
             the inflated shapes differ) holds such wrinkles within a step at this size (`D dt^2 \
             / (rho h l^4)` = {ratio:.2e} at the mean edge length l = {:.2e} m; the shared \
             models at 0.1 m, 12 to 610, then take whole 10 ms steps in 3 to 5 Newton \
             iterations)",
            wall.edge_length
        )
    } else if ratio >= 1.0 {
        format!(
            "the bending term holds wrinkles of the mesh scale within a step here (`D dt^2 / \
             (rho h l^4)` = {ratio:.2e} at the mean edge length l = {:.2e} m), so the shape \
             itself snaps: the cost lasts until the gas pressure stretches the wall",
            wall.edge_length
        )
    } else {
        format!(
            "at this size a bending stiffness does not hold them within a step (`D dt^2 / \
             (rho h l^4)` = {ratio:.2e} at the mean edge length l = {:.2e} m, below 1; at 0.15 \
             `bending` = 1 cut the shared bunny's iterations threefold but left 13.5 per step, \
             and at 1e-3 to 6e-2 it changed them by 0.7 to 0.9 times): the cost lasts until the \
             gas pressure stretches the wall",
            wall.edge_length
        )
    };
    let split = if summary.split_steps > 0 {
        format!(
            "; {} of {steps} were split into sub-steps (the smallest {:.3e} s)",
            summary.split_steps, summary.min_dt_used
        )
    } else {
        String::new()
    };
    let crossing = wall.wave_crossing_time();
    let (fewest, most) = FLOPPY_ITERATIONS_PER_CROSSING;
    Some(format!(
        "{lead} took {per_step:.1} Newton iterations on average{split}, the last at a gauge \
         pressure of {gauge_pressure:.1} Pa. So many are the mark of a slack wall, under a load \
         far below what stretches it: {cause}, and Newton follows that motion in short \
         iterations, about one per time the wall's elastic wave takes to cross an element \
         (`l / sqrt(E / rho)` = {crossing:.2e} s here, with the membrane modulus E: {:.0} to \
         {:.0} iterations per step of {:e} s while the wall is floppy, at the {fewest} to \
         {most} per crossing measured on the shared models and the built-in teddy). A smaller \
         `dt` does not save them: the iterations follow the simulated time (docs/benchmarks.md, \
         \"The floppy phase follows the wall's elastic wave\"). Nor does a looser `newton_tol` \
         (1e-2 saved a quarter on the shared bunny at 0.1 m); {remedy}",
        fewest * run.dt / crossing,
        most * run.dt / crossing,
        run.dt,
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
