//! `balloon two-layer`: a two-layer elastic object (seed 004, Song) in 1D, 2D or 3D, stepped
//! with explicit Euler, midpoint, RK4 or symplectic Euler.
//!
//! Output folder (`--out DIR`): `frame_NNNNN.obj` every `--frame-every` steps (3D: outer and
//! inner surface; 2D: the triangles between the layers; 1D: the two particles),
//! `stats.jsonl` (one line per step, flushed, so a run that blows up leaves a readable file)
//! and `summary.json` (also written when the run fails, with the error). `--json` prints the
//! summary as the last stdout line. `--format vtk` writes `.vtp` frames with fields and
//! `series.pvd`; `--render`, `--gif` and `--pov` write pictures (see `output.rs`).
//!
//! `--pressure` and `--inner-pressure` are the *initial* gas pressures (Pa; N/m in 2D) at the
//! rest volumes; the gas amount is fixed from them (`nRT = P0 V0`) and the pressure then follows
//! `P = nRT / V`.

use crate::output::{
    ColorField, Frame, FrameFormat, OutputDir, PictureArgs, PictureStyle, check_picture_args,
};
use crate::params::{End::Closed, End::Open, MAX_STEPS, count, real};
use crate::run::{Finished, FramePolicy, RunHooks, RunPlan, RunRecord, run_simulation};
use anyhow::{Context, Result, bail};
use balloon::two_layer::{
    AxisBox, DragTarget, ExplicitMethod, SpringKind, TwoLayerBody, TwoLayerSimulation,
    TwoLayerStats,
};
use balloon_render::{Camera, Projection, UpAxis};
use nalgebra::{Point3, Vector3};
use serde::Serialize;
use std::path::PathBuf;

/// Sphere construction in 3D.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SphereArg {
    /// Subdivided octahedron (`--level`), seed Sec. 3.5.2.
    Octa,
    /// UV sphere (`--slices`, `--stacks`), seed Sec. 3.5.1.
    Uv,
}

