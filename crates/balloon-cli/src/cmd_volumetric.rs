//! `balloon volumetric [MESH|builtin]`: a volume-conserving impulse-based body generated from a
//! triangle soup (seed 003, Diziol, Bender and Bayer), optionally in the Fig. 4 drop-sphere scene.
//!
//! Output folder (`--out DIR`): `input_soup.obj` (the soup as read and scaled), `lattice.vtk` (the rest tetrahedral lattice with per-cell rest
//! volumes and per-particle masses, for ParaView), `frame_NNNNN.obj` (the embedded soup, deformed
//! with the lattice, every `--frame-every` steps), `lattice_NNNNN.vtk` with `--lattice-frames`,
//! `stats.jsonl` (one line per step, flushed) and `summary.json`. In the drop-sphere scene, the
//! sphere and the floor go beside each frame as `sphere_NNNNN.<ext>` and `floor.<ext>` (parts 1
//! and 2 of `series.pvd` with VTK) and into the pictures (docs/outputs.md). `--json` prints the summary as
//! the last stdout line. `--format vtk` writes `.vtp` frames with fields and `series.pvd`;
//! `--render`, `--gif` and `--pov` write pictures (see `output.rs`).

use crate::output::{
    ColorField, Frame, FrameFormat, OutputDir, PictureArgs, PictureStyle, check_picture_args,
};
use crate::params::{End::Closed, End::Open, MAX_STEPS, count, real};
use crate::run::{Finished, FramePolicy, RunHooks, RunPlan, RunRecord, run_simulation};
use anyhow::{Context, Result};
use balloon::volumetric::{
    MassModel, StepStats, VolumetricBody, VolumetricError, VolumetricParams, VolumetricScene,
    VolumetricSimulation,
};
use balloon::{SimulationError, SimulationStats};
use balloon_constraint::cell_volume::{CellCentre, CellCorrection, CellVolumeParams, SpringParams};
use balloon_mesh::TriMesh;
use balloon_mesh::lattice::{
    DEFAULT_TARGET_CELLS, Lattice, LatticeError, LatticeParams, SizingParams, size_lattice,
};
use balloon_render::{Prop, UpAxis};
use nalgebra::{Point3, Vector3};
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

/// Scene choice.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SceneArg {
    /// The body alone (falls freely under gravity).
    Free,
    /// Fig. 4: a rigid sphere falls on the body resting on a floor plane.
    DropSphere,
}

/// Cell-volume correction (`--correction`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Correction {
    /// Scale the cell about its centre (seed 003, Sec. 4).
    Scaling,
    /// Move along the mass-weighted volume gradient.
    Gradient,
}

/// Over-relaxation of the Gauss-Seidel volume sweeps (`--over-relaxation`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Relaxation {
    /// Chosen from the measured convergence rate (`CellVolumeParams::adaptive_relaxation`).
    Adaptive,
    /// A fixed factor `omega` in (0, 2) (1 = the paper).
    Fixed(f64),
}

impl std::str::FromStr for Relaxation {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        if s.trim() == "adaptive" {
            return Ok(Self::Adaptive);
        }
        crate::params::check_real(s, Open(0.0), Open(2.0))
            .map(Self::Fixed)
            .map_err(|e| format!("{e}, or `adaptive`"))
    }
}

impl std::fmt::Display for Relaxation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Adaptive => f.write_str("adaptive"),
            Self::Fixed(omega) => write!(f, "{omega:?}"),
        }
    }
}

/// How the cell constraints are solved (`--volume-solver`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum VolumeSolver {
    /// The paper's Gauss-Seidel sweeps, one cell at a time.
    GaussSeidel,
    /// Newton iterations on all cells at once (sparse Cholesky); gradient correction.
    Global,
}

