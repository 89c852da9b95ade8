//! The job of a two-layer body (`balloon two-layer`, Song 2009).
//!
//! Output folder: `frame_NNNNN.obj` every `frame_every` steps (3D: outer and inner surface; 2D:
//! the triangles between the layers; 1D: the two particles), `stats.jsonl` (one line per step,
//! flushed, so a run that blows up leaves a readable file) and `summary.json` (also written
//! when the run fails, with the error).

use crate::output::{ColorField, Frame, OutputDir, PictureStyle};
use crate::run::{Finished, FramePolicy, RunHooks, RunPlan, RunRecord, run_simulation};
use anyhow::Result;
use balloon::two_layer::{DragTarget, ExplicitMethod, TwoLayerSimulation, TwoLayerStats};
use balloon_render::{Camera, Projection, UpAxis};
use balloon_scenario::selection::TwoLayerLoads;
use balloon_scenario::selection::apply::two_layer_loads;
use balloon_scenario::two_layer::{DragSpec, TWO_LAYER_COLORS, TwoLayerScenario};
use serde::Serialize;

/// The summary of a run (`summary.json`, and the `json` line).
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

/// 3D: perspective with +z up (gravity along -z); 2D: the xy plane seen from +z, +y up.
fn style(dim: u8) -> PictureStyle {
    let mut s = PictureStyle::new("two-layer", UpAxis::Z, ColorField::Speed, TWO_LAYER_COLORS);
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
    let tris = sim.model().draw_triangles();
    let body = crate::output::Body::whole("body", sim.positions().len() / 3, tris.len());
    Frame::new(step, sim.time(), sim.positions().to_vec(), tris)
        .with_velocity(sim.velocities().to_vec())?
        .with_stretch(rest)
        .map(|f| f.with_bodies(vec![body]))
}

/// What a two-layer run adds to the shared run loop: the drag window (`drag`) before each
/// step, the layer frames and the summary (also after a failure, with the error).
struct TwoLayerHooks<'a> {
    args: &'a TwoLayerScenario,
    /// The resolved scenario, repeated in the summary.
    record: Option<String>,
    drag: Option<DragSpec>,
    /// Spring anchors and loads.
    loads: TwoLayerLoads,
    /// Initial positions, the reference of the stretch field.
    rest: Vec<f64>,
}

impl RunHooks<TwoLayerSimulation> for TwoLayerHooks<'_> {
    type Summary = Summary;

    fn scenario(&self) -> Option<String> {
        self.record.clone()
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
                stiffness: self.args.run.drag_stiffness,
                damping: self.args.run.drag_damping,
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
            dim: args.body.dim,
            integrator: args.run.integrator,
            particles: sim.model().num_particles(),
            springs: sim.model().springs.len(),
            steps: run.steps,
            dt: args.run.dt,
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

/// Runs a two-layer scenario as a job (call [`TwoLayerScenario::validate`] first): checks the
/// output folder, builds the body ([`TwoLayerScenario::build`]), its spring anchors and loads,
/// writes the `record` (the recorded scenario's text), takes the steps with the drag, and
/// writes and returns the summary with the final simulation; `quiet` prints nothing.
pub fn run(
    args: &TwoLayerScenario,
    record: Option<&str>,
    quiet: bool,
) -> Result<Finished<TwoLayerSimulation>> {
    let dim = args.body.dim;
    let render_spec = args
        .output
        .check_pictures("two-layer", TWO_LAYER_COLORS)
        .map_err(anyhow::Error::msg)?;
    if let Some(dir) = &args.output.out {
        crate::output::check_out_dir(dir, args.output.overwrite)?;
    }
    let drag = args.drag().map_err(anyhow::Error::msg)?;
    let mut sim = args.build()?;
    let rest = sim.positions().to_vec();
    let out = match &args.output.out {
        Some(dir) => {
            // The earlier run's files go only now that this run is set up.
            crate::output::prepare_out_dir(dir, args.output.overwrite)?;
            Some(OutputDir::create(dir, args.output.format)?.with_pictures(
                &args.output,
                render_spec,
                style(dim),
            )?)
        }
        None => None,
    };
    if let (Some(o), Some(text)) = (&out, record) {
        o.write_text("scenario.toml", text)?;
    }
    let plan = RunPlan {
        steps: args.run.steps,
        frames: FramePolicy {
            every: args.output.frame_every,
            last: true,
        },
        json: args.output.json,
        quiet,
    };
    let loads = two_layer_loads(&mut sim, &args.anchors, args.run.pin_stiffness, &args.loads)?;
    let mut hooks = TwoLayerHooks {
        args,
        record: record.map(str::to_owned),
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