/// Arguments of `balloon two-layer`.
#[derive(Debug, clap::Args)]
pub struct TwoLayerArgs {
    /// Dimension: 1 (hanging spring), 2 (two-layer circle), 3 (two-layer sphere).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(1..=3))]
    pub dim: u8,
    /// 3D sphere construction.
    #[arg(long, value_enum, default_value_t = SphereArg::Octa)]
    pub sphere: SphereArg,
    /// Octahedron subdivision level (3D, `--sphere octa`), 0 to 7.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(0..=7))]
    pub level: u32,
    /// UV sphere meridians (3D, `--sphere uv`), 3 to 4096.
    #[arg(long, default_value_t = 16, value_parser = count(3, 4096))]
    pub slices: usize,
    /// UV sphere latitude bands (3D, `--sphere uv`), 2 to 4096.
    #[arg(long, default_value_t = 12, value_parser = count(2, 4096))]
    pub stacks: usize,
    /// Particles per layer (2D), 3 to 1e6.
    #[arg(long, default_value_t = 24, value_parser = count(3, 1_000_000))]
    pub particles: usize,
    /// Rest length of the spring (1D, m), in (0, 1e3].
    #[arg(long, default_value_t = 0.5, allow_hyphen_values = true,
          value_parser = real(Open(0.0), Closed(1e3)))]
    pub length: f64,
    /// Inner layer radius (m), in (0, 1e3].
    #[arg(long, default_value_t = 0.8, allow_hyphen_values = true,
          value_parser = real(Open(0.0), Closed(1e3)))]
    pub inner_radius: f64,
    /// Outer layer radius (m), in (0, 1e3].
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true,
          value_parser = real(Open(0.0), Closed(1e3)))]
    pub outer_radius: f64,
    /// Mass of each inner particle (kg), in [1e-9, 1e6] (a lighter particle on a stiff spring
    /// has no stable explicit step).
    #[arg(long, default_value_t = 0.01, allow_hyphen_values = true,
          value_parser = real(Closed(1e-9), Closed(1e6)))]
    pub inner_mass: f64,
    /// Mass of each outer particle (kg; the free particle in 1D), in [1e-9, 1e6] (a lighter particle on a stiff spring
    /// has no stable explicit step).
    #[arg(long, default_value_t = 0.01, allow_hyphen_values = true,
          value_parser = real(Closed(1e-9), Closed(1e6)))]
    pub outer_mass: f64,
    /// Structural spring stiffness (N/m), in [0, 1e9].
    #[arg(long, default_value_t = 100.0, allow_hyphen_values = true,
          value_parser = real(Closed(0.0), Closed(1e9)))]
    pub k_structural: f64,
    /// Radius spring stiffness (N/m), in [0, 1e9].
    #[arg(long, default_value_t = 50.0, allow_hyphen_values = true,
          value_parser = real(Closed(0.0), Closed(1e9)))]
    pub k_radius: f64,
    /// Shear spring stiffness, left and right (N/m), in [0, 1e9].
    #[arg(long, default_value_t = 50.0, allow_hyphen_values = true,
          value_parser = real(Closed(0.0), Closed(1e9)))]
    pub k_shear: f64,
    /// Left shear spring stiffness (N/m), overrides --k-shear; in [0, 1e9].
    #[arg(long, allow_hyphen_values = true, value_parser = real(Closed(0.0), Closed(1e9)))]
    pub k_shear_left: Option<f64>,
    /// Right shear spring stiffness (N/m), overrides --k-shear; in [0, 1e9].
    #[arg(long, allow_hyphen_values = true, value_parser = real(Closed(0.0), Closed(1e9)))]
    pub k_shear_right: Option<f64>,
    /// Damping of every spring type (N s/m), in [0, 1e6].
    #[arg(long, default_value_t = 0.1, allow_hyphen_values = true,
          value_parser = real(Closed(0.0), Closed(1e6)))]
    pub damping: f64,
    /// Damping of the structural springs (N s/m), overrides --damping; in [0, 1e6].
    #[arg(long, allow_hyphen_values = true, value_parser = real(Closed(0.0), Closed(1e6)))]
    pub damping_structural: Option<f64>,
    /// Damping of the radius springs (N s/m), overrides --damping; in [0, 1e6].
    #[arg(long, allow_hyphen_values = true, value_parser = real(Closed(0.0), Closed(1e6)))]
    pub damping_radius: Option<f64>,
    /// Damping of the shear springs (N s/m), overrides --damping; in [0, 1e6].
    #[arg(long, allow_hyphen_values = true, value_parser = real(Closed(0.0), Closed(1e6)))]
    pub damping_shear: Option<f64>,
    /// Initial gas pressure of the outer layer at its rest volume (Pa; N/m in 2D), in [0, 1e7].
    #[arg(long, default_value_t = 50.0, allow_hyphen_values = true,
          value_parser = real(Closed(0.0), Closed(1e7)))]
    pub pressure: f64,
    /// Initial gas pressure of the inner layer at its rest volume (Pa; N/m in 2D), in [0, 1e7].
    #[arg(long, default_value_t = 25.0, allow_hyphen_values = true,
          value_parser = real(Closed(0.0), Closed(1e7)))]
    pub inner_pressure: f64,
    /// Gravitational acceleration (m/s^2) pulling along -z (3D), -y (2D), -x (1D), in [-1e3, 1e3] (100 g).
    #[arg(long, default_value_t = 9.81, allow_hyphen_values = true,
          value_parser = real(Closed(-1e3), Closed(1e3)))]
    pub gravity: f64,
    /// Side of the cubic collision box centred on the body at rest (m), in (0, 1e4].
    #[arg(long = "box", default_value_t = 4.0, allow_hyphen_values = true,
          value_parser = real(Open(0.0), Closed(1e4)))]
    pub box_size: f64,
    /// No collision box.
    #[arg(long)]
    pub no_box: bool,
    /// Coefficient of restitution [0, 1] of the walls and of the inner layer against the outer, in [0, 1].
    #[arg(long, default_value_t = 0.5, allow_hyphen_values = true,
          value_parser = real(Closed(0.0), Closed(1.0)))]
    pub restitution: f64,
    /// Normalise spring forces by valence (seed Sec. 3.5.3).
    #[arg(long)]
    pub valence_normalization: bool,
    /// Integrator: euler | midpoint | rk4 | symplectic.
    #[arg(long, default_value = "rk4", value_parser = parse_method)]
    pub integrator: ExplicitMethod,
    /// Time step (s), in (0, 0.1]: the explicit integrators are stable only far below a tenth of a second for any spring this tool builds (the default is 5e-4 s).
    #[arg(long, default_value_t = 5e-4, allow_hyphen_values = true,
          value_parser = real(Open(0.0), Closed(0.1)))]
    pub dt: f64,
    /// Number of steps, 0 to 1e8.
    #[arg(long, default_value_t = 2000, value_parser = count(0, MAX_STEPS))]
    pub steps: usize,
    /// Pin particles (repeatable): `indices:1,2,3`, `file:PATH`, `below:AXIS:VALUE`,
    /// `above:AXIS:VALUE` or `box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX` (m, the rest positions), hard
    /// (they do not move at all) or with `@K` as zero-length springs of K N/m to the rest
    /// position, as `balloon inflate --pin`.
    #[arg(long, value_parser = crate::selection::parse_pin)]
    pub pin: Vec<crate::selection::Pin>,
    /// Stiffness of the --pin anchors without their own `@K`, N/m, in (0, 1e12]; absent: hard
    /// pins. The springs are integrated explicitly like the body's: K dt^2 / m well below 1.
    #[arg(long, value_parser = crate::selection::stiffness)]
    pub pin_stiffness: Option<f64>,
    /// A load (repeatable): `gravity=GX,GY,GZ` (m/s^2, each particle's mass times g, added to
    /// --gravity), `force=FX,FY,FZ;on=SELECTOR` (N per particle; `per=total` spreads it over the
    /// selection) or `grab=X,Y,Z;on=SELECTOR;stiffness=K` (pulled toward the point, N/m per
    /// particle); `start=S;end=S` schedule it (s).
    #[arg(long, value_parser = crate::selection::parse_load)]
    pub load: Vec<crate::selection::Load>,
    /// Drag ("mouse") target `X,Y,Z` (m), optionally active only in a time window `@T0:T1` (s).
    #[arg(long, allow_hyphen_values = true)]
    pub drag: Option<String>,
    /// Drag spring stiffness (N/m), in [0, 1e9].
    #[arg(long, default_value_t = 10.0, allow_hyphen_values = true,
          value_parser = real(Closed(0.0), Closed(1e9)))]
    pub drag_stiffness: f64,
    /// Drag spring damping (N s/m), in [0, 1e6].
    #[arg(long, default_value_t = 0.1, allow_hyphen_values = true,
          value_parser = real(Closed(0.0), Closed(1e6)))]
    pub drag_damping: f64,
    /// Output folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the files of an earlier run in --out (frames, records, pictures: only files
    /// this program writes); without it, a folder holding them is refused.
    #[arg(long)]
    pub overwrite: bool,
    /// Write a frame every N steps (0: only the first and last), 0 to 1e8.
    #[arg(long, default_value_t = 20, value_parser = count(0, MAX_STEPS))]
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
    /// The resolved scenario of this run (`crate::cmd_run::record`), written to
    /// `OUT/scenario.toml`; not a flag.
    #[arg(skip)]
    pub scenario_record: Option<String>,
}

