//! The job of a volumetric body (`balloon volumetric`, Diziol, Bender and Bayer 2011).
//!
//! Output folder: `input_soup.obj` (the soup as read and scaled), `lattice.vtk` (the rest
//! tetrahedral lattice with per-cell rest volumes and per-particle masses, for ParaView),
//! `frame_NNNNN.obj` (the embedded soup, deformed with the lattice, every `frame_every`
//! steps), `lattice_NNNNN.vtk` with `lattice_frames`, `stats.jsonl` (one line per step,
//! flushed) and `summary.json`. In the drop-sphere scene, the sphere and the floor go beside
//! each frame as `sphere_NNNNN.<ext>` and `floor.<ext>` (parts 1 and 2 of `series.pvd` with
//! VTK) and into the pictures.

use crate::output::{ColorField, Frame, OutputDir, PictureStyle};
use crate::run::{Finished, FramePolicy, RunHooks, RunPlan, RunRecord, run_simulation};
use anyhow::Result;
use balloon::mesh::TriMesh;
use balloon::mesh::lattice::Lattice;
use balloon::volumetric::{StepStats, VolumetricSimulation};
use balloon::{SimulationError, SimulationStats};
use balloon_render::{Prop, UpAxis};
use balloon_scenario::selection::VolumetricLoads;
use balloon_scenario::selection::apply::volumetric_loads;
use balloon_scenario::volumetric::{
    SceneChoice, Up, VOLUMETRIC_COLORS, VolumeSolver, VolumetricBuild, VolumetricScenario,
};
use nalgebra::{Point3, Vector3};
use serde::Serialize;

/// The run summary (`summary.json` and the `json` line).
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

/// Pictures (and the USD stage) stand on the scene's up axis (`up`, z by default).
fn style(up: Up) -> PictureStyle {
    PictureStyle::new(
        "volumetric",
        match up {
            Up::Y => UpAxis::Y,
            Up::Z => UpAxis::Z,
        },
        ColorField::Stretch,
        VOLUMETRIC_COLORS,
    )
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
    let body = crate::output::Body::whole("body", x.len() / 3, emb.triangles.len());
    Frame::new(step, sim.time(), x, emb.triangles.clone())
        .with_velocity(v)?
        .with_stretch(rest)
        .map(|f| f.with_bodies(vec![body]))
}

/// What a volumetric run adds to the shared run loop: the embedded-surface frames, lattice
/// frames (`lattice_frames`), the summary's running maxima and the summary (none after a
/// failure).
struct VolumetricHooks<'a> {
    args: &'a VolumetricScenario,
    /// The resolved scenario, repeated in the summary.
    record: Option<String>,
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
    /// Spring anchors and loads.
    loads: VolumetricLoads,
}

impl RunHooks<VolumetricSimulation> for VolumetricHooks<'_> {
    type Summary = Summary;

    fn scenario(&self) -> Option<String> {
        self.record.clone()
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
            && self.args.output.lattice_frames
        {
            balloon::mesh::io::vtk::write_tet_vtk(
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
        let isolated = args.run.gravity == 0.0
            && args.run.scene == SceneChoice::Free
            && args.anchors.is_empty()
            && args.loads.is_empty();
        Summary {
            mesh: args.mesh.path.clone(),
            scene: scene_name(args.run.scene).into(),
            cells: self.lattice.cells.len(),
            resolution: sim.body().params.lattice.resolution,
            surface_gap_cells: balloon::mesh::lattice::surface_gap(&self.soup, &self.lattice)
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
            volume_solver: match args.run.volume_solver {
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
        crate::run::step_failure(
            error,
            "the simulation",
            step,
            self.args.output.out.as_deref(),
        )
    }
}

/// The scene as the summary names it (the Rust variant names of the command-line tool's first
/// versions, kept so that summaries compare across versions).
fn scene_name(scene: SceneChoice) -> &'static str {
    match scene {
        SceneChoice::Free => "Free",
        SceneChoice::DropSphere => "DropSphere",
        SceneChoice::Floor => "Floor",
    }
}

/// Runs a volumetric scenario as a job (call [`VolumetricScenario::validate`] first): checks the
/// output folder, builds the body ([`VolumetricScenario::build`]; `mesh` replaces loading
/// `mesh.path`), its spring anchors and loads, writes the rest lattice, the input soup and the
/// `record` (the recorded scenario's text), takes the steps, and writes and returns the summary
/// with the final simulation. `quiet` prints nothing.
pub fn run(
    args: &VolumetricScenario,
    mesh: Option<TriMesh>,
    record: Option<&str>,
    quiet: bool,
) -> Result<Finished<VolumetricSimulation>> {
    let render_spec = args
        .output
        .check_pictures("volumetric", VOLUMETRIC_COLORS)
        .map_err(anyhow::Error::msg)?;
    if let Some(dir) = &args.output.out {
        crate::output::check_out_dir(dir, args.output.overwrite)?;
    }
    let VolumetricBuild {
        mut sim,
        soup,
        lattice_ms,
        stiffness: [edge, diagonal],
    } = args.build(mesh)?;
    let loads = volumetric_loads(
        &mut sim,
        &args.anchors,
        args.body.pin_stiffness,
        &args.loads,
    )?;
    let lattice = sim.lattice().clone();
    let rest_soup: Vec<f64> = lattice
        .embedding
        .positions(&lattice.tet_mesh.vertices)
        .iter()
        .flat_map(|q| [q.x, q.y, q.z])
        .collect();
    let out = match &args.output.out {
        Some(dir) => {
            // The earlier run's files go only now that this run is set up.
            crate::output::prepare_out_dir(dir, args.output.overwrite)?;
            Some(OutputDir::create(dir, args.output.format)?.with_pictures(
                &args.output,
                render_spec,
                style(args.run.up),
            )?)
        }
        None => None,
    };
    if let (Some(o), Some(text)) = (&out, record) {
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
            Ok(balloon::mesh::io::vtk::write_tet_vtk(
                tmp,
                &lattice.tet_mesh,
                &[("tet_volume", &cell_volume), ("cell", &cell_of_tet)],
                &[("mass", &masses)],
            )?)
        })?;
        out.write_named_mesh("input_soup", &soup)?;
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
    let mut hooks = VolumetricHooks {
        args,
        record: record.map(str::to_owned),
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
