//! `balloon connect [MESH|builtin]`: several shell balloons, each with its own isothermal ideal
//! gas, joined by tubes (issue 14, item 4: the two-balloon experiment), on
//! [`balloon::shell::connected::ConnectedBalloons`].
//!
//! The balloons are either `--copies N` of one mesh, placed side by side along x, or the
//! connected components of the mesh (split by topology). Each is pre-inflated statically to a
//! linear stretch (`--stretches`, volume control, then it holds that gas:
//! `ShellSimulation::inflate_to_volume`) or starts at rest holding the ideal gas at a gauge
//! pressure (`--pressures`), then the tubes (`--tubes`, default a chain) let gas flow with a
//! conductance (`--conductance`, m^3/s, or `instant`). Every other flag is `balloon inflate`'s
//! (material, wall, time stepping, solvers, output), parsed by the same [`InflateArgs`].
//!
//! The output folder holds frames with all balloons merged into one surface, `stats.jsonl`
//! (per step each balloon's gauge pressure, gas volume, amount and stretch, and the total
//! amount), `summary.json` (per-balloon end states and, for two equal spherical membrane
//! balloons, the analytic end state of `ThinSphere::joined_pair` with the differences),
//! `pair_start.png` / `pair_end.png` (renders) and `pressure_stretch.png` (each balloon's path
//! in the pressure-stretch plane, over the analytic thin-sphere curve where there is one).

use crate::cmd_inflate::{InflateArgs, ShellSim};
use crate::cmd_static::GasArg;
use crate::output::{ColorField, Field, Frame, OutputDir, PictureStyle, check_picture_args};
use crate::params::{End::Closed, End::Open, check_real};
use crate::run::{Finished, FramePolicy, RunHooks, RunPlan, RunRecord, run_simulation};
use anyhow::{Context, Result, bail};
use balloon::material::MembraneModel;
use balloon::material::membrane::ThinSphere;
use balloon::mesh::geometry;
use balloon::mesh::topology::Topology;
use balloon::shell::ShellMaterialModel;
use balloon::shell::connected::{Conductance, ConnectedBalloons, ConnectedStepStats, Tube};
use balloon::shell::statics::StaticOptions;
use balloon::{SimulationError, SimulationStats};
use balloon_mesh::TriMesh;
use balloon_render::UpAxis;
use serde::Serialize;

/// Most balloons a run may connect.
pub const MAX_BALLOONS: usize = 1000;

/// Steps in a row that must meet the tolerances for `--until-settled`.
pub const SETTLE_STEPS: usize = 20;

/// Tubes given as `A-B` pairs of balloon indices (`--tubes 0-1,1-2`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TubeList(pub Vec<(usize, usize)>);

/// `--tubes`: a comma list of `A-B` pairs of 0-based balloon indices.
pub fn parse_tubes(s: &str) -> Result<TubeList, String> {
    let mut out = Vec::new();
    for part in s.split(',') {
        let part = part.trim();
        let pair = part.split_once('-').and_then(|(a, b)| {
            Some((
                a.trim().parse::<usize>().ok()?,
                b.trim().parse::<usize>().ok()?,
            ))
        });
        match pair {
            Some((a, b)) if a != b => out.push((a, b)),
            Some(_) => return Err(format!("`{part}` joins a balloon to itself")),
            None => {
                return Err(format!(
                    "`{part}` is not a pair A-B of balloon indices (0-based, e.g. 0-1,1-2)"
                ));
            }
        }
    }
    Ok(TubeList(out))
}

/// `--conductance`: `instant` or a conductance in m^3/s, in (0, 1e6].
pub fn parse_conductance(s: &str) -> Result<Conductance, String> {
    if s.trim().eq_ignore_ascii_case("instant") {
        return Ok(Conductance::Instant);
    }
    check_real(s, Open(0.0), Closed(1e6))
        .map(Conductance::Finite)
        .map_err(|e| format!("{e}, or `instant`"))
}

