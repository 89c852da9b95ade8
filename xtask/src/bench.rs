//! `cargo xtask bench`: the paper's Table 1 (Wang et al. 2015) for a folder of meshes and every linear
//! solver behind Newton, and the growth of the cost with size for the shell, volumetric and
//! two-layer systems. Writes `target/bench/bench.{md,json}`; `--update-docs` also writes
//! `docs/benchmarks.md`.

use crate::report::{loglog_slope, median};
use crate::validate::meshes;
use anyhow::{Context, Result};
use balloon::Simulation;
use balloon::constraint::cell_volume::{CellSolver, CellVolumeParams};
use balloon::integrate::TangentKind;
use balloon::integrate::implicit::BackwardEulerParams;
use balloon::integrate::linear::{LinearSolverKind, PcgPreconditioner};
use balloon::mesh::TriMesh;
use balloon::mesh::generate::teddy::{TeddyParams, teddy};
use balloon::mesh::generate::{icosphere, octahedron_sphere, torus};
use balloon::mesh::lattice::LatticeParams;
use balloon::shell::{DEFAULT_LINEAR_TOLERANCE, DEFAULT_MASS_DAMPING, ShellBalloon};
use balloon::two_layer::{ExplicitMethod, TwoLayerBody};
use balloon::volumetric::{VolumetricBody, VolumetricParams, VolumetricSimulation};
use nalgebra::Vector3;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

/// Options of `cargo xtask bench`.
#[derive(Clone, Debug)]
pub struct Options {
    /// Smaller sizes and fewer steps (a smoke run).
    pub quick: bool,
    /// Folder of meshes for Table 1.
    pub meshes: Option<PathBuf>,
    /// Timed runs per measurement; the median is reported.
    pub runs: usize,
    /// Also write docs/benchmarks.md.
    pub update_docs: bool,
}

/// Names of the linear solver kinds known to this tool (`LinearSolverKind`'s `FromStr` names,
/// including ones that may be under development).
const SOLVER_NAMES: &[&str] = &["matrix-free-cg", "pcg", "cholesky", "factorized-pcg"];

/// Every linear solver kind the library accepts: the names that `LinearSolverKind` parses
/// (robust to kinds being added or withdrawn while the solvers are tuned).
fn all_solvers() -> Vec<LinearSolverKind> {
    SOLVER_NAMES.iter().filter_map(|n| n.parse().ok()).collect()
}

/// The (solver, tangent) pairs of Table 1: every solver with the exact tangent, and the solvers
/// that need an SPD matrix (and gain from one) with the projected tangent (projected Newton).
/// The iterative solvers with the projected tangent are left out: the regularised exact solves
/// are easier for CG than the true SPD systems (measured with
/// `cargo run --release -p balloon-benches --example step_profile`, see docs/benchmarks.md).
fn table1_configs() -> Vec<(LinearSolverKind, TangentKind)> {
    let mut v: Vec<_> = all_solvers()
        .into_iter()
        .filter(|k| k.to_string() != "factorized-pcg")
        .map(|k| (k, TangentKind::Exact))
        .collect();
    for k in all_solvers() {
        if k == LinearSolverKind::Cholesky || k.to_string() == "factorized-pcg" {
            v.push((k, TangentKind::Projected));
        }
    }
    v
}

/// One row of Table 1.
#[derive(Clone, Debug, Serialize)]
struct ShellRow {
    model: String,
    vertices: usize,
    faces: usize,
    solver: String,
    /// Tangent stiffness (`exact` or `projected`).
    tangent: String,
    /// Median over runs of the mean wall time per step, ms.
    ms_per_step: f64,
    /// Smallest and largest run mean, ms.
    ms_min: f64,
    ms_max: f64,
    /// Shell (material) volume ratio after the last step.
    volume_ratio: f64,
    /// Largest |ratio - 1| over all timed steps.
    worst_volume_error: f64,
    /// Mean CG iterations per step (0 for Cholesky).
    linear_iterations_per_step: f64,
    /// Gas volume ratio V / V0 at the end.
    gas_volume_ratio: f64,
    /// An error that stopped the run, if any.
    error: Option<String>,
}

/// One size of a cost-vs-size study.
#[derive(Clone, Debug, Serialize)]
struct SizePoint {
    label: String,
    /// Particles or vertices.
    vertices: usize,
    ms_per_step: f64,
    steps_per_second: f64,
}

/// A cost-vs-size study with its fitted exponent `ms ~ vertices^k`.
#[derive(Clone, Debug, Serialize)]
struct Scaling {
    system: String,
    setting: String,
    points: Vec<SizePoint>,
    exponent: f64,
}

#[derive(Serialize)]
struct BenchReport {
    machine: String,
    load: String,
    command: String,
    runs: usize,
    steps_per_run: usize,
    table1: Vec<ShellRow>,
    scaling: Vec<Scaling>,
}

