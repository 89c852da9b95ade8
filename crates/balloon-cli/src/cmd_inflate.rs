//! `balloon inflate [MESH|builtin]`: the main job, a shell balloon with thickness (seed 000).

use crate::cmd_static::GasArg;
use crate::material_args::MaterialArgs;
use crate::output::{
    ColorField, Frame, FrameFormat, OutputDir, PictureArgs, PictureStyle, check_picture_args,
};
use crate::params::{End::Closed, End::Open, MAX_STEPS, count, real};
use crate::run::{Finished, FramePolicy, RunHooks, RunPlan, RunRecord, run_simulation};
use anyhow::{Context, Result};
use balloon::constraint::shell_volume::{ProjectionScope, ShellVolumeParams};
use balloon::integrate::implicit::BackwardEulerParams;
use balloon::integrate::linear::{LinearSolverKind, LinearSolverParams, PcgPreconditioner};
use balloon::integrate::{PhaseTimes, TangentKind};
use balloon::shell::{
    self, ShellBalloon, ShellMaterial, ShellMaterialModel, ShellSimulation, ShellStepStats,
};
use balloon::{SimulationError, SimulationStats};
use balloon_mesh::TriMesh;
use balloon_render::UpAxis;
use serde::Serialize;
use std::path::PathBuf;

/// Volume projection mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ProjectionMode {
    /// The global shell-volume projection of seed 000 (Eq. 24-28, Algorithm 2).
    Global,
    /// Every element keeps its own material volume (thickness H A0 / A per element).
    PerElement,
    /// No projection: the thickness stays at its rest value (a membrane's still follows its
    /// stretch).
    Off,
}