/// Arguments of `balloon volumetric`.
#[derive(Debug, clap::Args)]
pub struct VolumetricArgs {
    /// Mesh file (.obj, .off, .ply, .stl; any triangle soup), `builtin` (the teddy) or
    /// `builtin:NAME`.
    #[arg(default_value = "builtin")]
    pub mesh: String,
    /// Scale factor applied to the mesh coordinates (to metres), in (0, 1e6].
    #[arg(long, default_value_t = 1.0, value_parser = real(Open(0.0), Closed(1e6)))]
    pub scale: f64,
    /// Affine map applied to the mesh after --scale: 12 comma-separated numbers, a 3x4 matrix
    /// row by row `a11,a12,a13,t1,a21,a22,a23,t2,a31,a32,a33,t3` mapping x to A x + t (m);
    /// A must have a positive determinant (no mirror). E.g. a translation by (0.1, 0, 0) is
    /// `1,0,0,0.1,0,1,0,0,0,0,1,0`. Each number in [-1e6, 1e6].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1,
          value_parser = real(Closed(-1e6), Closed(1e6)))]
    pub transform: Option<Vec<f64>>,
    /// Lattice generator flags (boxed to keep the subcommand enum small).
    #[command(flatten)]
    pub lattice: Box<LatticeArgs>,
    /// Scene.
    #[arg(long, value_enum, default_value_t = SceneArg::DropSphere)]
    pub scene: SceneArg,
    /// Soft diagonal springs (diagonal stiffness = edge stiffness / 20 and diagonal damping =
    /// edge damping / 2, unless given).
    #[arg(long)]
    pub soft_diagonals: bool,
    /// Edge spring stiffness (N/m); default: m / (10 dt^2) with m the particle mass, which keeps
    /// the explicit spring update stable, with the default dt chosen so that the body sags by
    /// about 0.4 % under its weight. In (0, 1e12].
    #[arg(long, value_parser = real(Open(0.0), Closed(1e12)))]
    pub edge_stiffness: Option<f64>,
    /// Diagonal spring stiffness (N/m); default: the edge stiffness (/20 with --soft-diagonals).
    /// In [0, 1e12].
    #[arg(long, value_parser = real(Closed(0.0), Closed(1e12)))]
    pub diagonal_stiffness: Option<f64>,
    /// Edge spring damping (N s/m); default: m / (50 dt), about 3 % of a spring's critical
    /// damping (m / (1000 dt), 0.35 %, let the impact ring through the body until thin parts
    /// inverted). In [0, 1e9].
    #[arg(long, value_parser = real(Closed(0.0), Closed(1e9)))]
    pub damping: Option<f64>,
    /// Diagonal spring damping (N s/m); default: the edge damping (/2 with --soft-diagonals).
    /// In [0, 1e9].
    #[arg(long, value_parser = real(Closed(0.0), Closed(1e9)))]
    pub diagonal_damping: Option<f64>,
    /// Mass density (kg/m^3), in (0, 1e5] (above any solid's: osmium is 2.26e4).
    #[arg(long, default_value_t = 100.0, value_parser = real(Open(0.0), Closed(1e5)))]
    pub density: f64,
    /// Gravity along z (m/s^2), in [-1e3, 1e3] (100 g).
    #[arg(long, default_value_t = -9.81, allow_hyphen_values = true,
          value_parser = real(Closed(-1e3), Closed(1e3)))]
    pub gravity: f64,
    /// Contact restitution, in [0, 1].
    #[arg(long, default_value_t = 0.2, value_parser = real(Closed(0.0), Closed(1.0)))]
    pub restitution: f64,
    /// Relative cell-volume tolerance of the impulse iteration, in (0, 0.1] (a looser one
    /// no longer conserves volume).
    #[arg(long, default_value_t = 1e-10, value_parser = real(Open(0.0), Closed(0.1)))]
    pub tolerance: f64,
    /// Over-relaxation of the Gauss-Seidel volume sweeps: `adaptive` (the default: after 16
    /// plain sweeps, the factor the measured convergence rate suggests, Young's rule, at most
    /// 1.9; `CellVolumeParams::adaptive_relaxation`) or a fixed factor in (0, 2) (1 = the
    /// paper). The global solver has no sweeps: it takes `adaptive` or 1.
    #[arg(long, default_value_t = Relaxation::Adaptive,
          value_parser = clap::value_parser!(Relaxation))]
    pub over_relaxation: Relaxation,
    /// Lumped masses and mass-weighted cell centres instead of equal masses.
    #[arg(long)]
    pub lumped_masses: bool,
    /// Volume correction: `gradient` (the default: along the mass-weighted volume gradient,
    /// never adds kinetic energy to first order; the only one the global solver supports) or
    /// `scaling` (the paper's scaling about the cell centre, Gauss-Seidel only: it adds energy
    /// at an impact, where it inverted cells of the bunny and spot in the drop-sphere scene).
    #[arg(long, value_enum, default_value_t = Correction::Gradient)]
    pub correction: Correction,
    /// Cell-volume solver: `global` (the default: Newton on all cells at once with a sparse
    /// Cholesky solve, a few iterations at any size) or `gauss-seidel` (sweeps one cell at a
    /// time, as in the paper; with the default `--correction gradient --over-relaxation
    /// adaptive` they run the drop-sphere scene on every shared model, at a few hundred sweeps
    /// per step; the paper's exact sweeps, `--correction scaling --over-relaxation 1`, stop at
    /// the 500-sweep limit within 6-35 steps on most of them at the default ~1000 cells).
    #[arg(long, value_enum, default_value_t = VolumeSolver::Global)]
    pub volume_solver: VolumeSolver,
    /// Time step (s), in (0, 0.1]. Default: the step at which the body with the default springs
    /// sags by about 0.4 % under its weight (`VolumetricBody::sag_limited_dt`), at most 5e-4 s:
    /// about 1.8e-4 s for the 0.15 m bunny at 1000 cells, 4.4e-4 s for the 1 m spot.
    #[arg(long, value_parser = real(Open(0.0), Closed(0.1)))]
    pub dt: Option<f64>,
    /// Number of steps, 0 to 1e8.
    #[arg(long, default_value_t = 600, value_parser = count(0, MAX_STEPS))]
    pub steps: usize,
    /// Pin lattice particles, picked by their rest positions (repeatable): `indices:1,2,3`,
    /// `file:PATH`, `below:AXIS:VALUE`, `above:AXIS:VALUE` or `box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX`
    /// (m), with `@K` for springs of K N/m to the rest position instead of a hard pin (a
    /// hard-pinned particle never moves: infinite mass in the springs, contacts and volume
    /// impulses).
    #[arg(long, value_parser = crate::selection::parse_pin)]
    pub pin: Vec<crate::selection::Pin>,
    /// Stiffness of the --pin anchors without their own `@K`, N/m, in (0, 1e12]; absent: hard
    /// pins. Springs act explicitly: K dt^2 / m well below 1 keeps them stable.
    #[arg(long, value_parser = crate::selection::stiffness)]
    pub pin_stiffness: Option<f64>,
    /// A load on the lattice particles (repeatable): `gravity=GX,GY,GZ` (m/s^2, replaces
    /// --gravity while active), `force=FX,FY,FZ;on=SELECTOR` (N per particle; `per=total`
    /// spreads it over the selection) or `grab=X,Y,Z;on=SELECTOR;stiffness=K` (pulled toward
    /// the point, N/m per particle); `start=S;end=S` schedule it (s).
    #[arg(long, value_parser = crate::selection::parse_load)]
    pub load: Vec<crate::selection::Load>,
    /// Output folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the files of an earlier run in --out (frames, records, pictures: only files
    /// this program writes); without it, a folder holding them is refused.
    #[arg(long)]
    pub overwrite: bool,
    /// Write a surface frame every N steps, 1 to 1e8.
    #[arg(long, default_value_t = 20, value_parser = count(1, MAX_STEPS))]
    pub frame_every: usize,
    /// Also write the deformed lattice as VTK with each frame.
    #[arg(long)]
    pub lattice_frames: bool,
    /// Surface frame format: obj, ply, or vtk (`.vtp` frames of the embedded surface with
    /// velocity, speed, stretch and max_stretch, listed with their times in `series.pvd`).
    #[arg(long, value_enum, default_value_t = FrameFormat::Obj)]
    pub format: FrameFormat,
    /// Pictures: --render, --gif, --pov, --color, --image-size.
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

