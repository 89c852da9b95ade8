//! The job of connected shell balloons (`balloon connect`, the two-balloon experiment).
//!
//! The output folder holds frames with all balloons merged into one surface, `stats.jsonl`
//! (per step each balloon's gauge pressure, gas volume, amount and stretch, and the total
//! amount), `summary.json` (per-balloon end states and, for two equal spherical membrane
//! balloons, the analytic end state of `ThinSphere::joined_pair` with the differences),
//! `pair_start.png` / `pair_end.png` (renders) and `pressure_stretch.png` (each balloon's path
//! in the pressure-stretch plane, over the analytic thin-sphere curve where there is one).

use crate::output::{ColorField, Field, Frame, OutputDir, PictureStyle};
use crate::run::{Finished, FramePolicy, RunHooks, RunPlan, RunRecord, run_simulation};
use anyhow::{Context, Result};
use balloon::material::MembraneModel;
use balloon::material::membrane::ThinSphere;
use balloon::mesh::geometry;
use balloon::shell::ShellMaterialModel;
use balloon::shell::connected::{Conductance, ConnectedStepStats};
use balloon::{SimulationError, SimulationStats};
use balloon_render::UpAxis;
use balloon_scenario::connect::{ConnectScenario, ConnectSim, SETTLE_STEPS};
use balloon_scenario::file::resolve_shell_record;
use balloon_scenario::gas::GasControl;
use balloon_scenario::shell::{SHELL_COLORS, ShellScenario};
use serde::Serialize;

/// One balloon's state in the summary.
#[derive(Clone, Debug, Default, Serialize)]
pub struct BalloonState {
    /// Vertices of this balloon.
    pub vertices: usize,
    /// Rest gas volume `V0`, m^3.
    pub rest_gas_volume: f64,
    /// Linear stretch `(V / V0)^(1/3)` when connected (after the pre-inflation).
    pub start_stretch: f64,
    /// Gauge pressure when connected, Pa.
    pub start_gauge_pressure: f64,
    /// Linear stretch at the end.
    pub stretch: f64,
    /// Gas volume at the end, m^3.
    pub gas_volume: f64,
    /// Gauge pressure at the end, Pa.
    pub gauge_pressure: f64,
    /// Gas amount `nRT` at the end, J.
    pub amount: f64,
}

/// The analytic end state of two equal spherical membrane balloons (`ThinSphere::joined_pair`)
/// and how far the run ended from it.
#[derive(Clone, Debug, Serialize)]
pub struct AnalyticPair {
    /// Sphere radius used, `3 V0 / A0` of the rest mesh, m.
    pub radius: f64,
    /// The smaller balloon's end stretch.
    pub small_stretch: f64,
    /// The larger balloon's end stretch.
    pub large_stretch: f64,
    /// The common gauge pressure, Pa.
    pub gauge_pressure: f64,
    /// `|l / l_analytic - 1|` of the balloon that ended smaller.
    pub small_stretch_error: f64,
    /// `|l / l_analytic - 1|` of the balloon that ended larger.
    pub large_stretch_error: f64,
    /// `|P / P_analytic - 1|` of the larger balloon's gauge pressure.
    pub pressure_error: f64,
}

/// The run summary (`summary.json`, and the `json` line).
#[derive(Debug, Default, Serialize)]
pub struct ConnectSummary {
    /// `ok`, `failed` or `interrupted`.
    pub status: String,
    /// The mesh (`mesh.path`).
    pub mesh: String,
    /// `copies` (N copies of the mesh) or `components` (the mesh's components).
    pub layout: String,
    /// Number of balloons.
    pub balloons: usize,
    /// The tubes as `[a, b]` pairs.
    pub tubes: Vec<[usize; 2]>,
    /// The tubes' conductance, m^3/s, or `instant`.
    pub conductance: String,
    /// Steps completed.
    pub steps: usize,
    /// Whether `until_settled` reached its tolerances.
    pub settled: bool,
    /// Simulated time, s.
    pub sim_time_s: f64,
    /// Total gas amount `sum nRT` when connected, J.
    pub total_amount_start: f64,
    /// Total gas amount at the end, J.
    pub total_amount_end: f64,
    /// Material model.
    pub material: String,
    /// The material with its parameters.
    pub material_parameters: Option<ShellMaterialModel>,
    /// Each balloon's start and end state.
    pub balloon_states: Vec<BalloonState>,
    /// The analytic end state (two equal spherical membrane balloons with a pressure maximum),
    /// or null.
    pub analytic: Option<AnalyticPair>,
    /// Why there is no analytic end state (null when there is one).
    pub analytic_note: Option<String>,
    /// The error that stopped the run, if any.
    pub error: Option<String>,
}

