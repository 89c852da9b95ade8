//! `balloon volumetric [MESH|builtin]`: a volume-conserving impulse-based body generated from a
//! triangle soup (Diziol, Bender and Bayer 2011), optionally in the Fig. 4 drop-sphere
//! scene: its flags, turned into a `balloon_scenario::volumetric::VolumetricScenario` and run by
//! `balloon_run::jobs::volumetric` (its output folder is described there).

use crate::choices::{Correction, FrameFormat, SceneArg, UpArg, VolumeSolver};
use crate::pictures::PictureArgs;
use crate::scenario_cli::{Invocation, job_error};
use anyhow::Result;
use balloon::mesh::TriMesh;
use balloon::volumetric::VolumetricSimulation;
use balloon_run::Finished;
use balloon_scenario::Scenario;
use balloon_scenario::mesh::MeshSpec;
use balloon_scenario::range::{parse_real, parse_whole};
use balloon_scenario::selection::{Load, Pin, parse_load, parse_pin};
use balloon_scenario::volumetric::{
    BodyTable, LatticeTable, Relaxation, VolumetricRun, VolumetricScenario,
};
use std::path::PathBuf;

pub use balloon_scenario::volumetric::VolumetricBuild;

/// Arguments of `balloon volumetric`.
#[derive(Debug, clap::Args)]
pub struct VolumetricArgs {
    /// Mesh file (.obj, .off, .ply, .stl; any triangle soup), `builtin` (the teddy) or
    /// `builtin:NAME`.
    #[arg(default_value = "builtin")]
    pub mesh: String,
    /// Scale factor applied to the mesh coordinates (to metres), in (0, 1e6].
    #[arg(long, default_value_t = MeshSpec::default().scale, value_parser = parse_real)]
    pub scale: f64,
    /// Affine map applied to the mesh after --scale: 12 comma-separated numbers, a 3x4 matrix
    /// row by row `a11,a12,a13,t1,a21,a22,a23,t2,a31,a32,a33,t3` mapping x to A x + t (m);
    /// A must have a positive determinant (no mirror). E.g. a translation by (0.1, 0, 0) is
    /// `1,0,0,0.1,0,1,0,0,0,0,1,0`. Each number in [-1e6, 1e6].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1,
          value_parser = parse_real)]
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
    #[arg(long, value_parser = parse_real)]
    pub edge_stiffness: Option<f64>,
    /// Diagonal spring stiffness (N/m); default: the edge stiffness (/20 with --soft-diagonals).
    /// In [0, 1e12].
    #[arg(long, value_parser = parse_real)]
    pub diagonal_stiffness: Option<f64>,
    /// Edge spring damping (N s/m); default: m / (50 dt), about 3 % of a spring's critical
    /// damping (m / (1000 dt), 0.35 %, let the impact ring through the body until thin parts
    /// inverted). In [0, 1e9].
    #[arg(long, value_parser = parse_real)]
    pub damping: Option<f64>,
    /// Diagonal spring damping (N s/m); default: the edge damping (/2 with --soft-diagonals).
    /// In [0, 1e9].
    #[arg(long, value_parser = parse_real)]
    pub diagonal_damping: Option<f64>,
    /// Mass density (kg/m^3), in (0, 1e5] (above any solid's: osmium is 2.26e4).
    #[arg(long, default_value_t = BodyTable::default().density, value_parser = parse_real)]
    pub density: f64,
    /// Gravity along the up axis (m/s^2), in [-1e3, 1e3] (100 g); negative pulls down.
    #[arg(long, default_value_t = VolumetricRun::default().gravity, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub gravity: f64,
    /// The up axis: gravity acts along it, the floor scene's floor is perpendicular to it
    /// (the drop-sphere scene needs z).
    #[arg(long, value_enum, default_value_t = UpArg::Z)]
    pub up: UpArg,
    /// Height (m) of the floor scene's floor along the up axis, in [-1e6, 1e6]; default: just
    /// under the body (a thousandth of its bounding-box diagonal below its lowest particle).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_real)]
    pub floor_height: Option<f64>,
    /// Contact restitution, in [0, 1].
    #[arg(long, default_value_t = VolumetricRun::default().restitution, value_parser = parse_real)]
    pub restitution: f64,
    /// Relative cell-volume tolerance of the impulse iteration, in (0, 0.1] (a looser one
    /// no longer conserves volume).
    #[arg(long, default_value_t = VolumetricRun::default().tolerance, value_parser = parse_real)]
    pub tolerance: f64,
    /// Over-relaxation of the Gauss-Seidel volume sweeps: `adaptive` (the default: after 16
    /// plain sweeps, the factor the measured convergence rate suggests, Young's rule, at most
    /// 1.9; `CellVolumeParams::adaptive_relaxation`) or a fixed factor in (0, 2) (1 = the
    /// paper). The global solver has no sweeps: it takes `adaptive` or 1.
    #[arg(long, default_value_t = Relaxation::Adaptive)]
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
    #[arg(long, value_parser = parse_real)]
    pub dt: Option<f64>,
    /// Number of steps, 0 to 1e8.
    #[arg(long, default_value_t = VolumetricRun::default().steps, value_parser = parse_whole)]
    pub steps: usize,
    /// Pin lattice particles, picked by their rest positions (repeatable): `indices:1,2,3`,
    /// `file:PATH`, `below:AXIS:VALUE`, `above:AXIS:VALUE` or `box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX`
    /// (m), with `@K` for springs of K N/m to the rest position instead of a hard pin (a
    /// hard-pinned particle never moves: infinite mass in the springs, contacts and volume
    /// impulses).
    #[arg(long, value_parser = parse_pin)]
    pub pin: Vec<Pin>,
    /// Stiffness of the --pin anchors without their own `@K`, N/m, in (0, 1e12]; absent: hard
    /// pins. Springs act explicitly: K dt^2 / m well below 1 keeps them stable.
    #[arg(long, value_parser = parse_real)]
    pub pin_stiffness: Option<f64>,
    /// A load on the lattice particles (repeatable): `gravity=GX,GY,GZ` (m/s^2, replaces
    /// --gravity while active), `force=FX,FY,FZ;on=SELECTOR` (N per particle; `per=total`
    /// spreads it over the selection) or `grab=X,Y,Z;on=SELECTOR;stiffness=K` (pulled toward
    /// the point, N/m per particle); `start=S;end=S` schedule it (s).
    #[arg(long, value_parser = parse_load)]
    pub load: Vec<Load>,
    /// Output folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the files of an earlier run in --out (frames, records, pictures: only files
    /// this program writes); without it, a folder holding them is refused.
    #[arg(long)]
    pub overwrite: bool,
    /// Write a surface frame every N steps, 1 to 1e8.
    #[arg(long, default_value_t = VolumetricScenario::default().output.frame_every, value_parser = parse_whole)]
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
}