/// Arguments of `balloon connect`: those of `balloon inflate` and the connection's.
#[derive(Debug, clap::Args)]
pub struct ConnectArgs {
    /// The flags of `balloon inflate` (mesh, material, wall, time stepping, solvers, output).
    /// The gas is the isothermal ideal gas (`--gas ideal`, the only one allowed); `--static`,
    /// `--pressure`, `--pump-rate`, `--pin` and `--load` are refused.
    #[command(flatten)]
    pub shell: InflateArgs,
    /// Connect N copies of the mesh (1 to 1000), placed side by side along x; without it, the
    /// balloons are the mesh's connected components.
    #[arg(long, value_parser = crate::params::count(1, MAX_BALLOONS))]
    pub copies: Option<usize>,
    /// Pre-inflate each balloon statically to this linear stretch (V / V0)^(1/3), each in
    /// (0, 10], comma-separated, one per balloon; it then holds that gas.
    #[arg(long, value_delimiter = ',', num_args = 1, conflicts_with = "pressures",
          value_parser = crate::params::real(Open(0.0), Closed(10.0)))]
    pub stretches: Option<Vec<f64>>,
    /// Start each balloon at rest holding the ideal gas at this gauge pressure (Pa, each in
    /// [-1e7, 1e7]), comma-separated, one per balloon.
    #[arg(long, value_delimiter = ',', num_args = 1, allow_hyphen_values = true,
          value_parser = crate::params::real(Closed(-1e7), Closed(1e7)))]
    pub pressures: Option<Vec<f64>>,
    /// Tubes as `A-B` pairs of 0-based balloon indices, comma-separated (e.g. `0-1,1-2`);
    /// default: a chain 0-1, 1-2, ...
    #[arg(long, value_parser = parse_tubes)]
    pub tubes: Option<TubeList>,
    /// Conductance of every tube, m^3/s in (0, 1e6] (flow in nRT units = conductance x
    /// pressure difference), or `instant` (the joined balloons share one pressure after every
    /// step).
    #[arg(long, default_value = "instant", allow_hyphen_values = true, value_parser = parse_conductance)]
    pub conductance: Conductance,
    /// Stop when, for 20 steps in a row, every balloon's per-step relative gas volume change is
    /// below --volume-tol and its largest vertex speed below --speed-tol (--steps is then the
    /// most steps). `--until-converged` means the same here.
    #[arg(long)]
    pub until_settled: bool,
}

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