fn style() -> PictureStyle {
    let mut s = PictureStyle::new("connect", UpAxis::Y, ColorField::Stretch, SHELL_COLORS);
    s.closed = true;
    s.camera.azimuth_deg = 0.0;
    s
}

/// The current state of all balloons as one frame: velocity, speed, pressure force (Eq. 15),
/// thickness, stretch and max_stretch against the rest shapes.
fn frame(sim: &ConnectSim, step: usize) -> Result<Frame> {
    use balloon::Simulation;
    let surface = sim.surface();
    let (mut rest, mut force, mut thickness) = (Vec::new(), Vec::new(), Vec::new());
    let mut bodies = Vec::new();
    let (mut v0, mut f0) = (0, 0);
    for (i, b) in sim.balloons().iter().enumerate() {
        let (nv, nf) = (b.positions().len() / 3, b.triangles().len());
        bodies.push(crate::output::Body {
            name: format!("balloon_{i}"),
            vertices: v0..v0 + nv,
            faces: f0..f0 + nf,
            pressure: Some(b.gauge_pressure()),
        });
        (v0, f0) = (v0 + nv, f0 + nf);
        rest.extend_from_slice(b.rest_positions());
        force.extend(balloon::fields::pressure_forces(
            b.positions(),
            b.triangles(),
            b.gauge_pressure(),
        )?);
        thickness.extend_from_slice(b.thickness());
    }
    let mut f = Frame::new(
        step,
        Simulation::time(sim),
        surface.positions.to_vec(),
        surface.triangles.to_vec(),
    )
    .with_velocity(Simulation::velocities(sim).to_vec())?
    .with_stretch(&rest)?
    .with_bodies(bodies);
    f.point_data.push(Field::vector("pressure_force", force));
    f.cell_data.push(Field::scalar("thickness", thickness));
    Ok(f)
}

/// The thin sphere of equal spherical membrane balloons with a uniform wall (radius
/// `3 V0 / A0` of the rest mesh), with the membrane, or why there is none.
fn sphere_of(
    sim: &ConnectSim,
    args: &ShellScenario,
    material: &ShellMaterialModel,
) -> Result<(ThinSphere, MembraneModel), String> {
    let ShellMaterialModel::Membrane(m) = material else {
        return Err("the material is not a membrane (`material` = membrane-...)".into());
    };
    if args.shell.thickness_file.is_some() || args.shell.thickness_rule.is_some() {
        return Err("the wall is not uniform (`thickness_file` / `thickness_rule`)".into());
    }
    let b = sim.balloons();
    let v0 = b[0].rest_gas_volume();
    let mut radius = 0.0;
    for (i, s) in b.iter().enumerate() {
        let mut mesh = s.mesh();
        mesh.set_positions_flat(s.rest_positions());
        let c = mesh
            .vertices
            .iter()
            .fold(nalgebra::Vector3::zeros(), |a, p| a + p.coords)
            / mesh.num_vertices() as f64;
        let d: Vec<f64> = mesh
            .vertices
            .iter()
            .map(|p| (p.coords - c).norm())
            .collect();
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        if d.iter().any(|r| (r / mean - 1.0).abs() > 0.01) {
            return Err(format!(
                "balloon {i} is not a sphere (its vertices' distances from its centre vary by more than 1%)"
            ));
        }
        if (s.rest_gas_volume() / v0 - 1.0).abs() > 1e-9 {
            return Err(format!(
                "balloon {i}'s rest volume differs from balloon 0's"
            ));
        }
        radius = 3.0 * geometry::enclosed_volume(&mesh) / geometry::surface_area(&mesh);
    }
    let sphere = ThinSphere::try_new(radius, args.shell.thickness).map_err(|e| e.to_string())?;
    Ok((sphere, m.clone()))
}

/// What `connect` adds to the shared run loop: the balloons' paths, settling, the summary.
struct ConnectHooks<'a> {
    args: &'a ConnectScenario,
    /// The resolved scenario, repeated in the summary.
    record: Option<String>,
    summary: ConnectSummary,
    /// The analytic thin sphere and the membrane, when the balloons are equal spheres.
    sphere: Option<(ThinSphere, MembraneModel)>,
    /// The analytic end state `(radius, l_small, l_large, P)`, or why there is none.
    analytic_end: Result<(f64, f64, f64, f64), String>,
    /// Each balloon's `(stretch, gauge pressure)` path, from the start.
    paths: Vec<Vec<(f64, f64)>>,
    /// Steps in a row meeting the `until_settled` tolerances.
    calm: usize,
    /// Previous volumes (for the relative change per step).
    volumes: Vec<f64>,
    /// The merged positions when connected (the start render).
    start: Frame,
}