/// Flags of the soup -> lattice generator (Diziol, Bender and Bayer 2011, Sec. 3).
#[derive(Debug, clap::Args)]
pub struct LatticeArgs {
    /// Voxels along the longest side of the bounding box, 4 to 200: the voxel grid holds up to
    /// resolution^3 voxels (at 200 the teddy's lattice took 3.8 s and 140 MB; 400 took 26 s
    /// and 920 MB). Default: chosen for `--cells`.
    #[arg(long, conflicts_with = "cells", value_parser = parse_whole)]
    pub resolution: Option<usize>,
    /// Size the lattice for about this many cells, 1 to 100000 (the resolution is searched so
    /// that the body has 0.8 to 1.25 times as many, raised further while a thin part of the
    /// model lies outside the lattice). Default 1000 when `--resolution` is not given.
    #[arg(long, value_parser = parse_whole)]
    pub cells: Option<usize>,
    /// Voxels along one side of a lattice cell, 1 to 200 (at most --resolution).
    #[arg(long, default_value_t = LatticeTable::default().voxels_per_cell, value_parser = parse_whole)]
    pub voxels_per_cell: usize,
    /// Ray directions in the inside/outside vote, 1 to 26 (6 axes, 14 with body diagonals,
    /// 26 all).
    #[arg(long, default_value_t = LatticeTable::default().rays, value_parser = parse_whole)]
    pub rays: usize,
    /// Distance band in voxels (P = 1 - |d| / band), in [1.5, 64].
    #[arg(long, default_value_t = LatticeTable::default().band_voxels, value_parser = parse_real)]
    pub band_voxels: f64,
    /// P_in: a ray enters/leaves where P > P_in and dP/dv > 0; in (0, 1).
    #[arg(long, default_value_t = LatticeTable::default().p_in, value_parser = parse_real)]
    pub p_in: f64,
    /// P_subs: the next change needs P < P_subs with dP/dv < 0 first; in (0, 1), at most P_in.
    #[arg(long, default_value_t = LatticeTable::default().p_subs, value_parser = parse_real)]
    pub p_subs: f64,
    /// Pseudo-density threshold m(V)/M(V) for keeping a cell, in [0, 1).
    #[arg(long, default_value_t = LatticeTable::default().density_threshold, value_parser = parse_real)]
    pub density_threshold: f64,
    /// Hole-filling rounds, 0 to 1000.
    #[arg(long, default_value_t = LatticeTable::default().fill_iterations, value_parser = parse_whole)]
    pub fill_iterations: usize,
    /// Axis-aligned second-order Laplacian smoothing iterations, 0 to 1000.
    #[arg(long, default_value_t = LatticeTable::default().smoothing_iterations, value_parser = parse_whole)]
    pub smoothing_iterations: usize,
    /// Weight of one smoothing iteration, in (0, 0.5].
    #[arg(long, default_value_t = LatticeTable::default().smoothing_weight, value_parser = parse_real)]
    pub smoothing_weight: f64,
}