/// Largest `--resolution` (and `--voxels-per-cell`): bounds the voxel grid (resolution^3
/// voxels at most) before anything is built.
const MAX_RESOLUTION: usize = 200;

/// Flags of the soup -> lattice generator (seed 003, Sec. 3).
#[derive(Debug, clap::Args)]
pub struct LatticeArgs {
    /// Voxels along the longest side of the bounding box, 4 to 200: the voxel grid holds up to
    /// resolution^3 voxels (at 200 the teddy's lattice took 3.8 s and 140 MB; 400 took 26 s
    /// and 920 MB). Default: chosen for `--cells`.
    #[arg(long, conflicts_with = "cells", value_parser = count(4, MAX_RESOLUTION))]
    pub resolution: Option<usize>,
    /// Size the lattice for about this many cells, 1 to 100000 (the resolution is searched so
    /// that the body has 0.8 to 1.25 times as many, raised further while a thin part of the
    /// model lies outside the lattice). Default 1000 when `--resolution` is not given.
    #[arg(long, value_parser = count(1, 100_000))]
    pub cells: Option<usize>,
    /// Voxels along one side of a lattice cell, 1 to 200 (at most --resolution).
    #[arg(long, default_value_t = 3, value_parser = count(1, MAX_RESOLUTION))]
    pub voxels_per_cell: usize,
    /// Ray directions in the inside/outside vote, 1 to 26 (6 axes, 14 with body diagonals,
    /// 26 all).
    #[arg(long, default_value_t = 14, value_parser = count(1, 26))]
    pub rays: usize,
    /// Distance band in voxels (P = 1 - |d| / band), in [1.5, 64].
    #[arg(long, default_value_t = 4.0, value_parser = real(Closed(1.5), Closed(64.0)))]
    pub band_voxels: f64,
    /// P_in: a ray enters/leaves where P > P_in and dP/dv > 0; in (0, 1).
    #[arg(long, default_value_t = 0.8, value_parser = real(Open(0.0), Open(1.0)))]
    pub p_in: f64,
    /// P_subs: the next change needs P < P_subs with dP/dv < 0 first; in (0, 1), at most P_in.
    #[arg(long, default_value_t = 0.6, value_parser = real(Open(0.0), Open(1.0)))]
    pub p_subs: f64,
    /// Pseudo-density threshold m(V)/M(V) for keeping a cell, in [0, 1).
    #[arg(long, default_value_t = 0.5, value_parser = real(Closed(0.0), Open(1.0)))]
    pub density_threshold: f64,
    /// Hole-filling rounds, 0 to 1000.
    #[arg(long, default_value_t = 2, value_parser = count(0, 1000))]
    pub fill_iterations: usize,
    /// Axis-aligned second-order Laplacian smoothing iterations, 0 to 1000.
    #[arg(long, default_value_t = 2, value_parser = count(0, 1000))]
    pub smoothing_iterations: usize,
    /// Weight of one smoothing iteration, in (0, 0.5].
    #[arg(long, default_value_t = 0.25, value_parser = real(Open(0.0), Closed(0.5)))]
    pub smoothing_weight: f64,
}