/// Arguments of `balloon inflate`. Defaults model a latex party balloon.
#[derive(Debug, clap::Args)]
pub struct InflateArgs {
    /// Mesh file (.obj, .off, .ply, .stl) or `builtin[:NAME]`; default: the built-in teddy.
    #[arg(default_value = "builtin")]
    pub mesh: String,
    /// Material: --material, its parameters, --material-preset.
    #[command(flatten)]
    pub material: MaterialArgs,
    /// Shell density, kg/m^3, in (0, 1e5] (above any solid's: osmium is 2.26e4).
    #[arg(long, default_value_t = shell::DEFAULT_DENSITY, allow_hyphen_values = true,
          value_parser = real(Open(0.0), Closed(1e5)))]
    pub density: f64,
    /// Rest shell thickness, m (the paper uses 0.3 mm), in (0, 1] (a thin shell).
    #[arg(long, default_value_t = shell::DEFAULT_THICKNESS, allow_hyphen_values = true,
          value_parser = real(Open(0.0), Closed(1.0)))]
    pub thickness: f64,
    /// Thickness maps, anchors and loads: --thickness-file, --thickness-rule, --pin,
    /// --pin-stiffness, --load.
    #[command(flatten)]
    pub setup: Box<crate::selection::SetupArgs>,
    /// Gas model: `pump` (ambient air added at --pump-rate from the rest shape: the process of
    /// inflating), `ideal` (isothermal, fixed amount, Eq. 12-14), `constant` (fixed pressure),
    /// `polytropic` (--gamma), `leak` (--leak-conductance) or `supply-pump` (--supply-pressure).
    /// The paper's model is `--gas ideal --ambient 0`. With --static also `volume` (a given
    /// enclosed volume, --volume-ratio / --volume-ratios; the pressure is reported).
    #[arg(long, value_enum, default_value_t = GasArg::Pump)]
    pub gas: GasArg,
    /// Parameters of `--gas polytropic|leak|supply-pump`.
    #[command(flatten)]
    pub gas_law: crate::cmd_static::GasLawArgs,
    /// Gauge pressure, Pa: initial for `ideal`, fixed for `constant`, unused by `pump`; in
    /// [-1e7, 1e7] (100 bar: far beyond what any inflatable shell holds).
    #[arg(long, default_value_t = shell::DEFAULT_GAUGE_PRESSURE, allow_hyphen_values = true,
          value_parser = real(Closed(-1e7), Closed(1e7)))]
    pub pressure: f64,
    /// Ambient (outside) pressure, Pa, in [0, 1e7] (0 is the paper's model; 100 bar is
    /// deeper than any dive, and far larger values overflow the gas law's p V).
    #[arg(long, default_value_t = balloon::gas::STANDARD_ATMOSPHERE, allow_hyphen_values = true,
          value_parser = real(Closed(0.0), Closed(1e7)))]
    pub ambient: f64,
    /// Pump rate for `--gas pump`, m^3/s of ambient air (2e-3 = 2 L/s, about what a person
    /// blows), in [0, 100] (an industrial blower moves a few m^3/s). Default: 0.7 rest volumes
    /// of the body per second, so that a 0.1 m model and a 1 m one inflate alike (2.0 L/s for
    /// the built-in 2.9 L teddy).
    #[arg(long, allow_hyphen_values = true, value_parser = real(Closed(0.0), Closed(100.0)))]
    pub pump_rate: Option<f64>,
    /// Mass-proportional damping alpha, 1/s, in [0, 1e6] (beyond, the shell only creeps).
    #[arg(long, default_value_t = shell::DEFAULT_MASS_DAMPING, allow_hyphen_values = true,
          value_parser = real(Closed(0.0), Closed(1e6)))]
    pub mass_damping: f64,
    /// Stiffness-proportional damping beta, s, in [0, 10].
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true,
          value_parser = real(Closed(0.0), Closed(10.0)))]
    pub stiffness_damping: f64,
    /// Time step, s, in (0, 1]: a balloon inflates in seconds, so a step of a second or more
    /// skips its whole motion (the default is 0.01 s).
    #[arg(long, default_value_t = shell::DEFAULT_DT, allow_hyphen_values = true,
          value_parser = real(Open(0.0), Closed(1.0)))]
    pub dt: f64,
    /// Number of steps (the maximum with --until-converged), 0 to 1e8.
    #[arg(long, default_value_t = 300, value_parser = count(0, MAX_STEPS))]
    pub steps: usize,
    /// Stop when the largest vertex speed is below --speed-tol and the per-step relative gas
    /// volume change is below --volume-tol.
    #[arg(long)]
    pub until_converged: bool,
    /// Speed tolerance for --until-converged, m/s, in (0, 1e3].
    #[arg(long, default_value_t = 1e-3, value_parser = real(Open(0.0), Closed(1e3)))]
    pub speed_tol: f64,
    /// Relative per-step volume change tolerance for --until-converged, in (0, 1) (at 1 or
    /// more any step would count as converged).
    #[arg(long, default_value_t = 1e-6, value_parser = real(Open(0.0), Open(1.0)))]
    pub volume_tol: f64,
    /// Maximum Newton iterations per (sub-)step, 1 to 1000. Newton stops earlier when the
    /// relative residual is below --newton-tol; a step that does not get there is retried with
    /// dt halved. The paper's mode is `--newton-iters 3 --newton-tol 0`.
    #[arg(long, default_value_t = balloon::integrate::implicit::DEFAULT_NEWTON_ITERATIONS,
          value_parser = parse_newton_iters)]
    pub newton_iters: usize,
    /// Newton's convergence test: the residual of backward Euler relative to the force scale
    /// of the step (inertia, elastic, gas and external forces). 0 is the paper's mode: exactly
    /// --newton-iters full Newton steps, no line search and no convergence test.
    #[arg(long, default_value_t = balloon::integrate::implicit::DEFAULT_NEWTON_TOLERANCE,
          value_parser = parse_newton_tol)]
    pub newton_tol: f64,
    /// Linear solver: `factorized-pcg` (default: CG preconditioned by a Cholesky factor, with
    /// Sherman-Morrison for the gas term, kept across Newton iterations and steps and refreshed
    /// when it stops paying), `cholesky` (sparse direct refactorised at every Newton
    /// iteration, with Sherman-Morrison for the gas term), `pcg` (assembled matrix, see
    /// --pcg-preconditioner) or `matrix-free-cg` (the paper's).
    #[arg(long, default_value = "factorized-pcg")]
    pub linear_solver: LinearSolverKind,
    /// Newton tangent: `projected` (element stiffnesses projected to positive semi-definite:
    /// projected Newton, no regularisation retries; same forces and equilibria) or `exact` (the
    /// Hessian of the energy, indefinite where the membrane is compressed).
    #[arg(long, default_value = "exact")]
    pub tangent: TangentKind,
    /// Preconditioner of `--linear-solver pcg`: `jacobi` or `ic0` (zero-fill incomplete Cholesky).
    #[arg(long, default_value = "ic0")]
    pub pcg_preconditioner: PcgPreconditioner,
    /// Relative tolerance of the CG solvers (inexact Newton), in (0, 1): CG stops once the
    /// residual is below this fraction of its start, so at 1 or more it returns a zero update
    /// and the shell never moves.
    #[arg(long, default_value_t = shell::DEFAULT_LINEAR_TOLERANCE,
          value_parser = real(Open(0.0), Open(1.0)))]
    pub cg_tol: f64,
    /// Inexact Newton, in [0, 1]: each CG solve of a Newton step is asked for a linearised
    /// residual of this fraction of --newton-tol, relative to the step's current residual
    /// (within [--cg-tol, 0.1]); 0 solves every Newton system to --cg-tol. Newton still stops
    /// on the nonlinear residual, so the result is the same to --newton-tol; only the CG
    /// iterations spent on it change. Not used in the paper's mode (--newton-tol 0).
    #[arg(long, default_value_t = balloon::integrate::implicit::DEFAULT_INEXACT_FORCING,
          value_parser = real(Closed(0.0), Closed(1.0)))]
    pub inexact_forcing: f64,
    /// Maximum CG iterations per Newton iteration, 1 to 1e6 (0 would never update the shell).
    #[arg(long, default_value_t = 500, value_parser = count(1, 1_000_000))]
    pub cg_max_iters: usize,
    /// Include the area-normal (follower) term `-(p - p_ambient) d^2V/dx^2` of the pressure
    /// tangent: `--follower-term` or `--follower-term=true` on, `--follower-term=false` off.
    /// Default: on with the residual test (the exact tangent: quadratic Newton convergence),
    /// off in the paper's mode (`--newton-tol 0`; the paper drops it).
    #[arg(long, num_args = 0..=1, require_equals = true, default_missing_value = "true")]
    pub follower_term: Option<bool>,
    /// Shell-volume projection: `global` (seed 000, Algorithm 2), `per-element` or `off`
    /// [default: global; off for membranes, whose thickness H / (l1 l2) keeps every element's
    /// volume exactly, so the projection has nothing to correct].
    #[arg(long, value_enum)]
    pub volume_projection: Option<ProjectionMode>,
    /// Multiply mesh coordinates by this factor (mesh units -> metres), in (0, 1e6].
    #[arg(long, default_value_t = 1.0, value_parser = real(Open(0.0), Closed(1e6)))]
    pub scale: f64,
    /// Affine map applied to the mesh after --scale: 12 comma-separated numbers, a 3x4 matrix
    /// row by row `a11,a12,a13,t1,a21,a22,a23,t2,a31,a32,a33,t3` mapping x to A x + t (m);
    /// A must have a positive determinant (no mirror). E.g. a translation by (0.1, 0, 0) is
    /// `1,0,0,0.1,0,1,0,0,0,0,1,0`. Each number in [-1e6, 1e6].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1,
          value_parser = real(Closed(-1e6), Closed(1e6)))]
    pub transform: Option<Vec<f64>>,
    /// Output folder: frames, final mesh, stats.jsonl, summary.json.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the files of an earlier run in --out (frames, records, pictures: only files
    /// this program writes); without it, a folder holding them is refused.
    #[arg(long)]
    pub overwrite: bool,
    /// Write a frame every K steps (0: only the first and final frames), 0 to 1e8.
    #[arg(long, default_value_t = 10, value_parser = count(0, MAX_STEPS))]
    pub frame_every: usize,
    /// Frame file format: obj, ply, or vtk (`.vtp` frames with velocity, speed, pressure force,
    /// thickness, stretch and max_stretch, listed with their times in `series.pvd`).
    #[arg(long, value_enum, default_value_t = FrameFormat::Obj)]
    pub format: FrameFormat,
    /// Pictures: --render, --gif, --pov, --color, --image-size.
    #[command(flatten)]
    pub pictures: PictureArgs,
    /// Print the summary as one JSON line (the last line on stdout); no progress bar.
    #[arg(long)]
    pub json: bool,
    /// Solve for the rest shape directly (static equilibrium: Newton with line search,
    /// Levenberg-Marquardt shift and load continuation) instead of stepping in time.
    #[arg(long = "static")]
    pub static_solve: bool,
    /// `--static --gas volume`: the enclosed volume over the rest volume, in (0, 1e3].
    #[arg(long, value_parser = real(Open(0.0), Closed(1e3)))]
    pub volume_ratio: Option<f64>,
    /// `--static --gas volume`: a continuation START:END:STEP of volume ratios, one
    /// `stats.jsonl` line (and frame) per point.
    #[arg(long, value_parser = crate::cmd_static::parse_volume_ratios)]
    pub volume_ratios: Option<std::vec::Vec<f64>>,
    /// The resolved scenario of this run (`crate::cmd_run::record`), written to
    /// `OUT/scenario.toml`; not a flag.
    #[arg(skip)]
    pub scenario_record: Option<String>,
}