impl VolumetricArgs {
    /// The scenario of these flags (every key, given or default).
    pub fn scenario(&self) -> VolumetricScenario {
        let l = &self.lattice;
        let mut s = VolumetricScenario {
            mesh: MeshSpec {
                path: self.mesh.clone(),
                scale: self.scale,
                transform: self.transform.clone(),
            },
            lattice: LatticeTable {
                resolution: l.resolution,
                cells: l.cells,
                voxels_per_cell: l.voxels_per_cell,
                rays: l.rays,
                band_voxels: l.band_voxels,
                p_in: l.p_in,
                p_subs: l.p_subs,
                density_threshold: l.density_threshold,
                fill_iterations: l.fill_iterations,
                smoothing_iterations: l.smoothing_iterations,
                smoothing_weight: l.smoothing_weight,
            },
            body: BodyTable {
                soft_diagonals: self.soft_diagonals,
                edge_stiffness: self.edge_stiffness,
                diagonal_stiffness: self.diagonal_stiffness,
                damping: self.damping,
                diagonal_damping: self.diagonal_damping,
                density: self.density,
                lumped_masses: self.lumped_masses,
                pin_stiffness: self.pin_stiffness,
            },
            run: VolumetricRun {
                scene: self.scene.into(),
                gravity: self.gravity,
                up: self.up.into(),
                floor_height: self.floor_height,
                restitution: self.restitution,
                dt: self.dt,
                steps: self.steps,
                tolerance: self.tolerance,
                over_relaxation: self.over_relaxation,
                correction: self.correction.into(),
                volume_solver: self.volume_solver.into(),
            },
            anchors: self.pin.clone(),
            loads: self.load.clone(),
            ..VolumetricScenario::default()
        };
        s.output.out.clone_from(&self.out);
        s.output.overwrite = self.overwrite;
        s.output.json = self.json;
        s.output.format = self.format.into();
        s.output.frame_every = self.frame_every;
        s.output.lattice_frames = self.lattice_frames;
        self.pictures.apply(&mut s.output);
        s
    }
}

/// Runs `balloon volumetric` (`matches`: the subcommand's, for the values as typed).
pub fn run(args: &VolumetricArgs, matches: &clap::ArgMatches) -> Result<()> {
    let call = Invocation::of(Scenario::Volumetric(args.scenario()), matches)?;
    let Scenario::Volumetric(s) = &call.scenario else {
        unreachable!("a volumetric scenario")
    };
    balloon_run::jobs::volumetric::run(s, None, Some(&call.record()), false).map(drop)
}

/// Builds the simulation of `balloon volumetric` for `args` (checked first), as the command
/// does: loads the mesh (or takes `mesh`, an in-memory soup), generates the lattice, sets the
/// springs, the scene and the hard anchors. Writes nothing.
pub fn build(args: &VolumetricArgs, mesh: Option<TriMesh>) -> Result<VolumetricBuild> {
    let s = args.scenario();
    s.validate().map_err(job_error)?;
    Ok(s.build(mesh)?)
}

/// Runs the job of `balloon volumetric` for `args` (checks, build, the output folder, the
/// steps, the summary) and returns the summary with the final simulation; `quiet` prints
/// nothing. No scenario is recorded.
pub fn execute(
    args: &VolumetricArgs,
    mesh: Option<TriMesh>,
    quiet: bool,
) -> Result<Finished<VolumetricSimulation>> {
    let s = args.scenario();
    s.validate().map_err(job_error)?;
    balloon_run::jobs::volumetric::run(&s, mesh, None, quiet)
}