fn time_shell(
    model: &str,
    mesh: &TriMesh,
    kind: LinearSolverKind,
    tangent: TangentKind,
    opts: &Options,
    steps: usize,
) -> ShellRow {
    let mut row = ShellRow {
        model: model.to_string(),
        vertices: mesh.num_vertices(),
        faces: mesh.num_triangles(),
        solver: kind.to_string(),
        tangent: tangent.to_string(),
        ms_per_step: f64::NAN,
        ms_min: f64::NAN,
        ms_max: f64::NAN,
        volume_ratio: f64::NAN,
        worst_volume_error: f64::NAN,
        linear_iterations_per_step: f64::NAN,
        gas_volume_ratio: f64::NAN,
        error: None,
    };
    // The shipped solver settings (`balloon inflate` defaults): CG tolerance 1e-3, incomplete
    // Cholesky for PCG; always all three Newton iterations, as the paper's timing.
    let mut params = BackwardEulerParams {
        newton_iterations: 3,
        newton_tolerance: 0.0,
        mass_damping: DEFAULT_MASS_DAMPING,
        pcg_preconditioner: PcgPreconditioner::IncompleteCholesky,
        tangent,
        ..Default::default()
    };
    params.linear.relative_tolerance = DEFAULT_LINEAR_TOLERANCE;
    let run = |row: &mut ShellRow| -> Result<()> {
        let mut sim = ShellBalloon::new(mesh.clone())
            .with_pump_rate(2e-3) // the fixed 2 L/s these figures were measured with
            .with_integrator(params)
            .with_linear_solver(kind)
            .build()?;
        for _ in 0..3 {
            sim.step()?; // warm-up: caches, symbolic factorisation
        }
        let mut per_run = Vec::new();
        let (mut worst, mut lin, mut n) = (0.0f64, 0usize, 0usize);
        let mut last = 1.0;
        for _ in 0..opts.runs {
            let t = Instant::now();
            for _ in 0..steps {
                let s = sim.step()?;
                worst = worst.max((s.shell_volume_ratio - 1.0).abs());
                lin += s.linear_iterations;
                n += 1;
                last = s.shell_volume_ratio;
            }
            per_run.push(t.elapsed().as_secs_f64() * 1e3 / steps as f64);
        }
        row.ms_per_step = median(&per_run);
        row.ms_min = per_run.iter().copied().fold(f64::INFINITY, f64::min);
        row.ms_max = per_run.iter().copied().fold(0.0, f64::max);
        row.volume_ratio = last;
        row.worst_volume_error = worst;
        row.linear_iterations_per_step = lin as f64 / n as f64;
        row.gas_volume_ratio = sim.gas_volume() / sim.rest_gas_volume();
        Ok(())
    };
    if let Err(e) = run(&mut row) {
        row.error = Some(format!("{e:#}"));
    }
    row
}

/// Default Table 1 models: built-in shapes of sizes comparable to the paper's (4k-16k vertices).
fn default_models(quick: bool) -> Result<Vec<(String, TriMesh)>> {
    let mut v = Vec::new();
    if quick {
        v.push(("icosphere L3".to_string(), icosphere(0.15, 3)?));
        v.push((
            "teddy (res 14)".to_string(),
            teddy(&TeddyParams {
                resolution: 14,
                ..Default::default()
            })?,
        ));
        return Ok(v);
    }
    v.push(("teddy".to_string(), teddy(&TeddyParams::default())?));
    v.push((
        "teddy (res 40)".to_string(),
        teddy(&TeddyParams {
            resolution: 40,
            ..Default::default()
        })?,
    ));
    v.push(("octasphere L5".to_string(), octahedron_sphere(0.15, 5)?));
    v.push(("torus 128x48".to_string(), torus(0.1, 0.04, 128, 48)?));
    Ok(v)
}

fn shell_scaling(opts: &Options) -> Result<Scaling> {
    // Issue 16 item 5: steps per second from level 2 to level 6 (real time at dt = 0.1 ms needs
    // 10000 steps per second).
    let levels: &[u32] = if opts.quick {
        &[1, 2, 3, 4]
    } else {
        &[2, 3, 4, 5, 6]
    };
    let mut points = Vec::new();
    for &l in levels {
        let mesh = icosphere(0.15, l)?;
        eprintln!("xtask bench: shell scaling, icosphere L{l}");
        let row = time_shell(
            &format!("icosphere L{l}"),
            &mesh,
            LinearSolverKind::Cholesky,
            TangentKind::Projected,
            opts,
            if opts.quick { 3 } else { 5 },
        );
        if let Some(e) = row.error {
            anyhow::bail!("shell scaling at level {l}: {e}");
        }
        points.push(SizePoint {
            label: format!("icosphere L{l}"),
            vertices: mesh.num_vertices(),
            ms_per_step: row.ms_per_step,
            steps_per_second: 1e3 / row.ms_per_step,
        });
    }
    Ok(finish(
        "shell",
        "pump, 3 Newton iterations, sparse Cholesky with the projected tangent (the shell's defaults)",
        points,
    ))
}

fn finish(system: &str, setting: &str, points: Vec<SizePoint>) -> Scaling {
    let pts: Vec<(f64, f64)> = points
        .iter()
        .map(|p| (p.vertices as f64, p.ms_per_step))
        .collect();
    Scaling {
        system: system.into(),
        setting: setting.into(),
        exponent: loglog_slope(&pts),
        points,
    }
}

fn volumetric_scaling(opts: &Options) -> Result<Scaling> {
    volumetric_scaling_with(opts, CellSolver::GaussSeidel)
}

fn volumetric_global_scaling(opts: &Options) -> Result<Scaling> {
    volumetric_scaling_with(opts, CellSolver::Global)
}