/// The run summary (`summary.json`, and the `--json` line).
#[derive(Debug, Default, Serialize)]
pub struct InflateSummary {
    /// Mesh given on the command line.
    pub mesh: String,
    /// Vertices.
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Steps completed.
    pub steps: usize,
    /// Whether --until-converged reached its tolerances.
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
    /// Whether the tangent includes the pressure follower term (`--follower-term`, resolved:
    /// on by default with the residual test, off in the paper's mode).
    pub follower_term: bool,
    /// The error that stopped the run, if any.
    pub error: Option<String>,
}

/// How shell balloons are drawn: the mesh's +y is up (the teddy stands along +y).
const STYLE_FIELDS: &[ColorField] = &[
    ColorField::Thickness,
    ColorField::Stretch,
    ColorField::Speed,
];

fn style() -> PictureStyle {
    PictureStyle {
        // Validated closed and outward oriented by the builder.
        closed: true,
        ..PictureStyle::new("inflate", UpAxis::Y, ColorField::Thickness, STYLE_FIELDS)
    }
}

/// The current state as a frame with its fields: velocity, speed, pressure force (Eq. 15),
/// thickness, stretch and max_stretch against the rest shape.
pub(crate) fn shell_frame<M: ShellMaterial>(
    sim: &ShellSimulation<M>,
    step: usize,
) -> Result<Frame> {
    let x = sim.positions();
    let tris = sim.triangles();
    let force = balloon::fields::pressure_forces(x, tris, sim.gauge_pressure())?;
    let mut f = Frame::new(step, sim.time(), x.to_vec(), tris.to_vec())
        .with_velocity(sim.velocities().to_vec())?
        .with_stretch(sim.rest_positions())?;
    f.point_data
        .push(crate::output::Field::vector("pressure_force", force));
    f.cell_data.push(crate::output::Field::scalar(
        "thickness",
        sim.thickness().to_vec(),
    ));
    Ok(f)
}