impl ConnectHooks<'_> {
    fn until_settled(&self) -> bool {
        self.args.connect.until_settled || self.args.shell.run.until_converged
    }

    /// The analytic end state with the run's differences from it, `None` with a note when
    /// there is none.
    fn analytic(&self, sim: &ConnectSim) -> (Option<AnalyticPair>, Option<String>) {
        let (radius, ls, ll, p) = match &self.analytic_end {
            Ok(e) => *e,
            Err(note) => return (None, Some(note.clone())),
        };
        let l = sim.stretches();
        let g = sim.gauge_pressures();
        let (small, large) = if l[0] <= l[1] { (0, 1) } else { (1, 0) };
        (
            Some(AnalyticPair {
                radius,
                small_stretch: ls,
                large_stretch: ll,
                gauge_pressure: p,
                small_stretch_error: (l[small] / ls - 1.0).abs(),
                large_stretch_error: (l[large] / ll - 1.0).abs(),
                pressure_error: (g[large] / p - 1.0).abs(),
            }),
            None,
        )
    }
}

/// The analytic end state `(radius, l_small, l_large, P)` of two equal spherical membrane
/// balloons holding `total` (J) of gas (`ThinSphere::joined_pair`), or why there is none.
fn analytic_end(
    sim: &ConnectSim,
    sphere: &Result<(ThinSphere, MembraneModel), String>,
    total: f64,
) -> Result<(f64, f64, f64, f64), String> {
    let (sphere, m) = sphere.as_ref().map_err(Clone::clone)?;
    if sim.balloons().len() != 2 {
        return Err("the analytic end state is for two balloons".into());
    }
    let b = &sim.balloons()[0];
    match sphere.joined_pair(m, b.ambient_pressure(), b.rest_gas_volume(), total, 10.0) {
        Ok(Some((ls, ll, p))) => Ok((sphere.radius(), ls, ll, p)),
        Ok(None) => Err(
            "no equal-pressure state with one balloon on each side of the pressure maximum for \
             this amount of gas (or the material has no maximum)"
                .into(),
        ),
        Err(e) => Err(e.to_string()),
    }
}