/// The run summary (`summary.json`, and the `--json` line).
#[derive(Debug, Default, Serialize)]
pub struct ConnectSummary {
    /// `ok`, `failed` or `interrupted`.
    pub status: String,
    /// Mesh given on the command line.
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
    /// Whether --until-settled reached its tolerances.
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

const STYLE_FIELDS: &[ColorField] = &[
    ColorField::Thickness,
    ColorField::Stretch,
    ColorField::Speed,
];

fn style() -> PictureStyle {
    let mut s = PictureStyle::new("connect", UpAxis::Y, ColorField::Stretch, STYLE_FIELDS);
    s.closed = true;
    s.camera.azimuth_deg = 0.0;
    s
}

/// The connected balloons `balloon connect` runs.
pub type ConnectSim = ConnectedBalloons<ShellMaterialModel>;

/// The mesh's connected components (through shared edges) as separate meshes, in the order of
/// their first triangle; vertices used by no triangle are dropped.
pub fn split_components(mesh: &TriMesh) -> Vec<TriMesh> {
    let (label, count) = Topology::new(mesh).triangle_components();
    let mut parts: Vec<(Vec<usize>, Vec<[usize; 3]>)> = vec![(Vec::new(), Vec::new()); count];
    let mut index = vec![usize::MAX; mesh.num_vertices()];
    for (t, &c) in mesh.triangles.iter().zip(&label) {
        let (verts, tris) = &mut parts[c];
        let tri = t.map(|v| {
            if index[v] == usize::MAX {
                index[v] = verts.len();
                verts.push(v);
            }
            index[v]
        });
        tris.push(tri);
    }
    parts
        .into_iter()
        .map(|(verts, tris)| TriMesh::new(verts.iter().map(|&v| mesh.vertices[v]).collect(), tris))
        .collect()
}

/// Checks the flags `balloon inflate` has but `connect` does not use.
fn check_shell_flags(args: &ConnectArgs) -> Result<()> {
    let s = &args.shell;
    if !matches!(s.gas, GasArg::Ideal | GasArg::Pump) {
        bail!(
            "--gas {}: connected balloons hold the isothermal ideal gas (leave --gas out or give \
             --gas ideal)",
            s.gas
        );
    }
    let refused = [
        (s.static_solve, "--static", ""),
        (s.volume_ratio.is_some(), "--volume-ratio", ""),
        (s.volume_ratios.is_some(), "--volume-ratios", ""),
        (s.pump_rate.is_some(), "--pump-rate", ""),
        (!s.setup.pin.is_empty(), "--pin", ""),
        (!s.setup.load.is_empty(), "--load", ""),
        (
            s.pressure != balloon::shell::DEFAULT_GAUGE_PRESSURE,
            "--pressure",
            " (give --pressures, one gauge pressure per balloon, or --stretches)",
        ),
    ];
    if let Some((_, flag, hint)) = refused.iter().find(|(given, ..)| *given) {
        bail!("{flag}: not used by `balloon connect`{hint}");
    }
    if args.stretches.is_none() && args.pressures.is_none() {
        bail!(
            "give --stretches (pre-inflate each balloon to a stretch) or --pressures (start each \
             at a gauge pressure), one value per balloon"
        );
    }
    Ok(())
}

/// The balloons' meshes: `--copies N` of the mesh side by side along x (the spacing from the
/// bounding box and the largest start stretch), or its components.
fn balloon_meshes(args: &ConnectArgs) -> Result<(Vec<TriMesh>, &'static str)> {
    let s = &args.shell;
    let mut mesh =
        balloon::mesh::load(&s.mesh).with_context(|| format!("cannot load mesh `{}`", s.mesh))?;
    if s.scale != 1.0 {
        mesh.scale(s.scale);
    }
    crate::params::apply_transform(&mut mesh, s.transform.as_deref())
        .map_err(anyhow::Error::msg)?;
    let Some(n) = args.copies else {
        let parts = split_components(&mesh);
        if parts.len() < 2 {
            bail!(
                "`{}` has {} connected component(s): give --copies N to connect N copies of it, \
                 or a mesh whose components are the balloons",
                s.mesh,
                parts.len()
            );
        }
        return Ok((parts, "components"));
    };
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in &mesh.vertices {
        lo = lo.min(p.x);
        hi = hi.max(p.x);
    }
    let grow = args
        .stretches
        .iter()
        .flatten()
        .copied()
        .fold(1.5_f64, f64::max);
    let spacing = 1.3 * grow * (hi - lo);
    Ok((
        (0..n)
            .map(|i| {
                let mut m = mesh.clone();
                for p in &mut m.vertices {
                    p.x += spacing * i as f64;
                }
                m
            })
            .collect(),
        "copies",
    ))
}

/// The tubes: `--tubes` or a chain, each with `--conductance`; an index out of range names the
/// flag.
fn tubes(args: &ConnectArgs, n: usize) -> Result<Vec<Tube>> {
    let pairs = match &args.tubes {
        Some(t) => t.0.clone(),
        None => (1..n).map(|i| (i - 1, i)).collect(),
    };
    if let Some((a, b)) = pairs.iter().find(|(a, b)| *a >= n || *b >= n) {
        bail!(
            "--tubes: {a}-{b} names a balloon beyond the {n} there are (indices 0 to {})",
            n - 1
        );
    }
    Ok(pairs
        .into_iter()
        .map(|(a, b)| Tube {
            a,
            b,
            conductance: args.conductance,
        })
        .collect())
}

/// A list flag's values, one per balloon.
fn per_balloon<'a>(flag: &str, values: &'a [f64], n: usize) -> Result<&'a [f64]> {
    if values.len() != n {
        bail!(
            "{flag} has {} value(s) but there are {n} balloons (one value per balloon)",
            values.len()
        );
    }
    Ok(values)
}