/// Cost growth of the volumetric step with the paper's Gauss-Seidel sweeps or the global
/// Newton solve of all cells (`CellSolver::Global`, gradient correction).
fn volumetric_scaling_with(opts: &Options, solver: CellSolver) -> Result<Scaling> {
    let soup = icosphere(0.5, 3)?;
    let resolutions: &[usize] = if opts.quick {
        &[12, 20, 28, 36]
    } else {
        &[16, 28, 40, 56]
    };
    let steps = 10;
    let mut points = Vec::new();
    for &res in resolutions {
        eprintln!("xtask bench: volumetric scaling ({solver:?}), resolution {res}");
        let params = VolumetricParams {
            lattice: LatticeParams {
                resolution: res,
                voxels_per_cell: 4,
                ..LatticeParams::default()
            },
            // Over-relaxed sweeps with a larger budget: at 1e-10 the plain Gauss-Seidel sweeps
            // of the paper need more than the default 500 sweeps on the larger lattices.
            volume: match solver {
                CellSolver::GaussSeidel => CellVolumeParams {
                    over_relaxation: 1.3,
                    max_sweeps: 5000,
                    ..CellVolumeParams::default()
                },
                CellSolver::Global => CellVolumeParams::global(),
            },
            gravity: [0.0; 3],
            ..VolumetricParams::default()
        };
        let body = VolumetricBody::build(&soup, params)?;
        // Springs scaled to the particle mass as `balloon volumetric` does (`k = m / (50 h^2)`,
        // damping `m / (1000 h)`): the library's fixed 2e4 N/m is explicitly unstable on the
        // finer lattices (lighter particles), where every step then halves itself.
        let springs = body.mass_scaled_springs(1.0 / 50.0, 1.0 / 1000.0);
        let body = body.with_springs(springs)?;
        let mut sim = VolumetricSimulation::new(body);
        let n = sim.positions().len();
        // A deforming free body: a smooth shear plus spin (1/s about the centre), which
        // stretches every cell so the volume impulses have work to do.
        let c = sim
            .positions()
            .iter()
            .fold(Vector3::zeros(), |a, p| a + p.coords)
            / n as f64;
        let v: Vec<Vector3<f64>> = sim
            .positions()
            .iter()
            .map(|p| {
                let r = p.coords - c;
                Vector3::new(0.5 * r.z - 0.3 * r.y, 0.3 * r.x, 0.0)
            })
            .collect();
        sim.set_velocities(&v)?;
        let ms = median_ms_per_step(&mut sim, steps, opts.runs)?;
        points.push(SizePoint {
            label: format!(
                "icosphere soup, resolution {res}, {} cells{}",
                sim.lattice().cells.len(),
                match sim.total_halvings() {
                    0 => String::new(),
                    k => format!(" ({k} step halvings)"),
                }
            ),
            vertices: n,
            ms_per_step: ms,
            steps_per_second: 1e3 / ms,
        });
    }
    Ok(match solver {
        CellSolver::GaussSeidel => finish(
            "volumetric",
            "free body, dt = 1 ms, springs k = m / (50 dt^2), initial shear + spin velocity field, cell-volume tolerance 1e-10, Gauss-Seidel sweeps (the paper's), over-relaxation 1.3, at most 5000 sweeps",
            points,
        ),
        CellSolver::Global => finish(
            "volumetric (global solver)",
            "the same body and motion, cell-volume tolerance 1e-10, `--volume-solver global`: Newton on all cells at once, sparse Cholesky, gradient correction",
            points,
        ),
    })
}

/// Median over `runs` runs of the wall-clock ms per step of `steps` steps of any system, driven
/// through `balloon::Simulation` (each run continues from where the previous one stopped).
fn median_ms_per_step<S: Simulation>(sim: &mut S, steps: usize, runs: usize) -> Result<f64> {
    let mut per_run = Vec::with_capacity(runs);
    for _ in 0..runs {
        let t = Instant::now();
        for _ in 0..steps {
            sim.step()?;
        }
        per_run.push(t.elapsed().as_secs_f64() * 1e3 / steps as f64);
    }
    Ok(median(&per_run))
}

fn two_layer_scaling(opts: &Options) -> Result<Scaling> {
    // Issue 16 item 5: steps per second from level 2 to level 6 (real time at dt = 0.1 ms needs
    // 10000 steps per second).
    let levels: &[u32] = if opts.quick {
        &[1, 2, 3, 4]
    } else {
        &[2, 3, 4, 5, 6]
    };
    let steps = if opts.quick { 20 } else { 100 };
    let mut points = Vec::new();
    for &l in levels {
        eprintln!("xtask bench: two-layer scaling, octahedron level {l}");
        let body = TwoLayerBody::octahedron_sphere(l)
            .with_radii(0.7, 1.0)
            .with_pressure(40.0, 20.0);
        let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-4)?;
        let n = sim.model().num_particles();
        let ms = median_ms_per_step(&mut sim, steps, opts.runs)?;
        points.push(SizePoint {
            label: format!("octahedron sphere level {l}"),
            vertices: n,
            ms_per_step: ms,
            steps_per_second: 1e3 / ms,
        });
    }
    Ok(finish(
        "two-layer",
        "RK4, dt = 0.1 ms (real time: 10000 steps/s), gravity, gas in both layers",
        points,
    ))
}