fn parse_method(s: &str) -> Result<ExplicitMethod, String> {
    s.parse::<ExplicitMethod>().map_err(|e| e.to_string())
}

/// A parsed `--drag X,Y,Z[@T0:T1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct DragSpec {
    point: Point3<f64>,
    window: (f64, f64),
}

fn parse_drag(s: &str) -> Result<DragSpec> {
    let (pt, window) = match s.split_once('@') {
        Some((p, w)) => (p, Some(w)),
        None => (s, None),
    };
    let c: Vec<f64> = pt
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--drag `{s}`: the point must be X,Y,Z in metres"))?;
    if c.len() != 3 || c.iter().any(|v| !v.is_finite()) {
        bail!("--drag `{s}`: the point must be three finite numbers X,Y,Z");
    }
    let window = match window {
        None => (0.0, f64::INFINITY),
        Some(w) => {
            let (a, b) = w
                .split_once(':')
                .with_context(|| format!("--drag `{s}`: the time window must be @T0:T1"))?;
            let t0: f64 = a
                .trim()
                .parse()
                .with_context(|| format!("--drag `{s}`: bad start time `{a}`"))?;
            let t1: f64 = b
                .trim()
                .parse()
                .with_context(|| format!("--drag `{s}`: bad end time `{b}`"))?;
            if !(t0.is_finite() && t1 >= t0) {
                bail!("--drag `{s}`: need finite T0 <= T1");
            }
            (t0, t1)
        }
    };
    Ok(DragSpec {
        point: Point3::new(c[0], c[1], c[2]),
        window,
    })
}

