//! `balloon inflate [MESH|builtin]`: the main job, a shell balloon with thickness (Wang et al. 2015):
//! its flags, turned into a `balloon_scenario::shell::ShellScenario` and run by
//! `balloon_run::jobs::shell`.

use crate::choices::{FrameFormat, GasArg, ProjectionMode};
use crate::material_args::MaterialArgs;
use crate::pictures::PictureArgs;
use crate::scenario_cli::{Invocation, job_error};
use anyhow::Result;
use balloon::integrate::TangentKind;
use balloon::integrate::linear::{LinearSolverKind, PcgPreconditioner};
use balloon::mesh::TriMesh;
use balloon_run::Finished;
use balloon_scenario::gas::{GasLaws, VolumeRatios};
use balloon_scenario::mesh::MeshSpec;
use balloon_scenario::range::{parse_real, parse_whole};
use balloon_scenario::selection::{LinearRule, Load, Pin, parse_load, parse_pin, parse_rule};
use balloon_scenario::shell::{Gas, ShellRun, ShellScenario, Wall};
use balloon_scenario::{Scenario, SystemKind};
use std::path::PathBuf;

pub use balloon_scenario::shell::ShellSim;

/// The parser of `balloon inflate`'s flags, on their own (the flags after a scenario file, the
/// tests).
#[derive(Debug, clap::Parser)]
#[command(name = "balloon run")]
pub struct ShellCli {
    /// The flags.
    #[command(flatten)]
    pub args: InflateArgs,
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
    #[arg(long, default_value_t = Wall::default().density, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub density: f64,
    /// Rest shell thickness, m (the paper uses 0.3 mm), in (0, 1] (a thin shell).
    #[arg(long, default_value_t = Wall::default().thickness, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub thickness: f64,
    /// Bending stiffness of the wall, as a factor on that of a plate of its material and
    /// thickness, `Y h^3 / (12 (1 - nu^2))`, in [0, 1e6]. 0 (the default): none, the wall of
    /// Wang et al. 2015, whose three-prism elements resist only stretching.
    #[arg(long, default_value_t = Wall::default().bending, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub bending: f64,
    /// Thickness maps, anchors and loads: --thickness-file, --thickness-rule, --pin,
    /// --pin-stiffness, --load.
    #[command(flatten)]
    pub setup: Box<SetupArgs>,
    /// Gas model: `pump` (ambient air added at --pump-rate from the rest shape: the process of
    /// inflating), `ideal` (isothermal, fixed amount, Eq. 12-14), `constant` (fixed pressure),
    /// `polytropic` (--gamma), `leak` (--leak-conductance) or `supply-pump` (--supply-pressure).
    /// The paper's model is `--gas ideal --ambient 0`. With --static also `volume` (a given
    /// enclosed volume, --volume-ratio / --volume-ratios; the pressure is reported).
    #[arg(long, value_enum, default_value_t = GasArg::Pump)]
    pub gas: GasArg,
    /// Parameters of `--gas polytropic|leak|supply-pump`.
    #[command(flatten)]
    pub gas_law: GasLawArgs,
    /// Gauge pressure, Pa: initial for `ideal`, fixed for `constant`, unused by `pump`; in
    /// [-1e7, 1e7] (100 bar: far beyond what any inflatable shell holds).
    #[arg(long, default_value_t = Gas::default().pressure, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub pressure: f64,
    /// Ambient (outside) pressure, Pa, in [0, 1e7] (0 is the paper's model; 100 bar is
    /// deeper than any dive, and far larger values overflow the gas law's p V).
    #[arg(long, default_value_t = Gas::default().ambient, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub ambient: f64,
    /// Pump rate for `--gas pump`, m^3/s of ambient air (2e-3 = 2 L/s, about what a person
    /// blows), in [0, 100] (an industrial blower moves a few m^3/s). Default: 0.7 rest volumes
    /// of the body per second, so that a 0.1 m model and a 1 m one inflate alike (2.0 L/s for
    /// the built-in 2.9 L teddy).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_real)]
    pub pump_rate: Option<f64>,
    /// Mass-proportional damping alpha, 1/s, in [0, 1e6] (beyond, the shell only creeps).
    #[arg(long, default_value_t = ShellRun::default().mass_damping, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub mass_damping: f64,
    /// Stiffness-proportional damping beta, s, in [0, 10].
    #[arg(long, default_value_t = ShellRun::default().stiffness_damping, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub stiffness_damping: f64,
    /// Time step, s, in (0, 1]: a balloon inflates in seconds, so a step of a second or more
    /// skips its whole motion (the default is 0.01 s).
    #[arg(long, default_value_t = ShellRun::default().dt, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub dt: f64,
    /// Number of steps (the maximum with --until-converged), 0 to 1e8.
    #[arg(long, default_value_t = ShellRun::default().steps, value_parser = parse_whole)]
    pub steps: usize,
    /// Stop when the largest vertex speed is below --speed-tol and the per-step relative gas
    /// volume change is below --volume-tol.
    #[arg(long)]
    pub until_converged: bool,
    /// Speed tolerance for --until-converged, m/s, in (0, 1e3].
    #[arg(long, default_value_t = ShellRun::default().speed_tol, value_parser = parse_real)]
    pub speed_tol: f64,
    /// Relative per-step volume change tolerance for --until-converged, in (0, 1) (at 1 or
    /// more any step would count as converged).
    #[arg(long, default_value_t = ShellRun::default().volume_tol, value_parser = parse_real)]
    pub volume_tol: f64,
    /// Maximum Newton iterations per (sub-)step, 1 to 1000. Newton stops earlier when the
    /// relative residual is below --newton-tol; a step that does not get there is retried with
    /// dt halved. The paper's mode is `--newton-iters 3 --newton-tol 0`.
    #[arg(long, default_value_t = ShellRun::default().newton_iters,
          value_parser = parse_whole)]
    pub newton_iters: usize,
    /// Newton's convergence test: the residual of backward Euler relative to the force scale
    /// of the step (inertia, elastic, gas and external forces). 0 is the paper's mode: exactly
    /// --newton-iters full Newton steps, no line search and no convergence test.
    #[arg(long, default_value_t = ShellRun::default().newton_tol,
          value_parser = parse_real)]
    pub newton_tol: f64,
    /// Linear solver: `factorized-pcg` (default: CG preconditioned by a Cholesky factor, with
    /// Sherman-Morrison for the gas term, kept across Newton iterations and steps and refreshed
    /// when it stops paying), `cholesky` (sparse direct refactorised at every Newton
    /// iteration, with Sherman-Morrison for the gas term), `pcg` (assembled matrix, see
    /// --pcg-preconditioner) or `matrix-free-cg` (the paper's).
    #[arg(long, default_value_t = ShellRun::default().linear_solver)]
    pub linear_solver: LinearSolverKind,
    /// Newton tangent: `projected` (element stiffnesses projected to positive semi-definite:
    /// projected Newton, no regularisation retries; same forces and equilibria) or `exact` (the
    /// Hessian of the energy, indefinite where the membrane is compressed).
    #[arg(long, default_value_t = ShellRun::default().tangent)]
    pub tangent: TangentKind,
    /// Preconditioner of `--linear-solver pcg`: `jacobi` or `ic0` (zero-fill incomplete Cholesky).
    #[arg(long, default_value_t = ShellRun::default().pcg_preconditioner)]
    pub pcg_preconditioner: PcgPreconditioner,
    /// Relative tolerance of the CG solvers (inexact Newton), in (0, 1): CG stops once the
    /// residual is below this fraction of its start, so at 1 or more it returns a zero update
    /// and the shell never moves.
    #[arg(long, default_value_t = ShellRun::default().cg_tol,
          value_parser = parse_real)]
    pub cg_tol: f64,
    /// Inexact Newton, in [0, 1]: each CG solve of a Newton step is asked for a linearised
    /// residual of this fraction of --newton-tol, relative to the step's current residual
    /// (within [--cg-tol, 0.1]); 0 solves every Newton system to --cg-tol. Newton still stops
    /// on the nonlinear residual, so the result is the same to --newton-tol; only the CG
    /// iterations spent on it change. Not used in the paper's mode (--newton-tol 0).
    #[arg(long, default_value_t = ShellRun::default().inexact_forcing,
          value_parser = parse_real)]
    pub inexact_forcing: f64,
    /// Maximum CG iterations per Newton iteration, 1 to 1e6 (0 would never update the shell).
    #[arg(long, default_value_t = ShellRun::default().cg_max_iters, value_parser = parse_whole)]
    pub cg_max_iters: usize,
    /// Include the area-normal (follower) term `-(p - p_ambient) d^2V/dx^2` of the pressure
    /// tangent: `--follower-term` or `--follower-term=true` on, `--follower-term=false` off.
    /// Default: on with the residual test (the exact tangent: quadratic Newton convergence),
    /// off in the paper's mode (`--newton-tol 0`; the paper drops it).
    #[arg(long, num_args = 0..=1, require_equals = true, default_missing_value = "true")]
    pub follower_term: Option<bool>,
    /// Solve each step with the wall thickness extrapolated to the end of the step and solved
    /// again (secant steps, at most 8 solves) while the projection's thickness differs from
    /// it by more than 1e-3 or a hundredth of the step's change of the thickness (the
    /// shell-volume projection after the solve thins the wall by what the step stretched it;
    /// without this the solve lags one step behind, a first-order error in --dt):
    /// `--thickness-prediction` or `=true` on, `=false` off. Default: off (the paper's
    /// Algorithm 1).
    #[arg(long, num_args = 0..=1, require_equals = true, default_missing_value = "true")]
    pub thickness_prediction: Option<bool>,
    /// Shell-volume projection: `global` (Wang et al. 2015, Algorithm 2), `per-element` or `off`
    /// [default: global; off for membranes, whose thickness H / (l1 l2) keeps every element's
    /// volume exactly, so the projection has nothing to correct].
    #[arg(long, value_enum)]
    pub volume_projection: Option<ProjectionMode>,
    /// Multiply mesh coordinates by this factor (mesh units -> metres), in (0, 1e6].
    #[arg(long, default_value_t = MeshSpec::default().scale, value_parser = parse_real)]
    pub scale: f64,
    /// Affine map applied to the mesh after --scale: 12 comma-separated numbers, a 3x4 matrix
    /// row by row `a11,a12,a13,t1,a21,a22,a23,t2,a31,a32,a33,t3` mapping x to A x + t (m);
    /// A must have a positive determinant (no mirror). E.g. a translation by (0.1, 0, 0) is
    /// `1,0,0,0.1,0,1,0,0,0,0,1,0`. Each number in [-1e6, 1e6].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1,
          value_parser = parse_real)]
    pub transform: Option<Vec<f64>>,
    /// Output folder: frames, final mesh, stats.jsonl, summary.json.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the files of an earlier run in --out (frames, records, pictures: only files
    /// this program writes); without it, a folder holding them is refused.
    #[arg(long)]
    pub overwrite: bool,
    /// Write a frame every K steps (0: only the first and final frames), 0 to 1e8.
    #[arg(long, default_value_t = ShellScenario::default().output.frame_every, value_parser = parse_whole)]
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
    /// With --static: report the smallest eigenvalue of each equilibrium's stiffness relative
    /// to its mass (1/s^2; negative: unstable under the load as held). Along --volume-ratios a
    /// sign change marks a limit point or a bifurcation (the aspherical inflation of Alexander
    /// 1971); the summary warns about unstable points
    #[arg(long)]
    pub stability: bool,
    /// `--static --gas volume`: the enclosed volume over the rest volume, in (0, 1e3].
    #[arg(long, value_parser = parse_real)]
    pub volume_ratio: Option<f64>,
    /// `--static --gas volume`: a continuation START:END:STEP of volume ratios, one
    /// `stats.jsonl` line (and frame) per point.
    #[arg(long)]
    pub volume_ratios: Option<VolumeRatios>,
}