fn markdown(r: &BenchReport) -> String {
    let mut s = String::new();
    s.push_str("# Benchmarks\n\n");
    let _ = writeln!(
        s,
        "Generated by `{}` (release build; source `xtask/src/bench.rs`). Machine: {}. \
         Each time is the median over {} runs of the mean wall time of consecutive steps \
         (Table 1: {} steps per run after 3 warm-up steps; shell scaling 5 (3 with `--quick`), volumetric 10, \
         two-layer 100 (20 with `--quick`)).\n\n**Load** during this run: {}. The machine has 2 \
         cores; rows timed while other work ran can be tens of percent slow.\n",
        r.command, r.machine, r.runs, r.steps_per_run, r.load
    );
    s.push_str("## Table 1: shell balloons (Wang et al. 2015)\n\n");
    s.push_str(
        "Pump inflation from the rest shape (2 L/s of ambient air), dt = 10 ms, backward Euler with \
         exactly 3 Newton iterations (tolerance 0), CG relative tolerance 1e-3 (pcg: incomplete-Cholesky preconditioner; the `balloon inflate` default is cholesky + projected), mass damping 10/s, StVK E = 1 MPa, nu = 0.45, \
         H = 0.3 mm, volume projection on (tolerance 1e-9). Meshes scaled to 0.3 m. `volume ratio` is \
         the shell (material) volume ratio after the last step (the paper reports 1.000003); \
         `worst |r-1|` the largest deviation over all timed steps. `tangent`: `exact` is the \
         Hessian of the energy (indefinite where elements are compressed: solves are retried \
         with a growing mass shift), `projected` the per-element Hessians projected onto the \
         positive semi-definite cone (projected Newton, `BackwardEulerParams::tangent`). \
         `factorized-pcg` is CG preconditioned by a sparse Cholesky factor kept across Newton \
         iterations and steps (refreshed after a solve of more than 8 CG iterations).\n\n",
    );
    s.push_str("| model | vertices | faces | solver | tangent | ms / step (min-max) | volume ratio | worst \\|r-1\\| | CG it. / step | V/V0 at end |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|---|\n");
    for row in &r.table1 {
        match &row.error {
            Some(e) => {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {} | failed: {} | | | | |",
                    row.model,
                    row.vertices,
                    row.faces,
                    row.solver,
                    row.tangent,
                    e.replace('|', "\\|")
                );
            }
            None => {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {} | {:.1} ({:.1}-{:.1}) | {:.12} | {:.1e} | {:.1} | {:.3} |",
                    row.model,
                    row.vertices,
                    row.faces,
                    row.solver,
                    row.tangent,
                    row.ms_per_step,
                    row.ms_min,
                    row.ms_max,
                    row.volume_ratio,
                    row.worst_volume_error,
                    row.linear_iterations_per_step,
                    row.gas_volume_ratio
                );
            }
        }
    }
    s.push_str("\n## Cost growth with size\n\n");
    for sc in &r.scaling {
        let _ = writeln!(
            s,
            "### {} ({})\n\nFitted exponent: ms per step ~ vertices^{:.2}\n",
            sc.system, sc.setting, sc.exponent
        );
        s.push_str("| size | vertices / particles | ms / step | steps / s |\n|---|---|---|---|\n");
        for p in &sc.points {
            let _ = writeln!(
                s,
                "| {} | {} | {:.3} | {:.1} |",
                p.label, p.vertices, p.ms_per_step, p.steps_per_second
            );
        }
        s.push('\n');
    }
    s.push_str("## Reproduce\n\n");
    s.push_str(
        "* This report: `cargo xtask bench` (`--update-docs` also puts its tables into the generated block at the top of docs/benchmarks.md; about 5 minutes on 2 cores; \
         `--meshes DIR` times every .obj/.off/.ply/.stl in DIR instead of the built-in models, \
         e.g. the paper's SHREC'07 models; `--quick` for a smoke run; `--runs N`). Raw numbers: \
         `target/bench/bench.json`.\n",
    );
    s.push_str(
        "* Per-stage criterion benches (material, element forces and stiffness, gas, assembly, \
         each linear solver, projection, whole step, volumetric, two-layer): \
         `cargo bench -p balloon-benches` (`-- --test` runs each once, as CI does).\n",
    );
    s.push_str(
        "* The converged default solver's studies alone: `cargo xtask bench --converged \
         sphere,teddy,scaling` (or `all`); profiles of one configuration: `cargo run --release \
         -p balloon-benches --example converged_profile` and `--example factor_profile`.\n",
    );
    s
}

/// Runs the benchmarks; see the module docs.
pub fn run(opts: &Options) -> Result<()> {
    let root = crate::workspace_root();
    let steps = if opts.quick { 3 } else { 5 };
    let models: Vec<(String, TriMesh)> = match &opts.meshes {
        Some(dir) => {
            let mut v = Vec::new();
            for src in meshes::folder(dir)? {
                let mut m = src.load()?;
                balloon::mesh::validate::validate_closed_manifold(&m).with_context(|| {
                    format!("{} is not a closed oriented 2-manifold", src.name())
                })?;
                meshes::normalise(&mut m, 0.3);
                v.push((src.name(), m));
            }
            v
        }
        None => default_models(opts.quick)?,
    };
    let mut load = crate::report::LoadSamples::default();
    load.sample();
    let mut table1 = Vec::new();
    for (name, mesh) in &models {
        for (kind, tangent) in table1_configs() {
            eprintln!(
                "xtask bench: {name} ({} v), {kind}, {tangent} tangent",
                mesh.num_vertices()
            );
            let row = time_shell(name, mesh, kind, tangent, opts, steps);
            eprintln!(
                "    {:.1} ms/step{}",
                row.ms_per_step,
                row.error
                    .as_deref()
                    .map(|e| format!(" ({e})"))
                    .unwrap_or_default()
            );
            table1.push(row);
            load.sample();
        }
    }
    let mut scaling = Vec::new();
    for study in [
        shell_scaling,
        volumetric_scaling,
        volumetric_global_scaling,
        two_layer_scaling,
    ] {
        scaling.push(study(opts)?);
        load.sample();
    }
    let mut command = "cargo xtask bench".to_string();
    for a in std::env::args().skip(2) {
        command.push(' ');
        command.push_str(&a);
    }
    let report = BenchReport {
        machine: crate::report::machine(),
        load: load.summary(),
        command,
        runs: opts.runs,
        steps_per_run: steps,
        table1,
        scaling,
    };
    let mut md = markdown(&report);
    md.push('\n');
    md.push_str(&run_converged(
        opts,
        ConvergedParts {
            sphere: true,
            teddy: true,
            scaling: true,
        },
    )?);
    let dir = root.join("target").join("bench");
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    std::fs::write(dir.join("bench.md"), &md)?;
    std::fs::write(
        dir.join("bench.json"),
        serde_json::to_string_pretty(&report)?,
    )?;
    println!("{md}");
    println!("wrote {}/bench.{{md,json}}", dir.display());
    if opts.update_docs {
        let p = root.join("docs").join("benchmarks.md");
        // The docs keep their hand-written studies: only the generated tables are replaced.
        let tables = md
            .split_once("## Reproduce\n")
            .map_or(md.as_str(), |(t, _)| t);
        let doc =
            std::fs::read_to_string(&p).with_context(|| format!("cannot read {}", p.display()))?;
        let updated = replace_generated_block(&doc, tables).with_context(|| {
            format!(
                "{} was not changed (the report is in {})",
                p.display(),
                dir.join("bench.md").display()
            )
        })?;
        std::fs::write(&p, updated).with_context(|| format!("cannot write {}", p.display()))?;
        println!("wrote the generated tables of {}", p.display());
    }
    Ok(())
}