/// Builds the connected balloons of `args`: loads and places the meshes, builds every balloon
/// as `balloon inflate` does (with the ideal gas), pre-inflates them and joins them. Writes
/// nothing.
pub fn build(args: &mut ConnectArgs) -> Result<(ConnectSim, &'static str)> {
    check_shell_flags(args)?;
    let (meshes, layout) = balloon_meshes(args)?;
    let n = meshes.len();
    let tubes = tubes(args, n)?;
    let stretches = args
        .stretches
        .as_deref()
        .map(|v| per_balloon("--stretches", v, n))
        .transpose()?
        .map(<[f64]>::to_vec);
    let pressures = args
        .pressures
        .as_deref()
        .map(|v| per_balloon("--pressures", v, n))
        .transpose()?
        .map(<[f64]>::to_vec);
    args.shell.gas = GasArg::Ideal;
    let mut options = StaticOptions::default();
    if args.shell.newton_tol > 0.0 {
        options.solver.tolerance = args.shell.newton_tol;
    }
    options.solver.tangent = args.shell.tangent;
    options.solver.inexact_forcing = args.shell.inexact_forcing;
    options.solver.solver.linear.kind = args.shell.linear_solver;
    options.solver.solver.linear.max_iterations = args.shell.cg_max_iters;
    options.solver.solver.pcg_preconditioner = args.shell.pcg_preconditioner;
    let mut balloons: Vec<ShellSim> = Vec::with_capacity(n);
    for (i, mesh) in meshes.into_iter().enumerate() {
        if let Some(p) = &pressures {
            args.shell.pressure = p[i];
        }
        let mut sim = crate::cmd_inflate::build(&args.shell, Some(mesh))
            .with_context(|| format!("balloon {i}"))?;
        if let Some(l) = &stretches {
            let target = sim.rest_gas_volume() * l[i].powi(3);
            sim.inflate_to_volume(target, &options).with_context(|| {
                format!(
                    "balloon {i}: pre-inflating to the stretch {} (--stretches)",
                    l[i]
                )
            })?;
        }
        balloons.push(sim);
    }
    args.shell.pressure = balloon::shell::DEFAULT_GAUGE_PRESSURE;
    let sim = ConnectedBalloons::new(balloons, tubes).context("connecting the balloons")?;
    Ok((sim, layout))
}