/// The summary of a run (`summary.json`, and the `--json` line).
#[derive(Debug, Serialize)]
struct Summary {
    status: &'static str,
    error: Option<String>,
    dim: u8,
    integrator: ExplicitMethod,
    particles: usize,
    springs: usize,
    steps: usize,
    dt: f64,
    time: f64,
    final_volume_outer: f64,
    final_volume_inner: f64,
    energy_initial: f64,
    energy_final: f64,
    work_done: f64,
    min_height: f64,
    escaped_particles: usize,
    mean_step_ms: f64,
    steps_per_second: f64,
    frames: usize,
}

fn body_from(args: &TwoLayerArgs) -> Result<TwoLayerBody> {
    let body = match args.dim {
        1 => TwoLayerBody::line(args.length),
        2 => TwoLayerBody::circle(args.particles),
        _ => match args.sphere {
            SphereArg::Octa => TwoLayerBody::octahedron_sphere(args.level),
            SphereArg::Uv => TwoLayerBody::uv_sphere(args.slices, args.stacks),
        },
    };
    let d = args.damping;
    let collision_box = if args.no_box {
        None
    } else {
        let h = 0.5 * args.box_size;
        Some(
            AxisBox::centered(Point3::origin(), Vector3::new(h, h, h))
                .with_context(|| format!("--box {}", args.box_size))?,
        )
    };
    Ok(body
        .with_radii(args.inner_radius, args.outer_radius)
        .with_masses(args.inner_mass, args.outer_mass)
        .with_spring(
            SpringKind::Structural,
            args.k_structural,
            args.damping_structural.unwrap_or(d),
        )
        .with_spring(
            SpringKind::Radius,
            args.k_radius,
            args.damping_radius.unwrap_or(d),
        )
        .with_spring(
            SpringKind::ShearLeft,
            args.k_shear_left.unwrap_or(args.k_shear),
            args.damping_shear.unwrap_or(d),
        )
        .with_spring(
            SpringKind::ShearRight,
            args.k_shear_right.unwrap_or(args.k_shear),
            args.damping_shear.unwrap_or(d),
        )
        .with_pressure(args.pressure, args.inner_pressure)
        .with_gravity(args.gravity)
        .with_box(collision_box)
        .with_restitution(args.restitution)
        .with_valence_normalization(args.valence_normalization))
}