/// The line before the generated tables of docs/benchmarks.md.
const GENERATED_START: &str = "<!-- generated by `cargo xtask bench --update-docs`: from here -->";
/// The line after them; what follows is written by hand.
const GENERATED_END: &str = "<!-- generated by `cargo xtask bench --update-docs`: up to here -->";

/// `doc` with the text between its [`GENERATED_START`] and [`GENERATED_END`] lines replaced by
/// `tables`; an error when the markers are missing or out of order (nothing is replaced then).
fn replace_generated_block(doc: &str, tables: &str) -> Result<String> {
    let start = doc.find(GENERATED_START);
    let end = doc.find(GENERATED_END);
    let (Some(start), Some(end)) = (start, end) else {
        anyhow::bail!(
            "it has no generated block: the lines `{GENERATED_START}` and `{GENERATED_END}` \
             must enclose the tables the command writes"
        );
    };
    if end < start {
        anyhow::bail!("its end-of-generated-block line comes before the start line");
    }
    let head = &doc[..start + GENERATED_START.len()];
    let tail = &doc[end..];
    Ok(format!("{head}\n{}\n{tail}", tables.trim_end()))
}

/// The converged default shell solver measured side by side (issue 12, item 4): the peer
/// sphere to rest (static and dynamic), the 300-step teddy inflation against a tight
/// reference, and the cost per step with size.
#[derive(Clone, Debug, Serialize)]
pub struct ConvergedReport {
    sphere: Option<SphereToRest>,
    teddy: Option<TeddyInflation>,
    scaling: Option<Scaling>,
}

/// The peer comparison's sphere brought to rest.
#[derive(Clone, Debug, Serialize)]
struct SphereToRest {
    vertices: usize,
    /// `solve_static`: wall time (s), Newton iterations, converged.
    static_s: f64,
    static_newton: usize,
    static_converged: bool,
    /// Outer iterations (thickness fixed point), numeric factorisations, CG iterations, final
    /// relative residual of the static solve.
    static_outer: usize,
    static_factorizations: usize,
    static_linear: usize,
    static_residual: f64,
    /// The static solve's time per phase.
    static_times: balloon::integrate::statics::PhaseTimes,
    /// Dynamic run until the largest speed is below 1e-3 m/s and the per-step relative volume
    /// change below 1e-6: wall time (s), steps, Newton iterations.
    dynamic_s: f64,
    dynamic_steps: usize,
    dynamic_newton: usize,
    /// Largest vertex distance between the two rest shapes over the bounding-box diagonal.
    shape_difference: f64,
    /// Gas volume ratio of the static rest shape.
    volume_ratio: f64,
    /// Building the sphere and solving for its rest shape (mesh, simulation, `solve_static`),
    /// s: the in-process counterpart of MuJoCo's `compile_s + rest_s`.
    static_whole_s: f64,
    /// The same sphere in MuJoCo (`benches/peer/mujoco_sphere.py`), when `python3` imports
    /// `mujoco`; else why not.
    mujoco: std::result::Result<MujocoPeer, String>,
}

/// What `benches/peer/mujoco_sphere.py` reported, plus the wall time of its whole process.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
struct MujocoPeer {
    mujoco: String,
    vertices: usize,
    dt: f64,
    compile_s: f64,
    steps_to_rest: usize,
    rest_s: f64,
    callback_s: f64,
    volume_ratio: f64,
    radius_min: f64,
    radius_max: f64,
    last_change: f64,
    analytic_volume_ratio: f64,
    /// Wall time of the whole `python3` process (start-up, import, compile, steps), s.
    #[serde(default)]
    process_s: f64,
}