/// What `inflate` adds to the shared run loop: the summary's running totals, convergence
/// (`--until-converged`), the progress message and the named final frame.
struct InflateHooks<'a> {
    summary: InflateSummary,
    /// Wall-clock ms of the steps as the simulation measured them.
    total_ms: f64,
    args: &'a InflateArgs,
    /// Anchor springs and scheduled loads (`--pin ...@K`, `--load`).
    loads: crate::selection::ShellLoads,
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
        s.converged = self.args.until_converged
            && d.max_speed < self.args.speed_tol
            && d.volume_change < self.args.volume_tol;
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
            ..self.summary
        }
    }

    fn no_progress(
        &self,
        sim: &ShellSimulation<M>,
        run: &RunRecord<ShellStepStats>,
    ) -> Option<String> {
        let loaded = match self.args.gas {
            GasArg::Pump => self.args.pump_rate.is_none_or(|r| r > 0.0),
            _ => self.args.pressure != 0.0,
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
                 coordinate: check --linear-solver, --cg-tol, --cg-max-iters, --pressure, \
                 --pump-rate)",
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
            &format!("the simulation of `{}`", self.args.mesh),
            step,
            self.args.out.as_deref(),
        )
    }
}

/// `--newton-iters`: a whole number from 1 to `MAX_NEWTON_ITERATIONS`.
fn parse_newton_iters(s: &str) -> Result<usize, String> {
    let max = balloon::integrate::implicit::MAX_NEWTON_ITERATIONS;
    match s.trim().parse::<usize>() {
        Ok(n) if (1..=max).contains(&n) => Ok(n),
        _ => Err(format!("`{s}` is not a whole number from 1 to {max}")),
    }
}

/// `--newton-tol`: a finite number >= 0 (0: the paper's fixed iterations).
fn parse_newton_tol(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(t) if t.is_finite() && t >= 0.0 => Ok(t),
        _ => Err(format!(
            "`{s}` is not a finite tolerance >= 0 (0 runs the paper's fixed iterations)"
        )),
    }
}

