//! `balloon two-layer`: a two-layer elastic object (Song 2009) in 1D, 2D or 3D, stepped
//! with explicit Euler, midpoint, RK4 or symplectic Euler: its flags, turned into a
//! `balloon_scenario::two_layer::TwoLayerScenario` and run by `balloon_run::jobs::two_layer`.
//!
//! `--pressure` and `--inner-pressure` are the *initial* gas pressures (Pa; N/m in 2D) at the
//! rest volumes; the gas amount is fixed from them (`nRT = P0 V0`) and the pressure then follows
//! `P = nRT / V`.

use crate::choices::{FrameFormat, SphereArg, whole};
use crate::pictures::PictureArgs;
use crate::scenario_cli::{Invocation, job_error};
use anyhow::Result;
use balloon::two_layer::{ExplicitMethod, TwoLayerSimulation};
use balloon_run::Finished;
use balloon_scenario::Scenario;
use balloon_scenario::range::{parse_real, parse_whole};
use balloon_scenario::selection::{Load, Pin, parse_load, parse_pin};
use balloon_scenario::two_layer::{TwoLayerBodyTable, TwoLayerGas, TwoLayerRun, TwoLayerScenario};
use std::path::PathBuf;

/// Arguments of `balloon two-layer`.
#[derive(Debug, clap::Args)]
pub struct TwoLayerArgs {
    /// Dimension: 1 (hanging spring), 2 (two-layer circle), 3 (two-layer sphere).
    #[arg(long, default_value_t = TwoLayerBodyTable::default().dim, value_parser = whole::<u8>)]
    pub dim: u8,
    /// 3D sphere construction.
    #[arg(long, value_enum, default_value_t = SphereArg::Octa)]
    pub sphere: SphereArg,
    /// Octahedron subdivision level (3D, `--sphere octa`), 0 to 7.
    #[arg(long, default_value_t = TwoLayerBodyTable::default().level, value_parser = whole::<u32>)]
    pub level: u32,
    /// UV sphere meridians (3D, `--sphere uv`), 3 to 4096.
    #[arg(long, default_value_t = TwoLayerBodyTable::default().slices, value_parser = parse_whole)]
    pub slices: usize,
    /// UV sphere latitude bands (3D, `--sphere uv`), 2 to 4096.
    #[arg(long, default_value_t = TwoLayerBodyTable::default().stacks, value_parser = parse_whole)]
    pub stacks: usize,
    /// Particles per layer (2D), 3 to 1e6.
    #[arg(long, default_value_t = TwoLayerBodyTable::default().particles, value_parser = parse_whole)]
    pub particles: usize,
    /// Rest length of the spring (1D, m), in (0, 1e3].
    #[arg(long, default_value_t = TwoLayerBodyTable::default().length, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub length: f64,
    /// Inner layer radius (m), in (0, 1e3].
    #[arg(long, default_value_t = TwoLayerBodyTable::default().inner_radius, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub inner_radius: f64,
    /// Outer layer radius (m), in (0, 1e3].
    #[arg(long, default_value_t = TwoLayerBodyTable::default().outer_radius, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub outer_radius: f64,
    /// Mass of each inner particle (kg), in [1e-9, 1e6] (a lighter particle on a stiff spring
    /// has no stable explicit step).
    #[arg(long, default_value_t = TwoLayerBodyTable::default().inner_mass, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub inner_mass: f64,
    /// Mass of each outer particle (kg; the free particle in 1D), in [1e-9, 1e6] (a lighter particle on a stiff spring
    /// has no stable explicit step).
    #[arg(long, default_value_t = TwoLayerBodyTable::default().outer_mass, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub outer_mass: f64,
    /// Structural spring stiffness (N/m), in [0, 1e9].
    #[arg(long, default_value_t = TwoLayerBodyTable::default().k_structural, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub k_structural: f64,
    /// Radius spring stiffness (N/m), in [0, 1e9].
    #[arg(long, default_value_t = TwoLayerBodyTable::default().k_radius, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub k_radius: f64,
    /// Shear spring stiffness, left and right (N/m), in [0, 1e9].
    #[arg(long, default_value_t = TwoLayerBodyTable::default().k_shear, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub k_shear: f64,
    /// Left shear spring stiffness (N/m), overrides --k-shear; in [0, 1e9].
    #[arg(long, allow_hyphen_values = true, value_parser = parse_real)]
    pub k_shear_left: Option<f64>,
    /// Right shear spring stiffness (N/m), overrides --k-shear; in [0, 1e9].
    #[arg(long, allow_hyphen_values = true, value_parser = parse_real)]
    pub k_shear_right: Option<f64>,
    /// Damping of every spring type (N s/m), in [0, 1e6].
    #[arg(long, default_value_t = TwoLayerBodyTable::default().damping, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub damping: f64,
    /// Damping of the structural springs (N s/m), overrides --damping; in [0, 1e6].
    #[arg(long, allow_hyphen_values = true, value_parser = parse_real)]
    pub damping_structural: Option<f64>,
    /// Damping of the radius springs (N s/m), overrides --damping; in [0, 1e6].
    #[arg(long, allow_hyphen_values = true, value_parser = parse_real)]
    pub damping_radius: Option<f64>,
    /// Damping of the shear springs (N s/m), overrides --damping; in [0, 1e6].
    #[arg(long, allow_hyphen_values = true, value_parser = parse_real)]
    pub damping_shear: Option<f64>,
    /// Initial gas pressure of the outer layer at its rest volume (Pa; N/m in 2D), in [0, 1e7].
    #[arg(long, default_value_t = TwoLayerGas::default().pressure, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub pressure: f64,
    /// Initial gas pressure of the inner layer at its rest volume (Pa; N/m in 2D), in [0, 1e7].
    #[arg(long, default_value_t = TwoLayerGas::default().inner_pressure, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub inner_pressure: f64,
    /// Gravitational acceleration (m/s^2) pulling along -z (3D), -y (2D), -x (1D), in [-1e3, 1e3] (100 g).
    #[arg(long, default_value_t = TwoLayerRun::default().gravity, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub gravity: f64,
    /// Side of the cubic collision box centred on the body at rest (m), in (0, 1e4].
    #[arg(long = "box", default_value_t = TwoLayerRun::default().box_size, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub box_size: f64,
    /// No collision box.
    #[arg(long)]
    pub no_box: bool,
    /// Coefficient of restitution [0, 1] of the walls and of the inner layer against the outer, in [0, 1].
    #[arg(long, default_value_t = TwoLayerRun::default().restitution, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub restitution: f64,
    /// Normalise spring forces by valence (Song 2009, Sec. 3.5.3).
    #[arg(long)]
    pub valence_normalization: bool,
    /// Integrator: euler | midpoint | rk4 | symplectic.
    #[arg(long, default_value_t = TwoLayerRun::default().integrator, value_parser = parse_method)]
    pub integrator: ExplicitMethod,
    /// Time step (s), in (0, 0.1]: the explicit integrators are stable only far below a tenth of a second for any spring this tool builds (the default is 5e-4 s).
    #[arg(long, default_value_t = TwoLayerRun::default().dt, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub dt: f64,
    /// Number of steps, 0 to 1e8.
    #[arg(long, default_value_t = TwoLayerRun::default().steps, value_parser = parse_whole)]
    pub steps: usize,
    /// Pin particles (repeatable): `indices:1,2,3`, `file:PATH`, `below:AXIS:VALUE`,
    /// `above:AXIS:VALUE` or `box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX` (m, the rest positions), hard
    /// (they do not move at all) or with `@K` as zero-length springs of K N/m to the rest
    /// position, as `balloon inflate --pin`.
    #[arg(long, value_parser = parse_pin)]
    pub pin: Vec<Pin>,
    /// Stiffness of the --pin anchors without their own `@K`, N/m, in (0, 1e12]; absent: hard
    /// pins. The springs are integrated explicitly like the body's: K dt^2 / m well below 1.
    #[arg(long, value_parser = parse_real)]
    pub pin_stiffness: Option<f64>,
    /// A load (repeatable): `gravity=GX,GY,GZ` (m/s^2, each particle's mass times g, added to
    /// --gravity), `force=FX,FY,FZ;on=SELECTOR` (N per particle; `per=total` spreads it over the
    /// selection) or `grab=X,Y,Z;on=SELECTOR;stiffness=K` (pulled toward the point, N/m per
    /// particle); `start=S;end=S` schedule it (s).
    #[arg(long, value_parser = parse_load)]
    pub load: Vec<Load>,
    /// Drag ("mouse") target `X,Y,Z` (m), optionally active only in a time window `@T0:T1` (s).
    #[arg(long, allow_hyphen_values = true)]
    pub drag: Option<String>,
    /// Drag spring stiffness (N/m), in [0, 1e9].
    #[arg(long, default_value_t = TwoLayerRun::default().drag_stiffness, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub drag_stiffness: f64,
    /// Drag spring damping (N s/m), in [0, 1e6].
    #[arg(long, default_value_t = TwoLayerRun::default().drag_damping, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub drag_damping: f64,
    /// Output folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the files of an earlier run in --out (frames, records, pictures: only files
    /// this program writes); without it, a folder holding them is refused.
    #[arg(long)]
    pub overwrite: bool,
    /// Write a frame every N steps (0: only the first and last), 0 to 1e8.
    #[arg(long, default_value_t = TwoLayerScenario::default().output.frame_every, value_parser = parse_whole)]
    pub frame_every: usize,
    /// Frame file format: obj, ply, or vtk (`.vtp` frames with velocity, speed, and per-face
    /// stretch and max_stretch against the initial shape, listed in `series.pvd`).
    #[arg(long, value_enum, default_value_t = FrameFormat::Obj)]
    pub format: FrameFormat,
    /// Pictures (dimensions 2 and 3): --render, --gif, --pov, --color, --image-size.
    #[command(flatten)]
    pub pictures: PictureArgs,
    /// Print the summary as one JSON line (the last stdout line).
    #[arg(long)]
    pub json: bool,
}