/// The flags of thickness maps, anchors and loads (part of `balloon inflate`).
#[derive(Clone, Debug, Default, clap::Args)]
pub struct SetupArgs {
    /// Rest thickness map: a text file of thicknesses (m), one per line (`#` comments), one per
    /// face or one per vertex (averaged to the faces), told apart by their count. Replaces
    /// --thickness. Without a file or a rule, a PLY mesh's `thickness` vertex or face property
    /// is used when it has one.
    #[arg(long, conflicts_with = "thickness_rule")]
    pub thickness_file: Option<PathBuf>,
    /// Rest thickness linear in a coordinate over the mesh's bounding box, `AXIS:FROM:TO` (m;
    /// e.g. `z:3e-4:6e-4` is 0.3 mm at the lowest face centroid, 0.6 mm at the highest).
    /// Replaces --thickness.
    #[arg(long, value_parser = parse_rule)]
    pub thickness_rule: Option<LinearRule>,
    /// Pin vertices (repeatable): `indices:1,2,3`, `file:PATH`, `below:AXIS:VALUE`,
    /// `above:AXIS:VALUE`, `box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX` (m) or `ply:PATH:PROPERTY` (the
    /// vertices whose PLY vertex property is not 0), with `@K` for springs of K N/m instead of
    /// a hard pin (a hard-pinned vertex does not move at all).
    #[arg(long, value_parser = parse_pin)]
    pub pin: Vec<Pin>,
    /// Stiffness of the --pin anchors without their own `@K`, N/m, in (0, 1e12]; absent: hard
    /// pins.
    #[arg(long, value_parser = parse_real)]
    pub pin_stiffness: Option<f64>,
    /// A load (repeatable): `gravity=GX,GY,GZ` (m/s^2), `force=FX,FY,FZ;on=SELECTOR` (N per
    /// vertex; `per=total` spreads it over the selection) or `grab=X,Y,Z;on=SELECTOR;
    /// stiffness=K` (pulled toward the point, N/m per vertex); `start=S;end=S` schedule it (s).
    #[arg(long, value_parser = parse_load)]
    pub load: Vec<Load>,
}