/// Runs `balloon inflate`.
pub fn run(args: InflateArgs) -> Result<()> {
    execute(&args, None, false).map(drop)
}

/// The shell simulation `balloon inflate` runs: the built-in or file mesh, or an in-memory one.
pub type ShellSim = ShellSimulation<ShellMaterialModel>;

/// Builds the simulation of `balloon inflate` for `args`: loads `args.mesh` (or takes `mesh`
/// when given, an in-memory mesh such as the Python package's arrays), scales it and sets up the
/// balloon exactly as the command does (thickness map, anchors, the loads of time 0). Writes
/// nothing. The scheduled loads are dropped: use [`build_with_loads`] to keep them.
pub fn build(args: &InflateArgs, mesh: Option<TriMesh>) -> Result<ShellSim> {
    build_with_loads(args, mesh).map(|(sim, _)| sim)
}

/// [`build`], returning the anchor springs and scheduled loads (`--pin ...@K`, `--load`) too:
/// call [`crate::selection::ShellLoads::before_step`] before every step to apply them.
pub fn build_with_loads(
    args: &InflateArgs,
    mesh: Option<TriMesh>,
) -> Result<(ShellSim, crate::selection::ShellLoads)> {
    let material = args.material.resolve()?;
    let membrane = material.thickness_follows_stretch();
    let mut mesh = match mesh {
        Some(m) => m,
        None => balloon::mesh::load(&args.mesh)
            .with_context(|| format!("cannot load mesh `{}`", args.mesh))?,
    };
    if args.scale != 1.0 {
        mesh.scale(args.scale);
    }
    crate::params::apply_transform(&mut mesh, args.transform.as_deref())
        .map_err(anyhow::Error::msg)?;
    let integrator = BackwardEulerParams {
        newton_iterations: args.newton_iters,
        newton_tolerance: args.newton_tol,
        linear: LinearSolverParams {
            kind: args.linear_solver,
            max_iterations: args.cg_max_iters,
            relative_tolerance: args.cg_tol,
        },
        mass_damping: args.mass_damping,
        stiffness_damping: args.stiffness_damping,
        pcg_preconditioner: args.pcg_preconditioner,
        tangent: args.tangent,
        refactor_cost: shell::DEFAULT_REFACTOR_COST,
        parallel_factorization: false,
        inexact_forcing: args.inexact_forcing,
        ..Default::default()
    };
    let projection = match args.volume_projection.unwrap_or(if membrane {
        ProjectionMode::Off
    } else {
        ProjectionMode::Global
    }) {
        ProjectionMode::Global => Some(Default::default()),
        ProjectionMode::PerElement => Some(ShellVolumeParams {
            scope: ProjectionScope::PerElement,
            ..Default::default()
        }),
        ProjectionMode::Off => None,
    };
    let builder = match args.setup.thickness(&args.mesh, &mesh)? {
        Some(map) => ShellBalloon::new(mesh).with_thickness_per_face(map),
        None => ShellBalloon::new(mesh).with_thickness(args.thickness),
    };
    let builder = match args.pump_rate {
        Some(rate) => builder.with_pump_rate(rate),
        None => builder.with_relative_pump_rate(shell::DEFAULT_PUMP_VOLUMES_PER_SECOND),
    };
    let mut sim = builder
        .with_material(material)
        .with_density(args.density)
        .with_gas(args.gas.kind())
        .with_gauge_pressure(args.pressure)
        .with_ambient_pressure(args.ambient)
        .with_gas_law(args.gas_law.params(args.gas)?)
        .with_follower_term(args.follower_term)
        .with_integrator(integrator)
        .with_projection(projection)
        .with_dt(args.dt)
        .build()
        .with_context(|| format!("cannot set up the balloon for `{}`", args.mesh))?;
    let loads = args.setup.apply(&mut sim)?;
    Ok((sim, loads))
}