/// The run summary (`summary.json` and the `--json` line).
#[derive(Debug, Serialize)]
pub struct Summary {
    /// Mesh spec.
    pub mesh: String,
    /// Scene.
    pub scene: String,
    /// Lattice cells.
    pub cells: usize,
    /// Lattice resolution used (voxels along the longest side).
    pub resolution: usize,
    /// Largest distance of a model vertex outside the rest lattice, in cell sizes (how well the
    /// thinnest part is resolved; the drawn surface is extrapolated that far).
    pub surface_gap_cells: f64,
    /// Tetrahedra.
    pub tetrahedra: usize,
    /// Particles (lattice vertices).
    pub particles: usize,
    /// Steps done.
    pub steps: usize,
    /// Largest relative cell-volume error after any step.
    pub max_cell_volume_error: f64,
    /// Final total volume over rest volume.
    pub total_volume_ratio: f64,
    /// |P_end - P_0| (kg m/s) of particles and sphere, reported only when no external force
    /// acts (free scene, zero gravity); `null` otherwise, where momentum is not conserved and
    /// `momentum_balance` is the figure to read.
    pub momentum_drift: Option<f64>,
    /// |L_end - L_0| (kg m^2/s) about the origin, only when no external force acts (as
    /// `momentum_drift`).
    pub angular_momentum_drift: Option<f64>,
    /// Sum of the impulses from outside the body and sphere over the run (N s): gravity,
    /// external forces and the floor's contacts.
    pub external_impulse: [f64; 3],
    /// |P_end - P_0 - external_impulse| (kg m/s): the momentum change not explained by the
    /// impulses from outside (round-off when the internal impulses conserve momentum).
    pub momentum_balance: f64,
    /// Step halvings (inversions avoided).
    pub step_halvings: u64,
    /// Cell-volume solver: `gauss-seidel` or `global`.
    pub volume_solver: String,
    /// Mean Gauss-Seidel sweeps (or global Newton iterations) per step.
    pub mean_sweeps: f64,
    /// Mean wall time per step (ms).
    pub mean_step_ms: f64,
    /// Lattice generation time (ms).
    pub lattice_ms: f64,
    /// Body mass (kg).
    pub mass: f64,
    /// Edge and diagonal stiffness used (N/m).
    pub stiffness: [f64; 2],
    /// Largest spring strain seen.
    pub max_strain: f64,
}