/// The current state of all balloons as one frame: velocity, speed, pressure force (Eq. 15),
/// thickness, stretch and max_stretch against the rest shapes.
fn frame(sim: &ConnectSim, step: usize) -> Result<Frame> {
    use balloon::Simulation;
    let surface = sim.surface();
    let (mut rest, mut force, mut thickness) = (Vec::new(), Vec::new(), Vec::new());
    for b in sim.balloons() {
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
    .with_stretch(&rest)?;
    f.point_data.push(Field::vector("pressure_force", force));
    f.cell_data.push(Field::scalar("thickness", thickness));
    Ok(f)
}

/// The thin sphere of equal spherical membrane balloons with a uniform wall (radius
/// `3 V0 / A0` of the rest mesh), with the membrane, or why there is none.
fn sphere_of(
    sim: &ConnectSim,
    args: &InflateArgs,
    material: &ShellMaterialModel,
) -> Result<(ThinSphere, MembraneModel), String> {
    let ShellMaterialModel::Membrane(m) = material else {
        return Err("the material is not a membrane (--material membrane-...)".into());
    };
    if args.setup.thickness_file.is_some() || args.setup.thickness_rule.is_some() {
        return Err("the wall is not uniform (--thickness-file / --thickness-rule)".into());
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
    let sphere = ThinSphere::try_new(radius, args.thickness).map_err(|e| e.to_string())?;
    Ok((sphere, m.clone()))
}

/// What `connect` adds to the shared run loop: the balloons' paths, settling, the summary.
struct ConnectHooks<'a> {
    args: &'a ConnectArgs,
    /// The resolved scenario ([`crate::cmd_inflate::resolved_record`]), repeated in the summary.
    record: Option<String>,
    summary: ConnectSummary,
    /// The analytic thin sphere and the membrane, when the balloons are equal spheres.
    sphere: Option<(ThinSphere, MembraneModel)>,
    /// The analytic end state `(radius, l_small, l_large, P)`, or why there is none.
    analytic_end: Result<(f64, f64, f64, f64), String>,
    /// Each balloon's `(stretch, gauge pressure)` path, from the start.
    paths: Vec<Vec<(f64, f64)>>,
    /// Steps in a row meeting the --until-settled tolerances.
    calm: usize,
    /// Previous volumes (for the relative change per step).
    volumes: Vec<f64>,
    /// The merged positions when connected (the start render).
    start: Frame,
}

impl ConnectHooks<'_> {
    fn until_settled(&self) -> bool {
        self.args.until_settled || self.args.shell.until_converged
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
            .all(|(v, old)| (v / old - 1.0).abs() < self.args.shell.volume_tol)
            && d.balloons
                .iter()
                .all(|b| b.max_speed < self.args.shell.speed_tol);
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
            &self.args.shell.mesh,
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
            &format!("the connected balloons of `{}`", self.args.shell.mesh),
            step,
            self.args.shell.out.as_deref(),
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

/// The resolved scenario as it ran: `--gas` left at inflate's default (pump) is the ideal gas
/// here, so that is what the record says.
fn recorded(text: &str) -> String {
    text.replace("\nmodel = \"pump\"\n", "\nmodel = \"ideal\"\n")
}

/// Runs `balloon connect`.
pub fn run(args: ConnectArgs) -> Result<()> {
    execute(args, false).map(drop)
}

/// Runs the job of `balloon connect` (checks, [`build`], the output folder, the steps, the
/// summary) and returns the summary as `summary.json` holds it, with the final balloons.
/// `quiet` prints nothing (no progress bar, no summary line).
pub fn execute(mut args: ConnectArgs, quiet: bool) -> Result<Finished<ConnectSim>> {
    let material = args.shell.material.resolve()?;
    let render_spec =
        check_picture_args(&args.shell.pictures, args.shell.out.as_deref(), &style())?;
    if let Some(dir) = &args.shell.out {
        crate::output::prepare_out_dir(dir, args.shell.overwrite)?;
    }
    if args.shell.steps == 0 {
        bail!("nothing to do: --steps is 0");
    }
    let (mut sim, layout) = build(&mut args)?;
    let args = &args;
    let out = match &args.shell.out {
        Some(dir) => Some(OutputDir::create(dir, args.shell.format)?.with_pictures(
            &args.shell.pictures,
            render_spec,
            style(),
        )?),
        None => None,
    };
    // Resolved like inflate's record: the material's defaults and the projection made
    // explicit (the balloons are built by `cmd_inflate::build` with the same shell flags; the
    // gas is the ideal gas, so there is no pump rate to resolve).
    let record = match (&args.shell.scenario_record, sim.balloons().first()) {
        (Some(text), Some(first)) => Some(crate::cmd_inflate::resolved_record(
            &recorded(text),
            &args.shell,
            &material,
            first,
        )),
        (Some(text), None) => Some(recorded(text)),
        (None, _) => None,
    };
    if let (Some(o), Some(text)) = (&out, &record) {
        o.write_text("scenario.toml", text)?;
    }
    let sphere = sphere_of(&sim, &args.shell, &material);
    let (l, g, a) = (sim.stretches(), sim.gauge_pressures(), sim.amounts());
    let summary = ConnectSummary {
        status: "ok".into(),
        mesh: args.shell.mesh.clone(),
        layout: layout.into(),
        balloons: sim.balloons().len(),
        tubes: sim.tubes().iter().map(|t| [t.a, t.b]).collect(),
        conductance: match args.conductance {
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
        steps: args.shell.steps,
        frames: FramePolicy {
            every: args.shell.frame_every,
            last: false,
        },
        json: args.shell.json,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tubes_and_conductances_parse_and_refuse_nonsense() {
        assert_eq!(
            parse_tubes("0-1, 1-2").unwrap(),
            TubeList(vec![(0, 1), (1, 2)])
        );
        for bad in ["0-0", "0", "a-b", "0-1,", "-1-2"] {
            assert!(parse_tubes(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_conductance("instant").unwrap(), Conductance::Instant);
        assert_eq!(parse_conductance("2.5").unwrap(), Conductance::Finite(2.5));
        for bad in ["0", "-1", "inf", "nan", "fast"] {
            let e = parse_conductance(bad).unwrap_err();
            assert!(e.contains("instant"), "{bad}: {e}");
        }
    }

    #[test]
    fn components_become_separate_meshes() {
        let a = balloon::mesh::generate::icosphere(0.1, 1).unwrap();
        let n = a.num_vertices();
        let mut both = a.clone();
        both.vertices
            .extend(a.vertices.iter().map(|p| p + nalgebra::Vector3::x() * 0.5));
        both.triangles
            .extend(a.triangles.iter().map(|t| t.map(|i| i + n)));
        let parts = split_components(&both);
        assert_eq!(parts.len(), 2);
        for (k, p) in parts.iter().enumerate() {
            assert_eq!(p.num_vertices(), n);
            assert_eq!(p.triangles.len(), a.triangles.len());
            let x = p.vertices.iter().map(|v| v.x).sum::<f64>() / n as f64;
            assert!((x - 0.5 * k as f64).abs() < 1e-12, "{x}");
            assert!(
                (geometry::enclosed_volume(p) / geometry::enclosed_volume(&a) - 1.0).abs() < 1e-12
            );
        }
    }
}