const STYLE_FIELDS: &[ColorField] = &[ColorField::Speed, ColorField::Stretch];

/// 3D: perspective with +z up (gravity along -z); 2D: the xy plane seen from +z, +y up.
fn style(dim: u8) -> PictureStyle {
    let mut s = PictureStyle::new("two-layer", UpAxis::Z, ColorField::Speed, STYLE_FIELDS);
    if dim == 2 {
        s.camera = Camera {
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            up: UpAxis::Y,
            projection: Projection::Orthographic,
        };
    } else {
        // Both layers are closed, outward-oriented spheres.
        s.closed = true;
    }
    s
}

/// All particles with the drawing triangles (3D: outer and inner surface; 2D: the band between
/// the layers), velocity, speed, and stretch against the initial positions `rest`.
fn layer_frame(sim: &TwoLayerSimulation, rest: &[f64], step: usize) -> Result<Frame> {
    Frame::new(
        step,
        sim.time(),
        sim.positions().to_vec(),
        sim.model().draw_triangles(),
    )
    .with_velocity(sim.velocities().to_vec())?
    .with_stretch(rest)
}

/// What `two-layer` adds to the shared run loop: the drag window (`--drag`) before each step, the
/// layer frames and the summary (also after a failure, with the error).
struct TwoLayerHooks<'a> {
    args: &'a TwoLayerArgs,
    drag: Option<DragSpec>,
    /// Spring anchors and loads (`--pin ...@K`, `--load`).
    loads: crate::selection::TwoLayerLoads,
    /// Initial positions, the reference of the stretch field.
    rest: Vec<f64>,
}

impl RunHooks<TwoLayerSimulation> for TwoLayerHooks<'_> {
    type Summary = Summary;

    fn scenario(&self) -> Option<String> {
        self.args.scenario_record.clone()
    }

    fn frame(&self, sim: &TwoLayerSimulation, step: usize) -> Result<Frame> {
        layer_frame(sim, &self.rest, step)
    }

    fn before_step(&mut self, sim: &mut TwoLayerSimulation) -> Result<()> {
        self.loads.before_step(sim)?;
        let Some(d) = &self.drag else {
            return Ok(());
        };
        let active = sim.forces().drag().is_some();
        let t = sim.time();
        let inside = t >= d.window.0 && t <= d.window.1;
        if inside && !active {
            sim.set_drag(Some(DragTarget {
                point: d.point,
                stiffness: self.args.drag_stiffness,
                damping: self.args.drag_damping,
                rest_length: 0.0,
            }))?;
        } else if !inside && active {
            sim.set_drag(None)?;
        }
        Ok(())
    }

    fn summary(&self, sim: &TwoLayerSimulation, run: &RunRecord<TwoLayerStats>) -> Summary {
        let args = self.args;
        let failed = run.failure.is_some();
        let last = run.last.as_ref().map_or_else(|| sim.stats(), |s| s.detail);
        let taken = run.steps.max(1);
        Summary {
            status: match (failed, run.interrupted.is_some()) {
                (true, _) => "blew_up",
                (false, true) => "interrupted",
                (false, false) => "ok",
            },
            error: run.failure.as_ref().map(|e| e.to_string()),
            dim: args.dim,
            integrator: args.integrator,
            particles: sim.model().num_particles(),
            springs: sim.model().springs.len(),
            steps: run.steps,
            dt: args.dt,
            time: sim.time(),
            final_volume_outer: last.volume_outer,
            final_volume_inner: last.volume_inner,
            energy_initial: sim.energy_initial(),
            energy_final: last.total,
            work_done: sim.work_done(),
            min_height: last.min_height,
            escaped_particles: if failed { 0 } else { sim.escaped_particles() },
            mean_step_ms: 1e3 * run.step_seconds / taken as f64,
            steps_per_second: if run.step_seconds > 0.0 {
                taken as f64 / run.step_seconds
            } else {
                0.0
            },
            frames: run.frames,
        }
    }

    fn print(
        &self,
        summary: &Summary,
        _out: Option<&OutputDir>,
        w: &mut dyn std::io::Write,
    ) -> std::io::Result<()> {
        writeln!(
            w,
            "two-layer {}D ({} particles, {} springs), {} x {:e} s with {}: outer volume {:.6}, inner {:.6}, energy {:.6e} -> {:.6e} J, min height {:.4} m, {} escaped, {:.3} ms/step",
            summary.dim,
            summary.particles,
            summary.springs,
            summary.steps,
            summary.dt,
            summary.integrator,
            summary.final_volume_outer,
            summary.final_volume_inner,
            summary.energy_initial,
            summary.energy_final,
            summary.min_height,
            summary.escaped_particles,
            summary.mean_step_ms
        )
    }
}