const STYLE_FIELDS: &[ColorField] = &[ColorField::Stretch, ColorField::Speed];

/// Volumetric scenes have gravity along z, so +z is up in pictures.
fn style() -> PictureStyle {
    PictureStyle::new("volumetric", UpAxis::Z, ColorField::Stretch, STYLE_FIELDS)
}

/// The rigid objects of the scene at the current state: the sphere at its centre and radius,
/// and every plane as a square centred under the rest body (see [`floor_square`]).
pub fn scene_props(sim: &VolumetricSimulation, floor: (Point3<f64>, f64)) -> Vec<Prop> {
    let mut props: Vec<Prop> = sim
        .sphere()
        .map(|s| Prop::sphere(s.position.into(), s.radius))
        .into_iter()
        .collect();
    let (centre, half) = floor;
    props.extend(sim.planes().iter().map(|pl| {
        // The body's centre projected onto the plane.
        let foot = centre - pl.normal * pl.distance(&centre);
        Prop::floor(foot.into(), pl.normal.into(), half)
    }));
    props
}

/// Where a plane of the scene is drawn: a square centred on the body's rest bounding-box centre
/// (projected onto the plane) with half side the box's largest side, so the floor spans twice
/// the body (and the sphere's footprint, which is narrower than the body) whatever its size.
pub fn floor_square(sim: &VolumetricSimulation) -> (Point3<f64>, f64) {
    let x = &sim.lattice().tet_mesh.vertices;
    let (mut lo, mut hi) = (x[0], x[0]);
    for p in x {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (nalgebra::center(&lo, &hi), (hi - lo).max())
}

/// The embedded surface (the soup deformed with the lattice) as a frame: velocity and speed
/// interpolated from the lattice particles with the embedding weights, stretch and max_stretch
/// against the rest soup `rest`.
fn surface_frame(sim: &VolumetricSimulation, rest: &[f64], step: usize) -> Result<Frame> {
    let emb = &sim.lattice().embedding;
    let flat =
        |p: Vec<Point3<f64>>| -> Vec<f64> { p.iter().flat_map(|q| [q.x, q.y, q.z]).collect() };
    let x = flat(emb.positions(sim.positions()));
    let vel: Vec<Point3<f64>> = sim.velocities().iter().map(|v| Point3::from(*v)).collect();
    let v = flat(emb.positions(&vel));
    Frame::new(step, sim.time(), x, emb.triangles.clone())
        .with_velocity(v)?
        .with_stretch(rest)
}

/// What `volumetric` adds to the shared run loop: the embedded-surface frames, lattice frames
/// (`--lattice-frames`), the summary's running maxima and the summary (none after a failure).
struct VolumetricHooks<'a> {
    args: &'a VolumetricArgs,
    soup: TriMesh,
    rest_soup: Vec<f64>,
    /// Centre and half side of the drawn floor ([`floor_square`]).
    floor: (Point3<f64>, f64),
    lattice: Lattice,
    p0: Vector3<f64>,
    l0: Vector3<f64>,
    impulse: Vector3<f64>,
    lattice_ms: f64,
    stiffness: [f64; 2],
    max_err: f64,
    total_sweeps: usize,
    max_strain: f64,
    /// Spring anchors and loads (`--pin ...@K`, `--load`).
    loads: crate::selection::VolumetricLoads,
}