/// The flags of the gas laws beyond the isothermal ones (`balloon_gas::laws`), checked against
/// `--gas` by `balloon_scenario::gas::GasLaws::params`.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct GasLawArgs {
    /// Polytropic exponent of `--gas polytropic`, `p V^gamma` constant (> 0; 1.4 adiabatic
    /// air, 1 isothermal) [default: 1.4].
    #[arg(long, allow_hyphen_values = true)]
    pub gamma: Option<f64>,
    /// Leak conductance of `--gas leak`, m^3/s (>= 0): the gas content nRT flows out at
    /// C (p - p_ambient) J/s, so a rigid balloon of volume V loses its gauge pressure as
    /// exp(-C t / V).
    #[arg(long, allow_hyphen_values = true)]
    pub leak_conductance: Option<f64>,
    /// Gauge supply pressure of `--gas supply-pump`, Pa (> 0): the pump adds --pump-rate until
    /// the balloon reaches it, then stops.
    #[arg(long, allow_hyphen_values = true)]
    pub supply_pressure: Option<f64>,
}

impl GasLawArgs {
    /// The gas-law keys.
    pub fn laws(&self) -> GasLaws {
        GasLaws {
            gamma: self.gamma,
            leak_conductance: self.leak_conductance,
            supply_pressure: self.supply_pressure,
        }
    }
}