/// Runs the MuJoCo peer on `mesh` (written to `target/bench/peer_sphere.obj`).
fn mujoco_peer(mesh: &TriMesh) -> std::result::Result<MujocoPeer, String> {
    let root = crate::workspace_root();
    let probe = std::process::Command::new("python3")
        .args(["-c", "import mujoco, numpy"])
        .output();
    match probe {
        Ok(o) if o.status.success() => {}
        _ => return Err("python3 with mujoco and numpy not found (pip install mujoco)".into()),
    }
    let dir = root.join("target").join("bench");
    std::fs::create_dir_all(&dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let obj = dir.join("peer_sphere.obj");
    balloon::mesh::io::write_obj(&obj, mesh).map_err(|e| e.to_string())?;
    let script = root.join("benches").join("peer").join("mujoco_sphere.py");
    eprintln!("xtask bench: peer sphere in MuJoCo ({})", script.display());
    let t = Instant::now();
    let out = std::process::Command::new("python3")
        .arg(&script)
        .arg(&obj)
        // MuJoCo appends its warnings to MUJOCO_LOG.TXT in the working directory.
        .current_dir(&dir)
        .output()
        .map_err(|e| format!("cannot run {}: {e}", script.display()))?;
    let process_s = t.elapsed().as_secs_f64();
    if !out.status.success() {
        return Err(format!(
            "{} failed: {}",
            script.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout.lines().last().unwrap_or_default();
    let mut peer: MujocoPeer = serde_json::from_str(line)
        .map_err(|e| format!("{}: unreadable report {line:?}: {e}", script.display()))?;
    peer.process_s = process_s;
    eprintln!(
        "    {} steps to rest {:.2} s, compile {:.2} s, whole process {process_s:.2} s",
        peer.steps_to_rest, peer.rest_s, peer.compile_s
    );
    Ok(peer)
}

/// 300 steps of the resolution-40 teddy, default solver against the reference.
#[derive(Clone, Debug, Serialize)]
struct TeddyInflation {
    vertices: usize,
    steps: usize,
    /// Wall time of the whole default run, s.
    default_s: f64,
    default_newton: usize,
    default_factorizations: usize,
    /// The default run's time per phase (`ShellStepStats::times` summed).
    default_times: balloon::integrate::PhaseTimes,
    /// Wall time of the reference run (`--newton-tol 1e-10 --newton-iters 100`), s.
    reference_s: f64,
    reference_newton: usize,
    /// Largest relative gas-volume difference over the checkpoints (every 30 steps).
    max_volume_difference: f64,
    /// Final shape difference over the bounding-box diagonal.
    shape_difference: f64,
}

/// The peer comparison's sphere (10242 vertices; [`crate::measure::peer_sphere`]).
pub fn peer_sphere() -> Result<balloon::shell::ShellSimulation> {
    let builder = crate::measure::peer_sphere(5).map_err(|e| anyhow::anyhow!(e))?;
    Ok(builder.build()?)
}

/// Largest vertex distance between `a` and `b` over the bounding-box diagonal of `a`.
fn shape_difference(a: &[f64], b: &[f64]) -> f64 {
    crate::measure::max_vertex_distance(a, b) / crate::measure::bbox_diagonal(a)
}

fn sphere_to_rest() -> Result<SphereToRest> {
    use balloon::shell::statics::StaticOptions;
    let whole = Instant::now();
    let mut sim = peer_sphere()?;
    let vertices = sim.positions().len() / 3;
    eprintln!("xtask bench: peer sphere ({vertices} v), static");
    let t = Instant::now();
    let report = sim.solve_static(&StaticOptions::default())?;
    let static_whole_s = whole.elapsed().as_secs_f64();
    eprintln!(
        "    outer iterations {}, load steps {}, cuts {}, factorisations {}\n    phases (ms): {}",
        report.outer_iterations,
        report.load_steps,
        report.line_search_cuts,
        report.factorizations,
        report.times
    );
    let static_s = t.elapsed().as_secs_f64();
    let static_x = sim.positions().to_vec();
    let volume_ratio = sim.gas_volume() / sim.rest_gas_volume();
    eprintln!(
        "    {static_s:.2} s, {} Newton iterations",
        report.newton_iterations
    );
    eprintln!("xtask bench: peer sphere, dynamic until at rest");
    let mut sim = peer_sphere()?;
    let t = Instant::now();
    let (mut steps, mut newton) = (0, 0);
    while steps < 10_000 {
        let s = sim.step()?;
        steps += 1;
        newton += s.newton_iterations;
        if s.max_speed < 1e-3 && s.volume_change < 1e-6 {
            break;
        }
    }
    let dynamic_s = t.elapsed().as_secs_f64();
    eprintln!("    {dynamic_s:.2} s, {steps} steps, {newton} Newton iterations");
    Ok(SphereToRest {
        vertices,
        static_s,
        static_newton: report.newton_iterations,
        static_converged: report.converged,
        static_outer: report.outer_iterations,
        static_factorizations: report.factorizations,
        static_linear: report.linear_iterations,
        static_residual: report.relative_residual,
        static_times: report.times,
        dynamic_s,
        dynamic_steps: steps,
        dynamic_newton: newton,
        shape_difference: shape_difference(&static_x, sim.positions()),
        volume_ratio,
        static_whole_s,
        mujoco: mujoco_peer(&icosphere(1.0, 5)?),
    })
}

/// The resolution-40 teddy with the paper's gas and wall (`--gas ideal --ambient 0`, 0.3 mm).
fn paper_teddy(reference: bool) -> Result<balloon::shell::ShellSimulation> {
    let mesh = teddy(&TeddyParams {
        resolution: 40,
        ..Default::default()
    })?;
    let mut b = ShellBalloon::new(mesh)
        .with_gas(balloon::gas::GasKind::Ideal)
        .with_ambient_pressure(0.0)
        .with_thickness(3e-4);
    if reference {
        b = b.configure_integrator(|p| {
            p.newton_tolerance = 1e-10;
            p.newton_iterations = 100;
        });
    }
    Ok(b.build()?)
}

/// One 300-step teddy run: wall time (s), Newton iterations, factorisations, gas volumes at
/// the checkpoints, final positions, vertices.
struct TeddyRun {
    secs: f64,
    newton: usize,
    factorizations: usize,
    times: balloon::integrate::PhaseTimes,
    volumes: Vec<f64>,
    positions: Vec<f64>,
    vertices: usize,
}

fn teddy_run(reference: bool, steps: usize) -> Result<TeddyRun> {
    let mut sim = paper_teddy(reference)?;
    let vertices = sim.positions().len() / 3;
    let (mut newton, mut factorizations, mut volumes) = (0, 0, Vec::new());
    let mut times = balloon::integrate::PhaseTimes::default();
    let t = Instant::now();
    for k in 0..steps {
        let s = sim.step()?;
        newton += s.newton_iterations;
        factorizations += s.factorizations;
        times += s.times;
        if (k + 1) % 30 == 0 || k + 1 == steps {
            volumes.push(s.gas_volume);
        }
    }
    Ok(TeddyRun {
        secs: t.elapsed().as_secs_f64(),
        newton,
        factorizations,
        times,
        volumes,
        positions: sim.positions().to_vec(),
        vertices,
    })
}

fn teddy_inflation(steps: usize) -> Result<TeddyInflation> {
    eprintln!("xtask bench: teddy (res 40), {steps} steps, default solver");
    let d = teddy_run(false, steps)?;
    eprintln!("    {:.2} s, {} Newton iterations", d.secs, d.newton);
    eprintln!("xtask bench: teddy (res 40), {steps} steps, reference (tol 1e-10, 100 iterations)");
    let r = teddy_run(true, steps)?;
    eprintln!("    {:.2} s, {} Newton iterations", r.secs, r.newton);
    let (v_def, v_ref) = (&d.volumes, &r.volumes);
    let max_volume_difference = v_def
        .iter()
        .zip(v_ref)
        .map(|(a, b)| ((a - b) / b).abs())
        .fold(0.0, f64::max);
    Ok(TeddyInflation {
        vertices: d.vertices,
        steps,
        default_s: d.secs,
        default_newton: d.newton,
        default_factorizations: d.factorizations,
        default_times: d.times,
        reference_s: r.secs,
        reference_newton: r.newton,
        max_volume_difference,
        shape_difference: shape_difference(&r.positions, &d.positions),
    })
}

/// Cost per step of the converged default solver (pump inflation from rest, 3 warm-up steps)
/// on icospheres from 2562 to 163842 vertices (`--quick`: 642 to 10242).
fn converged_scaling(opts: &Options) -> Result<Scaling> {
    let levels: &[u32] = if opts.quick {
        &[3, 4, 5]
    } else {
        &[4, 5, 6, 7]
    };
    let mut points = Vec::new();
    for &l in levels {
        let mesh = icosphere(0.15, l)?;
        eprintln!("xtask bench: converged scaling, icosphere L{l}");
        let mut sim = ShellBalloon::new(mesh.clone())
            .with_pump_rate(2e-3)
            .build()?;
        for _ in 0..3 {
            sim.step()?;
        }
        let ms = median_ms_per_step(&mut sim, if opts.quick { 3 } else { 5 }, opts.runs)?;
        eprintln!("    {ms:.1} ms/step");
        points.push(SizePoint {
            label: format!("icosphere L{l}"),
            vertices: mesh.num_vertices(),
            ms_per_step: ms,
            steps_per_second: 1e3 / ms,
        });
    }
    Ok(finish(
        "shell (converged default)",
        "pump, Newton to 1e-6 with line search, exact tangent, CG with a kept Cholesky factor",
        points,
    ))
}

/// Which of the converged-solver studies to run.
#[derive(Clone, Copy, Debug)]
pub struct ConvergedParts {
    /// The peer sphere, static and dynamic.
    pub sphere: bool,
    /// The 300-step teddy against the reference.
    pub teddy: bool,
    /// Cost per step with size.
    pub scaling: bool,
}

/// Runs the converged-solver studies named in `parts`, prints them as Markdown and writes
/// `target/bench/converged.{md,json}`; returns the Markdown.
pub fn run_converged(opts: &Options, parts: ConvergedParts) -> Result<String> {
    let mut load = crate::report::LoadSamples::default();
    load.sample();
    let report = ConvergedReport {
        sphere: parts.sphere.then(sphere_to_rest).transpose()?,
        teddy: parts
            .teddy
            .then(|| teddy_inflation(if opts.quick { 60 } else { 300 }))
            .transpose()?,
        scaling: parts.scaling.then(|| converged_scaling(opts)).transpose()?,
    };
    load.sample();
    let mut md = format!(
        "## The converged default solver\n\nMachine: {}. Load: {}.\n\n",
        crate::report::machine(),
        load.summary()
    );
    if let Some(s) = &report.sphere {
        let _ = writeln!(
            md,
            "Peer sphere ({} v, E t = 1155 N/m, nu = 1/3, 1 kg, ideal gas 377 Pa gauge, ambient 0, \
             mass damping 20 1/s) to rest: static {:.2} s ({} Newton iterations, converged {}), \
             dynamic {:.2} s ({} steps, {} Newton iterations); rest shapes differ by {:.1e} of \
             the bounding-box diagonal; V/V0 = {:.4}.\n",
            s.vertices,
            s.static_s,
            s.static_newton,
            s.static_converged,
            s.dynamic_s,
            s.dynamic_steps,
            s.dynamic_newton,
            s.shape_difference,
            s.volume_ratio
        );
        match &s.mujoco {
            Ok(m) => {
                let _ = writeln!(
                    md,
                    "The same sphere in MuJoCo {} (`benches/peer/mujoco_sphere.py`: 2D flex, \
                     StVK membrane at constant thickness, `discrete` integrator, dt {} s, the \
                     gas as a passive-force callback): at rest (within 1e-4 of the diagonal of \
                     its final shape) after {} steps, {:.2} s of stepping ({:.2} s of it the \
                     Python callback); compile {:.2} s; whole process {:.2} s. Ours, build and \
                     static solve: {:.2} s (whole process / ours: {:.1}x; stepping alone / \
                     static solve: {:.2}x). MuJoCo V/V0 = {:.4} (plane-stress StVK sphere at \
                     constant thickness, analytic: {:.4}).\n",
                    m.mujoco,
                    m.dt,
                    m.steps_to_rest,
                    m.rest_s,
                    m.callback_s,
                    m.compile_s,
                    m.process_s,
                    s.static_whole_s,
                    m.process_s / s.static_whole_s,
                    m.rest_s / s.static_s,
                    m.volume_ratio,
                    m.analytic_volume_ratio
                );
            }
            Err(why) => {
                let _ = writeln!(md, "MuJoCo peer not run: {why}.\n");
            }
        }
        let t = &s.static_times;
        let _ = writeln!(
            md,
            "Static solve: {} outer iterations, {} factorisations, {} CG iterations, final \
             relative residual {:.1e}. Time per phase (ms):\n\n\
             | forces | energy | assembly | factorisation | solves | projection | other | total |\n\
             |---|---|---|---|---|---|---|---|\n\
             | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} |\n",
            s.static_outer,
            s.static_factorizations,
            s.static_linear,
            s.static_residual,
            t.forces_ms,
            t.energy_ms,
            t.assembly_ms,
            t.factorization_ms,
            t.solve_ms,
            t.projection_ms,
            (s.static_s * 1e3 - t.total_ms()).max(0.0),
            s.static_s * 1e3
        );
    }
    if let Some(t) = &report.teddy {
        let _ = writeln!(
            md,
            "Teddy (res 40, {} v), {} steps, `--gas ideal --ambient 0`, 0.3 mm: default {:.2} s \
             ({} Newton iterations, {} factorisations), reference (tol 1e-10, 100 iterations) \
             {:.2} s ({} Newton iterations); gas volume within {:.1e} (relative) at every 30th \
             step, final shape within {:.1e} of the bounding-box diagonal.\n",
            t.vertices,
            t.steps,
            t.default_s,
            t.default_newton,
            t.default_factorizations,
            t.reference_s,
            t.reference_newton,
            t.max_volume_difference,
            t.shape_difference
        );
        let p = &t.default_times;
        let per = |ms: f64| ms / t.default_newton.max(1) as f64;
        let _ = writeln!(
            md,
            "Default run, time per phase, ms in all / per Newton iteration:\n\n\
             | forces | energy | assembly | factorisation | solves | projection | other | total |\n\
             |---|---|---|---|---|---|---|---|\n\
             | {:.0} / {:.2} | {:.0} / {:.2} | {:.0} / {:.2} | {:.0} / {:.2} | {:.0} / {:.2} | \
             {:.0} / {:.2} | {:.0} | {:.0} |\n",
            p.forces_ms,
            per(p.forces_ms),
            p.energy_ms,
            per(p.energy_ms),
            p.assembly_ms,
            per(p.assembly_ms),
            p.factorization_ms,
            per(p.factorization_ms),
            p.solve_ms,
            per(p.solve_ms),
            p.projection_ms,
            per(p.projection_ms),
            (t.default_s * 1e3 - p.total_ms()).max(0.0),
            t.default_s * 1e3
        );
    }
    if let Some(s) = &report.scaling {
        let _ = writeln!(
            md,
            "Cost per step, {} ({}): exponent {:.2}\n\n| size | vertices | ms / step |\n|---|---|---|",
            s.system, s.setting, s.exponent
        );
        for p in &s.points {
            let _ = writeln!(
                md,
                "| {} | {} | {:.1} |",
                p.label, p.vertices, p.ms_per_step
            );
        }
    }
    let dir = crate::workspace_root().join("target").join("bench");
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    std::fs::write(dir.join("converged.md"), &md)?;
    std::fs::write(
        dir.join("converged.json"),
        serde_json::to_string_pretty(&report)?,
    )?;
    println!("{md}");
    println!("wrote {}/converged.{{md,json}}", dir.display());
    Ok(md)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn update_docs_replaces_only_the_generated_block() {
        let doc = format!(
            "{GENERATED_START}\n# Benchmarks\n\nold tables\n{GENERATED_END}\n\n## Hand-written\n\nstudy\n"
        );
        let out = replace_generated_block(&doc, "# Benchmarks\n\nnew tables\n").unwrap();
        assert!(
            out.contains("new tables") && !out.contains("old tables"),
            "{out}"
        );
        assert!(out.ends_with(&format!("{GENERATED_END}\n\n## Hand-written\n\nstudy\n")));
        assert!(out.starts_with(GENERATED_START));
        // Idempotent: a second update gives the same file.
        let again = replace_generated_block(&out, "# Benchmarks\n\nnew tables\n").unwrap();
        assert_eq!(again, out);
    }

    #[test]
    fn update_docs_refuses_a_file_without_markers() {
        let e = replace_generated_block("# Benchmarks\n\nhand-written\n", "x").unwrap_err();
        assert!(e.to_string().contains("no generated block"), "{e}");
        let swapped = format!("{GENERATED_END}\nx\n{GENERATED_START}\n");
        assert!(replace_generated_block(&swapped, "x").is_err());
    }
}