fn parse_method(s: &str) -> Result<ExplicitMethod, String> {
    s.parse::<ExplicitMethod>().map_err(|e| e.to_string())
}

impl TwoLayerArgs {
    /// The scenario of these flags (every key, given or default).
    pub fn scenario(&self) -> TwoLayerScenario {
        let mut s = TwoLayerScenario {
            body: TwoLayerBodyTable {
                dim: self.dim,
                sphere: self.sphere.into(),
                level: self.level,
                slices: self.slices,
                stacks: self.stacks,
                particles: self.particles,
                length: self.length,
                inner_radius: self.inner_radius,
                outer_radius: self.outer_radius,
                inner_mass: self.inner_mass,
                outer_mass: self.outer_mass,
                k_structural: self.k_structural,
                k_radius: self.k_radius,
                k_shear: self.k_shear,
                k_shear_left: self.k_shear_left,
                k_shear_right: self.k_shear_right,
                damping: self.damping,
                damping_structural: self.damping_structural,
                damping_radius: self.damping_radius,
                damping_shear: self.damping_shear,
                valence_normalization: self.valence_normalization,
            },
            gas: TwoLayerGas {
                pressure: self.pressure,
                inner_pressure: self.inner_pressure,
            },
            run: TwoLayerRun {
                gravity: self.gravity,
                box_size: self.box_size,
                no_box: self.no_box,
                restitution: self.restitution,
                integrator: self.integrator,
                dt: self.dt,
                steps: self.steps,
                drag: self.drag.clone(),
                drag_stiffness: self.drag_stiffness,
                drag_damping: self.drag_damping,
                pin_stiffness: self.pin_stiffness,
            },
            anchors: self.pin.clone(),
            loads: self.load.clone(),
            ..TwoLayerScenario::default()
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

/// Runs `balloon two-layer` (`matches`: the subcommand's, for the values as typed).
pub fn run(args: &TwoLayerArgs, matches: &clap::ArgMatches) -> Result<()> {
    let call = Invocation::of(Scenario::TwoLayer(args.scenario()), matches)?;
    let Scenario::TwoLayer(s) = &call.scenario else {
        unreachable!("a two-layer scenario")
    };
    balloon_run::jobs::two_layer::run(s, Some(&call.record()), false).map(drop)
}

/// Builds the simulation of `balloon two-layer` for `args` (checked first): the body, its
/// springs, gases, gravity and box, the integrator and the hard anchors. Writes nothing.
pub fn build(args: &TwoLayerArgs) -> Result<TwoLayerSimulation> {
    let s = args.scenario();
    s.validate().map_err(job_error)?;
    Ok(s.build()?)
}

/// Runs the job of `balloon two-layer` for `args` (checks, build, the output folder, the steps
/// with the drag, the summary) and returns the summary with the final simulation; `quiet`
/// prints nothing. No scenario is recorded.
pub fn execute(args: &TwoLayerArgs, quiet: bool) -> Result<Finished<TwoLayerSimulation>> {
    let s = args.scenario();
    s.validate().map_err(job_error)?;
    balloon_run::jobs::two_layer::run(&s, None, quiet)
}