impl InflateArgs {
    /// The scenario of these flags (every key, given or default).
    pub fn scenario(&self) -> ShellScenario {
        let mut s = ShellScenario {
            mesh: MeshSpec {
                path: self.mesh.clone(),
                scale: self.scale,
                transform: self.transform.clone(),
            },
            shell: Wall {
                material: self.material.spec(),
                thickness: self.thickness,
                thickness_file: self.setup.thickness_file.clone(),
                thickness_rule: self.setup.thickness_rule,
                pin_stiffness: self.setup.pin_stiffness,
                density: self.density,
                volume_projection: self.volume_projection.map(Into::into),
                bending: self.bending,
            },
            gas: Gas {
                model: self.gas.into(),
                pressure: self.pressure,
                ambient: self.ambient,
                pump_rate: self.pump_rate,
                laws: self.gas_law.laws(),
                volume_ratio: self.volume_ratio,
                volume_ratios: self.volume_ratios.clone(),
            },
            run: ShellRun {
                dt: self.dt,
                steps: self.steps,
                static_solve: self.static_solve,
                until_converged: self.until_converged,
                speed_tol: self.speed_tol,
                volume_tol: self.volume_tol,
                mass_damping: self.mass_damping,
                stiffness_damping: self.stiffness_damping,
                newton_iters: self.newton_iters,
                newton_tol: self.newton_tol,
                linear_solver: self.linear_solver,
                tangent: self.tangent,
                pcg_preconditioner: self.pcg_preconditioner,
                cg_tol: self.cg_tol,
                inexact_forcing: self.inexact_forcing,
                cg_max_iters: self.cg_max_iters,
                follower_term: self.follower_term,
                thickness_prediction: self.thickness_prediction,
                stability: self.stability,
            },
            anchors: self.setup.pin.clone(),
            loads: self.setup.load.clone(),
            ..ShellScenario::default()
        };
        s.output.out.clone_from(&self.out);
        s.output.overwrite = self.overwrite;
        s.output.json = self.json;
        s.output.format = self.format.into();
        s.output.frame_every = self.frame_every;
        self.pictures.apply(&mut s.output);
        s
    }
}