impl RunHooks<VolumetricSimulation> for VolumetricHooks<'_> {
    type Summary = Summary;

    fn scenario(&self) -> Option<String> {
        self.args.scenario_record.clone()
    }

    fn before_step(&mut self, sim: &mut VolumetricSimulation) -> Result<()> {
        Ok(self.loads.before_step(sim)?)
    }

    fn frame(&self, sim: &VolumetricSimulation, step: usize) -> Result<Frame> {
        Ok(surface_frame(sim, &self.rest_soup, step)?.with_props(scene_props(sim, self.floor)))
    }

    fn after_step(
        &mut self,
        sim: &VolumetricSimulation,
        stats: &SimulationStats<StepStats>,
        out: Option<&mut OutputDir>,
        regular: bool,
    ) -> Result<bool> {
        let d = &stats.detail;
        self.impulse += Vector3::from(d.external_impulse);
        self.max_err = self.max_err.max(d.max_cell_volume_error);
        self.total_sweeps += d.sweeps;
        self.max_strain = self.max_strain.max(d.max_strain);
        if let Some(out) = out
            && regular
            && self.args.lattice_frames
        {
            balloon_mesh::io::vtk::write_tet_vtk(
                &out.path().join(format!("lattice_{:05}.vtk", stats.steps)),
                &sim.tet_mesh(),
                &[],
                &[],
            )?;
        }
        Ok(false)
    }

    fn summary(&self, sim: &VolumetricSimulation, run: &RunRecord<StepStats>) -> Summary {
        let args = self.args;
        let isolated = args.gravity == 0.0
            && args.scene == SceneArg::Free
            && args.pin.is_empty()
            && args.load.is_empty();
        Summary {
            mesh: args.mesh.clone(),
            scene: format!("{:?}", args.scene),
            cells: self.lattice.cells.len(),
            resolution: sim.body().params.lattice.resolution,
            surface_gap_cells: balloon_mesh::lattice::surface_gap(&self.soup, &self.lattice)
                / self.lattice.info.cell_size,
            tetrahedra: self.lattice.tet_mesh.tets.len(),
            particles: self.lattice.tet_mesh.vertices.len(),
            steps: run.steps,
            max_cell_volume_error: self.max_err,
            total_volume_ratio: run
                .last
                .as_ref()
                .map_or(1.0, |s| s.detail.total_volume_ratio),
            momentum_drift: isolated.then(|| (sim.momentum() - self.p0).norm()),
            angular_momentum_drift: isolated.then(|| (sim.angular_momentum() - self.l0).norm()),
            external_impulse: self.impulse.into(),
            momentum_balance: (sim.momentum() - self.p0 - self.impulse).norm(),
            step_halvings: sim.total_halvings(),
            volume_solver: match args.volume_solver {
                VolumeSolver::GaussSeidel => "gauss-seidel".into(),
                VolumeSolver::Global => "global".into(),
            },
            mean_sweeps: self.total_sweeps as f64 / run.steps.max(1) as f64,
            mean_step_ms: if run.steps > 0 {
                run.step_seconds * 1e3 / run.steps as f64
            } else {
                0.0
            },
            lattice_ms: self.lattice_ms,
            mass: sim.masses().iter().sum(),
            stiffness: self.stiffness,
            max_strain: self.max_strain,
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
            "{}: {} cells, {} tetrahedra, {} particles; {} steps, max cell volume error {:.2e}, volume ratio {:.12}, {} halvings, {:.3} ms/step",
            summary.mesh,
            summary.cells,
            summary.tetrahedra,
            summary.particles,
            summary.steps,
            summary.max_cell_volume_error,
            summary.total_volume_ratio,
            summary.step_halvings,
            summary.mean_step_ms
        )
    }

    fn failure(&self, error: SimulationError, step: usize) -> anyhow::Error {
        crate::run::step_failure(error, "the simulation", step, self.args.out.as_deref())
    }
}

/// Largest default time step (s).
const MAX_DT: f64 = 5e-4;
/// Default edge stiffness relative to `m / dt^2` (the library's, shared with the viewer).
const EDGE_STIFFNESS: f64 = balloon::volumetric::DEFAULT_SPRING_STIFFNESS;
/// Sag under the body's weight that the default time step allows. With 0.02 (and stiffness
/// 1/50, the same time step) the drop-sphere impact strained springs by 40-95 % and inverted
/// cells of the bunny, spot and armadillo within 2000 steps; 0.004 is five times stiffer.
const SAG_STRAIN: f64 = 0.004;

/// The cell-volume solver settings of `args`: [`CellVolumeParams::gauss_seidel`] or
/// [`CellVolumeParams::global`] changed by the flags given.
fn volume_params(args: &VolumetricArgs) -> CellVolumeParams {
    let base = match args.volume_solver {
        VolumeSolver::GaussSeidel => CellVolumeParams::gauss_seidel(),
        VolumeSolver::Global => CellVolumeParams::global(),
    };
    let (over_relaxation, adaptive_relaxation) = match args.over_relaxation {
        // The global solver has no sweeps to relax.
        Relaxation::Adaptive => (1.0, args.volume_solver == VolumeSolver::GaussSeidel),
        Relaxation::Fixed(omega) => (omega, false),
    };
    CellVolumeParams {
        tolerance: args.tolerance,
        over_relaxation,
        adaptive_relaxation,
        centre: if args.lumped_masses {
            CellCentre::MassWeighted
        } else {
            CellCentre::Arithmetic
        },
        correction: match args.correction {
            Correction::Scaling => CellCorrection::Scaling,
            Correction::Gradient => CellCorrection::Gradient,
        },
        ..base
    }
}