impl RunHooks<ConnectSim> for ConnectHooks<'_> {
    type Summary = ConnectSummary;

    fn scenario(&self) -> Option<String> {
        self.record.clone()
    }

    fn frame(&self, sim: &ConnectSim, step: usize) -> Result<Frame> {
        frame(sim, step)
    }

    fn after_step(
        &mut self,
        _sim: &ConnectSim,
        stats: &SimulationStats<ConnectedStepStats>,
        _out: Option<&mut OutputDir>,
        _regular: bool,
    ) -> Result<bool> {
        let d = &stats.detail;
        for (i, path) in self.paths.iter_mut().enumerate() {
            path.push((d.stretches[i], d.gauge_pressures[i]));
        }
        let still = d
            .volumes
            .iter()
            .zip(&self.volumes)
            .all(|(v, old)| (v / old - 1.0).abs() < self.args.shell.run.volume_tol)
            && d.balloons
                .iter()
                .all(|b| b.max_speed < self.args.shell.run.speed_tol);
        self.volumes.clone_from(&d.volumes);
        self.calm = if still { self.calm + 1 } else { 0 };
        self.summary.settled = self.until_settled() && self.calm >= SETTLE_STEPS;
        Ok(self.summary.settled)
    }

    fn progress(&self, stats: &SimulationStats<ConnectedStepStats>) -> Option<String> {
        let d = &stats.detail;
        Some(
            d.stretches
                .iter()
                .zip(&d.gauge_pressures)
                .map(|(l, p)| format!("l = {l:.4}, p = {p:.0} Pa"))
                .collect::<Vec<_>>()
                .join("; "),
        )
    }

    fn finish_extras(&mut self, out: &mut OutputDir, last: &Frame) -> Result<()> {
        out.write_named_frame("final", last)?;
        write_render(out, "pair_start.png", &self.start, "connected")?;
        write_render(out, "pair_end.png", last, "end")?;
        write_plot(
            out,
            &self.args.shell.mesh.path,
            self.sphere.as_ref(),
            &self.paths,
            self.analytic_end.as_ref().ok(),
        )
    }

    fn summary(&self, sim: &ConnectSim, run: &RunRecord<ConnectedStepStats>) -> ConnectSummary {
        let (l, g, a) = (sim.stretches(), sim.gauge_pressures(), sim.amounts());
        let states = self
            .summary
            .balloon_states
            .iter()
            .zip(sim.balloons())
            .enumerate()
            .map(|(i, (s, b))| BalloonState {
                stretch: l[i],
                gas_volume: b.gas_volume(),
                gauge_pressure: g[i],
                amount: a[i],
                ..s.clone()
            })
            .collect();
        let (analytic, analytic_note) = self.analytic(sim);
        let status = if run.failure.is_some() {
            "failed"
        } else if run.interrupted.is_some() {
            "interrupted"
        } else {
            "ok"
        };
        ConnectSummary {
            status: status.into(),
            mesh: self.summary.mesh.clone(),
            layout: self.summary.layout.clone(),
            tubes: self.summary.tubes.clone(),
            conductance: self.summary.conductance.clone(),
            material: self.summary.material.clone(),
            material_parameters: self.summary.material_parameters.clone(),
            steps: run.steps,
            sim_time_s: sim.time(),
            total_amount_end: sim.total_amount(),
            balloon_states: states,
            analytic,
            analytic_note,
            error: run.failure.as_ref().map(|e| e.to_string()),
            ..self.summary
        }
    }

    fn print(
        &self,
        summary: &ConnectSummary,
        out: Option<&OutputDir>,
        w: &mut dyn std::io::Write,
    ) -> std::io::Result<()> {
        let ends: Vec<String> = summary
            .balloon_states
            .iter()
            .map(|b| {
                format!(
                    "l {:.4} -> {:.4} at {:.1} Pa",
                    b.start_stretch, b.stretch, b.gauge_pressure
                )
            })
            .collect();
        writeln!(
            w,
            "{} balloons, {} steps, t = {:.3} s{}: {}; total amount x{:.12}",
            summary.balloons,
            summary.steps,
            summary.sim_time_s,
            if summary.settled { ", settled" } else { "" },
            ends.join("; "),
            summary.total_amount_end / summary.total_amount_start
        )?;
        if let Some(a) = &summary.analytic {
            writeln!(
                w,
                "analytic end state (thin sphere): l = {:.4} and {:.4} at {:.1} Pa (stretch errors {:.1e}, {:.1e}; pressure error {:.1e})",
                a.small_stretch,
                a.large_stretch,
                a.gauge_pressure,
                a.small_stretch_error,
                a.large_stretch_error,
                a.pressure_error
            )?;
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
            &format!("the connected balloons of `{}`", self.args.shell.mesh.path),
            step,
            self.args.shell.output.out.as_deref(),
        )
    }
}

/// Writes a render of `frame` (all balloons) to `name`.
fn write_render(out: &OutputDir, name: &str, frame: &Frame, what: &str) -> Result<()> {
    use balloon_render::{RenderOptions, Renderer, Surface};
    let opts = RenderOptions {
        camera: style().camera,
        cull_back_faces: true,
        title: Some(format!(
            "connect ({what}): step {}  t = {} s",
            frame.step,
            balloon_render::format_tick(frame.time)
        )),
        ..RenderOptions::new(800, 450)
    };
    let surface = Surface::new(&frame.positions, &frame.triangles);
    let mut renderer = Renderer::new();
    out.write_file(name, |tmp| {
        renderer
            .render(&surface, &opts, None)
            .and_then(|img| img.write_png(tmp))
            .with_context(|| format!("cannot render {name}"))
    })?;
    Ok(())
}

/// Writes `pressure_stretch.png`: each balloon's path (stretch, gauge pressure) over the
/// analytic thin-sphere curve `P(l)` when there is one.
fn write_plot(
    out: &OutputDir,
    mesh: &str,
    sphere: Option<&(ThinSphere, MembraneModel)>,
    paths: &[Vec<(f64, f64)>],
    analytic: Option<&(f64, f64, f64, f64)>,
) -> Result<()> {
    use balloon_render::plot::{LinePlot, PlotSeries};
    let mut plot = LinePlot::new(
        format!("connected balloons of {mesh}: gauge pressure vs stretch"),
        "stretch l = (V / V0)^(1/3)",
        "gauge pressure (Pa)",
    );
    if let Some((sphere, m)) = sphere {
        let top = paths.iter().flatten().map(|p| p.0).fold(1.5_f64, f64::max) * 1.1;
        let curve = (0..=400)
            .map(|i| {
                let l = 1.0 + (top - 1.0) * f64::from(i) / 400.0;
                (l, sphere.pressure(m, l))
            })
            .collect();
        plot = plot.with_series(PlotSeries::line("analytic thin sphere", curve, 0));
    }
    for (i, p) in paths.iter().enumerate() {
        plot = plot.with_series(PlotSeries::line(format!("balloon {i}"), p.clone(), 1 + i));
    }
    if let Some(&(_, ls, ll, p)) = analytic {
        plot = plot.with_series(PlotSeries::line_points(
            "analytic end state (one pressure)",
            vec![(ls, p), (ll, p)],
            1 + paths.len(),
        ));
    }
    out.write_file("pressure_stretch.png", |tmp| {
        plot.render(960, 640)
            .and_then(|img| img.write_png(tmp))
            .context("cannot draw pressure_stretch.png")
    })?;
    Ok(())
}