/// Runs the subcommand.
pub fn run(args: TwoLayerArgs) -> Result<()> {
    execute(&args, false).map(drop)
}

/// Builds the simulation of `balloon two-layer` for `args` (the body, its springs, gases,
/// gravity and box, and the integrator) exactly as the command does. Writes nothing.
pub fn build(args: &TwoLayerArgs) -> Result<TwoLayerSimulation> {
    let body = body_from(args)?;
    let mut sim = body.simulate(args.integrator, args.dt)?;
    crate::selection::fix_two_layer(&mut sim, &args.pin, args.pin_stiffness)?;
    Ok(sim)
}

/// Runs the job of `balloon two-layer` for `args` (checks, [`build`], the output folder, the
/// steps with the drag, the summary) and returns the summary with the final simulation; `quiet`
/// prints nothing.
pub fn execute(args: &TwoLayerArgs, quiet: bool) -> Result<Finished<TwoLayerSimulation>> {
    let render_spec = check_picture_args(&args.pictures, args.out.as_deref(), &style(args.dim))?;
    if let Some(dir) = &args.out {
        crate::output::prepare_out_dir(dir, args.overwrite)?;
    }
    if args.dim == 1 && (render_spec.is_some() || args.pictures.gif || args.pictures.pov) {
        bail!("--render, --gif and --pov need a surface: use --dim 2 or 3 (1D has two particles)");
    }
    let drag = args.drag.as_deref().map(parse_drag).transpose()?;
    let mut sim = build(args)?;
    let rest = sim.positions().to_vec();
    let out = match &args.out {
        Some(dir) => Some(OutputDir::create(dir, args.format)?.with_pictures(
            &args.pictures,
            render_spec,
            style(args.dim),
        )?),
        None => None,
    };
    if let (Some(o), Some(text)) = (&out, &args.scenario_record) {
        o.write_text("scenario.toml", text)?;
    }
    let plan = RunPlan {
        steps: args.steps,
        frames: FramePolicy {
            every: args.frame_every,
            last: true,
        },
        json: args.json,
        quiet,
    };
    let loads =
        crate::selection::two_layer_loads(&mut sim, &args.pin, args.pin_stiffness, &args.load)?;
    let mut hooks = TwoLayerHooks {
        args,
        drag,
        loads,
        rest,
    };
    let summary = run_simulation(&mut sim, &mut hooks, &plan, out)?;
    Ok(Finished {
        summary: Some(summary),
        sim,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drag_spec_parses_point_and_window() {
        let d = parse_drag("1, -2.5,3").unwrap();
        assert_eq!(d.point, Point3::new(1.0, -2.5, 3.0));
        assert_eq!(d.window, (0.0, f64::INFINITY));
        let d = parse_drag("0,0,2@0.1:0.5").unwrap();
        assert_eq!(d.window, (0.1, 0.5));
        for bad in ["1,2", "a,b,c", "1,2,3@0.5", "1,2,3@0.5:0.1", "1,2,nan"] {
            assert!(parse_drag(bad).is_err(), "{bad} should not parse");
        }
    }
}