/// The body at `--resolution`, or sized for `--cells` (default [`DEFAULT_TARGET_CELLS`]). A
/// resolution that leaves no interior is reported with the resolution the sizing would choose.
fn build_body(
    soup: &TriMesh,
    params: VolumetricParams,
    lattice: &LatticeArgs,
) -> Result<VolumetricBody> {
    const CONTEXT: &str = "cannot build the volumetric body";
    let Some(resolution) = lattice.resolution else {
        let sizing = SizingParams::for_cells(lattice.cells.unwrap_or(DEFAULT_TARGET_CELLS));
        let (body, _) = VolumetricBody::build_sized(soup, params, &sizing).context(CONTEXT)?;
        return Ok(body);
    };
    match VolumetricBody::build(soup, params.clone()) {
        Ok(body) => Ok(body),
        Err(VolumetricError::Lattice(e @ LatticeError::NoInterior { .. })) => {
            let hint = match size_lattice(soup, &params.lattice, &SizingParams::default()) {
                Ok((_, s)) => format!(
                    "resolution {resolution} leaves no cell; --resolution {} gives {} cells \
                     (or leave --resolution out to size the lattice for --cells)",
                    s.resolution, s.cells
                ),
                Err(e) => format!("no resolution gives a body either: {e}"),
            };
            Err(anyhow::Error::new(e).context(hint).context(CONTEXT))
        }
        Err(e) => Err(anyhow::Error::new(e).context(CONTEXT)),
    }
}

/// Runs the subcommand.
pub fn run(args: VolumetricArgs) -> Result<()> {
    execute(&args, None, false).map(drop)
}

/// What [`build`] makes: the simulation and what the summary reports about its making.
pub struct VolumetricBuild {
    /// The simulation in its scene, at rest.
    pub sim: VolumetricSimulation,
    /// The triangle soup as read and scaled.
    pub soup: TriMesh,
    /// Lattice generation time (ms).
    pub lattice_ms: f64,
    /// Edge and diagonal spring stiffness used (N/m).
    pub stiffness: [f64; 2],
}

/// Builds the simulation of `balloon volumetric` for `args`: loads `args.mesh` (or takes
/// `mesh`, an in-memory soup), scales it, generates the lattice, sets the springs and the
/// scene exactly as the command does. Writes nothing.
pub fn build(args: &VolumetricArgs, mesh: Option<TriMesh>) -> Result<VolumetricBuild> {
    let mut soup = match mesh {
        Some(m) => m,
        None => {
            balloon_mesh::load(&args.mesh).with_context(|| format!("cannot load {}", args.mesh))?
        }
    };
    soup.scale(args.scale);
    crate::params::apply_transform(&mut soup, args.transform.as_deref())
        .map_err(anyhow::Error::msg)?;
    let params = VolumetricParams {
        lattice: LatticeParams {
            resolution: args
                .lattice
                .resolution
                .unwrap_or(LatticeParams::default().resolution),
            voxels_per_cell: args.lattice.voxels_per_cell,
            rays: args.lattice.rays,
            band_voxels: args.lattice.band_voxels,
            p_in: args.lattice.p_in,
            p_subs: args.lattice.p_subs,
            density_threshold: args.lattice.density_threshold,
            fill_iterations: args.lattice.fill_iterations,
            smoothing_iterations: args.lattice.smoothing_iterations,
            smoothing_weight: args.lattice.smoothing_weight,
        },
        volume: volume_params(args),
        density: args.density,
        mass_model: if args.lumped_masses {
            MassModel::Lumped
        } else {
            MassModel::Equal
        },
        gravity: [0.0, 0.0, args.gravity],
        dt: args.dt.unwrap_or(MAX_DT),
        restitution: args.restitution,
        ..VolumetricParams::default()
    };
    let t0 = Instant::now();
    let mut body = build_body(&soup, params, &args.lattice)?;
    let lattice_ms = t0.elapsed().as_secs_f64() * 1e3;
    let dt = args
        .dt
        .unwrap_or_else(|| body.sag_limited_dt(EDGE_STIFFNESS, SAG_STRAIN, args.gravity, MAX_DT));
    body.params.dt = dt;
    let defaults = body.default_springs(EDGE_STIFFNESS);
    let edge = args.edge_stiffness.unwrap_or(defaults.edge_stiffness);
    let diagonal = args.diagonal_stiffness.unwrap_or(if args.soft_diagonals {
        edge / 20.0
    } else {
        edge
    });
    let damping = args.damping.unwrap_or(defaults.edge_damping);
    let diagonal_damping = args.diagonal_damping.unwrap_or(if args.soft_diagonals {
        damping / 2.0
    } else {
        damping
    });
    let body = body
        .with_springs(SpringParams {
            edge_stiffness: edge,
            edge_damping: damping,
            diagonal_stiffness: diagonal,
            diagonal_damping,
        })
        .context("invalid spring parameters")?;
    let scene = match args.scene {
        SceneArg::Free => VolumetricScene::Free,
        SceneArg::DropSphere => VolumetricScene::DropSphere {
            soft_diagonals: args.soft_diagonals,
        },
    };
    let mut sim = scene.setup(body)?;
    crate::selection::fix_volumetric(&mut sim, &args.pin, args.pin_stiffness)?;
    Ok(VolumetricBuild {
        sim,
        soup,
        lattice_ms,
        stiffness: [edge, diagonal],
    })
}