/// Runs `balloon inflate` (`matches`: the subcommand's, for the values as typed).
pub fn run(args: &InflateArgs, matches: &clap::ArgMatches) -> Result<()> {
    let call = Invocation::of(Scenario::Shell(args.scenario()), matches)?;
    let Scenario::Shell(s) = &call.scenario else {
        unreachable!("a shell scenario")
    };
    balloon_run::jobs::shell::run(s, None, Some(&call.record()), false).map(drop)
}

/// Builds the simulation of `balloon inflate` for `args` (checked first), as the command does:
/// loads the mesh (or takes `mesh`, an in-memory one), sets up the balloon, its anchors and
/// the loads of time 0. Writes nothing; the scheduled loads are dropped.
pub fn build(args: &InflateArgs, mesh: Option<TriMesh>) -> Result<ShellSim> {
    let s = args.scenario();
    s.validate().map_err(job_error)?;
    Ok(s.build(mesh)?.0)
}

/// Runs the job of `balloon inflate` for `args` (checks, build, the output folder, the steps
/// or the static solve, the summary) and returns the summary with the final simulation;
/// `quiet` prints nothing. No scenario is recorded.
pub fn execute(
    args: &InflateArgs,
    mesh: Option<TriMesh>,
    quiet: bool,
) -> Result<Finished<ShellSim>> {
    let s = args.scenario();
    s.validate().map_err(job_error)?;
    balloon_run::jobs::shell::run(&s, mesh, None, quiet).map(|(finished, _)| finished)
}

/// The system of these flags.
pub const SYSTEM: SystemKind = SystemKind::Shell;