/// The recorded scenario `text` with the defaults this run resolved written in, where the record
/// says "(not set: the flag's default applies)": the material and its modulus and Poisson's ratio
/// (the StVK default), the shell-volume projection (global, or off for a membrane) and the
/// pump's rate (0.7 rest volumes per second of this body, in m^3/s), so that `scenario.toml` and
/// the summary state every physical value of the run (issue 15, item 2). The values are written
/// in round-trip form, so re-running the record repeats the run bit for bit.
pub fn resolved_record(
    text: &str,
    args: &InflateArgs,
    material: &balloon::shell::ShellMaterialModel,
    sim: &ShellSim,
) -> String {
    use balloon::shell::ShellMaterialModel;
    let mut values: Vec<(&str, String)> = Vec::new();
    if args.material.material.is_none() && args.material.material_preset.is_none() {
        values.push(("material", "\"stvk\"".into()));
    }
    if matches!(material, ShellMaterialModel::Solid(_)) {
        values.push(("young", format!("{:?}", shell::DEFAULT_YOUNG)));
        values.push(("poisson", format!("{:?}", shell::DEFAULT_POISSON)));
    }
    let projection = if material.thickness_follows_stretch() {
        "off"
    } else {
        "global"
    };
    values.push(("volume_projection", format!("\"{projection}\"")));
    if matches!(args.gas, GasArg::Pump | GasArg::SupplyPump) {
        let rate = shell::DEFAULT_PUMP_VOLUMES_PER_SECOND * sim.rest_gas_volume();
        values.push(("pump_rate", format!("{rate:?}")));
    }
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        let unset = values.iter().find(|(key, _)| {
            line.strip_prefix("# ")
                .and_then(|l| l.strip_prefix(key))
                .is_some_and(|l| l == " = (not set: the flag's default applies)")
        });
        match unset {
            // Written as if given, so that the record of a repeat is the same text.
            Some((key, value)) => out.push_str(&format!("{key} = {value}")),
            None => out.push_str(line),
        }
        out.push('\n');
    }
    out
}

/// Runs the job of `balloon inflate` for `args` (checks, [`build`], the output folder, the
/// steps or the static solve, the summary) and returns the summary with the final simulation.
/// `mesh` replaces loading `args.mesh`; `quiet` prints nothing (no progress bar, no summary
/// line), for callers that take the returned summary instead.
pub fn execute(
    args: &InflateArgs,
    mesh: Option<TriMesh>,
    quiet: bool,
) -> Result<Finished<ShellSim>> {
    execute_with_points(args, mesh, quiet).map(|(finished, _)| finished)
}

/// As [`execute`], also returning the converged points of a static run (`--static`: one value
/// per point, the `stats.jsonl` lines; empty for a step run).
pub fn execute_with_points(
    args: &InflateArgs,
    mesh: Option<TriMesh>,
    quiet: bool,
) -> Result<(Finished<ShellSim>, Vec<serde_json::Value>)> {
    // The material flags are checked together before anything is loaded.
    let material = args.material.resolve()?;
    let render_spec = check_picture_args(&args.pictures, args.out.as_deref(), &style())?;
    if let Some(dir) = &args.out {
        crate::output::prepare_out_dir(dir, args.overwrite)?;
    }
    if args.frame_every == 0 && args.steps == 0 {
        anyhow::bail!("nothing to do: --steps is 0");
    }
    if !args.static_solve && args.gas == GasArg::Volume {
        anyhow::bail!("--gas volume is a static control: add --static");
    }
    let (mut sim, loads) = build_with_loads(args, mesh)?;

    let out = match &args.out {
        Some(dir) => Some(OutputDir::create(dir, args.format)?.with_pictures(
            &args.pictures,
            render_spec,
            style(),
        )?),
        None => None,
    };
    let record = args
        .scenario_record
        .as_deref()
        .map(|text| resolved_record(text, args, &material, &sim));
    if let (Some(o), Some(text)) = (&out, &record) {
        o.write_text("scenario.toml", text)?;
    }
    if args.static_solve {
        let run = crate::cmd_static::run(args, &mut sim, out, quiet, record.as_deref())?;
        return Ok((
            Finished {
                summary: Some(run.summary),
                sim,
            },
            run.points,
        ));
    }
    let plan = RunPlan {
        steps: args.steps,
        frames: FramePolicy {
            every: args.frame_every,
            last: false,
        },
        json: args.json,
        quiet,
    };
    let mut hooks = InflateHooks {
        summary: InflateSummary {
            mesh: args.mesh.clone(),
            vertices: sim.positions().len() / 3,
            triangles: sim.triangles().len(),
            initial_gas_volume: sim.rest_gas_volume(),
            shell_volume_ratio_final: 1.0,
            material: material.name(),
            material_parameters: Some(material),
            linear_solver: args.linear_solver.to_string(),
            tangent: args.tangent.to_string(),
            follower_term: sim.follower_term(),
            newton_tolerance: args.newton_tol,
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