/// Runs the job of `balloon volumetric` for `args` (checks, [`build`], the output folder, the
/// steps, the summary) and returns the summary with the final simulation. `mesh` replaces
/// loading `args.mesh`; `quiet` prints nothing.
pub fn execute(
    args: &VolumetricArgs,
    mesh: Option<TriMesh>,
    quiet: bool,
) -> Result<Finished<VolumetricSimulation>> {
    let render_spec = check_picture_args(&args.pictures, args.out.as_deref(), &style())?;
    if let Some(dir) = &args.out {
        crate::output::prepare_out_dir(dir, args.overwrite)?;
    }
    if !(args.scale.is_finite() && args.scale > 0.0) {
        anyhow::bail!("invalid --scale {}: must be > 0", args.scale);
    }
    if args.frame_every == 0 {
        anyhow::bail!("invalid --frame-every 0: must be >= 1");
    }
    let VolumetricBuild {
        mut sim,
        soup,
        lattice_ms,
        stiffness: [edge, diagonal],
    } = build(args, mesh)?;
    let loads =
        crate::selection::volumetric_loads(&mut sim, &args.pin, args.pin_stiffness, &args.load)?;
    let lattice = sim.lattice().clone();
    let rest_soup: Vec<f64> = lattice
        .embedding
        .positions(&lattice.tet_mesh.vertices)
        .iter()
        .flat_map(|q| [q.x, q.y, q.z])
        .collect();
    let out = match &args.out {
        Some(dir) => Some(OutputDir::create(dir, args.format)?.with_pictures(
            &args.pictures,
            render_spec,
            style(),
        )?),
        None => None,
    };
    if let (Some(o), Some(text)) = (&out, &args.scenario_record) {
        o.write_text("scenario.toml", text)?;
    }
    if let Some(out) = &out {
        let masses = sim.masses().to_vec();
        let cell_volume: Vec<f64> = (0..lattice.tet_mesh.tets.len())
            .map(|t| lattice.tet_mesh.tet_volume(t))
            .collect();
        let cell_of_tet: Vec<f64> = {
            let mut c = vec![0.0; lattice.tet_mesh.tets.len()];
            for (cell, tets) in lattice.cell_tets.iter().enumerate() {
                for &t in tets {
                    c[t] = cell as f64;
                }
            }
            c
        };
        out.write_file("lattice.vtk", |tmp| {
            Ok(balloon_mesh::io::vtk::write_tet_vtk(
                tmp,
                &lattice.tet_mesh,
                &[("tet_volume", &cell_volume), ("cell", &cell_of_tet)],
                &[("mass", &masses)],
            )?)
        })?;
        out.write_named_mesh("input_soup", &soup)?;
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
    let mut hooks = VolumetricHooks {
        args,
        soup: soup.clone(),
        rest_soup,
        floor: floor_square(&sim),
        lattice,
        p0: sim.momentum(),
        l0: sim.angular_momentum(),
        impulse: Vector3::zeros(),
        lattice_ms,
        stiffness: [edge, diagonal],
        max_err: 0.0,
        total_sweeps: 0,
        max_strain: 0.0,
        loads,
    };
    let summary = run_simulation(&mut sim, &mut hooks, &plan, out)?;
    Ok(Finished {
        summary: Some(summary),
        sim,
    })
}