/// Runs a connected-balloons scenario as a job (call [`ConnectScenario::validate`] first):
/// checks the output folder, builds and pre-inflates the balloons
/// ([`ConnectScenario::build`]), writes the resolved `record` to `OUT/scenario.toml`, takes the
/// steps, and writes and returns the summary with the final balloons. `quiet` prints nothing
/// (no progress bar, no summary line).
pub fn run(
    args: &ConnectScenario,
    record: Option<&str>,
    quiet: bool,
) -> Result<Finished<ConnectSim>> {
    let shell = &args.shell;
    let material = shell.material()?;
    let render_spec = shell
        .output
        .check_pictures("connect", SHELL_COLORS)
        .map_err(anyhow::Error::msg)?;
    if let Some(dir) = &shell.output.out {
        crate::output::check_out_dir(dir, shell.output.overwrite)?;
    }
    let (mut sim, layout) = args.build()?;
    let out = match &shell.output.out {
        Some(dir) => {
            // The earlier run's files go only now that this run is set up.
            crate::output::prepare_out_dir(dir, shell.output.overwrite)?;
            Some(OutputDir::create(dir, shell.output.format)?.with_pictures(
                &shell.output,
                render_spec,
                style(),
            )?)
        }
        None => None,
    };
    // Resolved like a shell run's record: the material's defaults and the projection made
    // explicit (the gas is the ideal gas, so there is no pump rate to resolve).
    let mut ideal = shell.clone();
    ideal.gas.model = GasControl::Ideal;
    let record = match (record, sim.balloons().first()) {
        (Some(text), Some(first)) => Some(resolve_shell_record(
            text,
            &ideal,
            &material,
            first.rest_gas_volume(),
        )),
        (Some(text), None) => Some(text.to_owned()),
        (None, _) => None,
    };
    if let (Some(o), Some(text)) = (&out, &record) {
        o.write_text("scenario.toml", text)?;
    }
    let sphere = sphere_of(&sim, shell, &material);
    let (l, g, a) = (sim.stretches(), sim.gauge_pressures(), sim.amounts());
    let summary = ConnectSummary {
        status: "ok".into(),
        mesh: shell.mesh.path.clone(),
        layout: layout.into(),
        balloons: sim.balloons().len(),
        tubes: sim.tubes().iter().map(|t| [t.a, t.b]).collect(),
        conductance: match args.connect.conductance {
            Conductance::Finite(k) => k.to_string(),
            Conductance::Instant => "instant".into(),
        },
        total_amount_start: sim.total_amount(),
        material: material.name(),
        material_parameters: Some(material),
        balloon_states: sim
            .balloons()
            .iter()
            .enumerate()
            .map(|(i, b)| BalloonState {
                vertices: b.positions().len() / 3,
                rest_gas_volume: b.rest_gas_volume(),
                start_stretch: l[i],
                start_gauge_pressure: g[i],
                stretch: l[i],
                gas_volume: b.gas_volume(),
                gauge_pressure: g[i],
                amount: a[i],
            })
            .collect(),
        ..Default::default()
    };
    let analytic_end = analytic_end(&sim, &sphere, summary.total_amount_start);
    let plan = RunPlan {
        steps: shell.run.steps,
        frames: FramePolicy {
            every: shell.output.frame_every,
            last: false,
        },
        json: shell.output.json,
        quiet,
    };
    let mut hooks = ConnectHooks {
        args,
        record,
        paths: l.iter().zip(&g).map(|(&l, &p)| vec![(l, p)]).collect(),
        volumes: sim.balloons().iter().map(|b| b.gas_volume()).collect(),
        start: frame(&sim, 0)?,
        summary,
        sphere: sphere.ok(),
        analytic_end,
        calm: 0,
    };
    let summary = run_simulation(&mut sim, &mut hooks, &plan, out)?;
    Ok(Finished {
        summary: Some(summary),
        sim,
    })
}
