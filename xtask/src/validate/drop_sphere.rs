//! The default drop-sphere scene of `balloon volumetric` (Diziol, Bender and Bayer 2011, Fig. 4, scaled to the body;
//! issue 16) on every shared model and the built-in teddy, at their natural size: built exactly
//! as the command builds it (`balloon_scenario::volumetric::VolumetricScenario::build`: lattice sized for about 1000
//! cells, springs and time step from the particle mass, sphere size, height and speed from the
//! body) and stepped 2000 times.
//!
//! With the global cell-volume solver (the CLI's default) every run must complete its steps
//! without a failure (an inversion that step halving cannot avoid ends a run), with every
//! tetrahedron positive and every cell at its rest volume, both recomputed here from the
//! positions after every step (`crate::measure::cell_volumes`), not taken from the solver.
//!
//! `--volume-solver gauss-seidel` at its defaults (gradient correction, adaptive
//! over-relaxation: `CellVolumeParams::gauss_seidel`) must pass the same checks over the same
//! 2000 steps (full mode; 400 in quick mode). The command's other scene, `--scene free` (the
//! body falling under gravity, no contact), runs 2000 steps with both solvers in full mode.
//!
//! The paper's exact sweeps (`--correction scaling --over-relaxation 1`) are run on the same
//! scenes and recorded as they are: at about 1000 cells their volume error falls by only about
//! 2 % per sweep, so a step needs more than the 500-sweep limit to reach the 1e-10 tolerance
//! and the run stops with "did not converge". Those cases state the step reached and pass when
//! the run ended in the documented way (the sweep limit, or all steps) with every completed
//! step still volume-conserving and uninverted; an inversion or a broken volume fails them.

use super::Options;
use super::meshes::{Source, shared_meshes_dir};
use crate::report::Case;
use anyhow::{Context, Result};
use balloon::volumetric::{VolumetricError, VolumetricSimulation};
use balloon_scenario::value::Value;
use balloon_scenario::volumetric::VolumetricScenario;
use balloon_scenario::{Scenario, SystemKind};

const G: &str = "drop-sphere";

/// Bound on the per-cell volume error measured from the positions: the solver's tolerance is
/// 1e-10 per cell; the recomputed tetrahedron sums add round-off.
const CELL_BOUND: f64 = 1e-9;

/// The scenario of `balloon volumetric MESH --scene drop-sphere` with the cell-volume solver
/// settings `solver` (scenario keys and their values, e.g. `[("volume_solver", "global")]`).
fn scenario(mesh: &str, solver: &[(&str, &str)]) -> Result<VolumetricScenario> {
    let mut s = Scenario::new(SystemKind::Volumetric);
    s.set("mesh", &Value::Text(mesh.into()))
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    s.set("scene", &Value::Text("drop-sphere".into()))
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    for (key, value) in solver {
        s.set(key, &Value::Text((*value).into()))
            .map_err(|e| anyhow::anyhow!("{key} = {value}: {e:?}"))?;
    }
    s.validate().context("volumetric scenario")?;
    match s {
        Scenario::Volumetric(v) => Ok(v),
        _ => unreachable!("a volumetric scenario"),
    }
}

/// The paper's exact Gauss-Seidel sweeps: the scaling correction, no over-relaxation.
const GS_PAPER: &[(&str, &str)] = &[
    ("volume_solver", "gauss-seidel"),
    ("correction", "scaling"),
    ("over_relaxation", "1"),
];

/// What one run did.
struct Outcome {
    cells: usize,
    steps: usize,
    /// The error that ended the run early.
    error: Option<VolumetricError>,
    /// Largest per-cell `|V / V0 - 1|` from the positions over the completed steps.
    worst_cell: f64,
    /// Smallest tetrahedron volume over the completed steps (m^3) relative to the smallest
    /// rest tetrahedron.
    min_tet: f64,
    halvings: u64,
    mean_iterations: f64,
    seconds: f64,
    /// The sphere reached the body: the closest particle came within 5 % of its radius.
    touched: bool,
}

fn run(mesh: &str, solver: &[(&str, &str)], steps: usize) -> Result<Outcome> {
    let mut sim: VolumetricSimulation = scenario(mesh, solver)?.build(None)?.sim;
    let lattice = sim.lattice().clone();
    let rest = crate::measure::cell_volumes(sim.positions(), &lattice);
    let tets = &lattice.tet_mesh.tets;
    let tet_volume = |x: &[nalgebra::Point3<f64>], t: &[usize; 4]| {
        let o = x[t[0]];
        (x[t[1]] - o).dot(&(x[t[2]] - o).cross(&(x[t[3]] - o))) / 6.0
    };
    let rest_min = tets
        .iter()
        .map(|t| tet_volume(&lattice.tet_mesh.vertices, t))
        .fold(f64::INFINITY, f64::min);
    let mut out = Outcome {
        cells: lattice.cells.len(),
        steps: 0,
        error: None,
        worst_cell: 0.0,
        min_tet: f64::INFINITY,
        halvings: 0,
        mean_iterations: 0.0,
        seconds: 0.0,
        touched: false,
    };
    let mut iterations = 0usize;
    let t0 = std::time::Instant::now();
    for step in 1..=steps {
        match sim.step() {
            Ok(s) => {
                iterations += s.sweeps;
                out.steps = step;
            }
            Err(e) => {
                out.error = Some(e);
                break;
            }
        }
        let x = sim.positions();
        let now = crate::measure::cell_volumes(x, &lattice);
        out.worst_cell = out
            .worst_cell
            .max(crate::measure::max_relative_change(&now, &rest));
        out.min_tet = tets
            .iter()
            .map(|t| tet_volume(x, t) / rest_min)
            .fold(out.min_tet, f64::min);
        if let Some(s) = sim.sphere() {
            let gap = x
                .iter()
                .map(|p| (p - s.position).norm() - s.radius)
                .fold(f64::INFINITY, f64::min);
            out.touched |= gap < 0.05 * s.radius;
        }
    }
    out.seconds = t0.elapsed().as_secs_f64();
    out.halvings = sim.total_halvings();
    out.mean_iterations = iterations as f64 / out.steps.max(1) as f64;
    Ok(out)
}

/// The models: the built-in teddy and every shared mesh (only the teddy in quick mode).
fn models(opts: &Options) -> Result<Vec<String>> {
    let mut names = vec!["builtin".to_string()];
    if opts.quick {
        return Ok(names);
    }
    let dir = match &opts.meshes {
        Some(d) => Some(d.clone()),
        None => shared_meshes_dir(),
    };
    match dir {
        Some(d) => {
            for src in super::meshes::folder(&d)? {
                if let Source::File(p) = src {
                    names.push(p.display().to_string());
                }
            }
        }
        None => eprintln!("xtask validate: drop-sphere: ../shared/meshes not found, teddy only"),
    }
    Ok(names)
}

fn short(mesh: &str) -> String {
    match mesh {
        "builtin" => "teddy (builtin)".into(),
        m => std::path::Path::new(m)
            .file_name()
            .map_or_else(|| m.to_string(), |n| n.to_string_lossy().into_owned()),
    }
}

/// All cases of the group.
pub fn cases(opts: &Options) -> Vec<Case> {
    let mut cases = Vec::new();
    let steps = if opts.quick { 400 } else { 2000 };
    // The paper's sweeps hit the sweep limit early; each of their steps costs up to 500 sweeps, so
    // their runs are capped shorter (the cap is stated in the case).
    let gs_steps = if opts.quick { 100 } else { 400 };
    let models = match models(opts) {
        Ok(m) => m,
        Err(e) => return vec![Case::error(G, "models", format!("{e:#}"))],
    };
    for mesh in &models {
        let name = short(mesh);
        for (label, solver, steps) in [
            ("global", &[("volume_solver", "global")][..], steps),
            (
                "Gauss-Seidel",
                &[("volume_solver", "gauss-seidel")][..],
                steps,
            ),
        ] {
            eprintln!("xtask validate: drop-sphere / {name} ({label}, {steps} steps)");
            match run(mesh, solver, steps) {
                Ok(o) => completed(&mut cases, &name, label, steps, &o),
                Err(e) => cases.push(Case::error(G, format!("{name}, {label}"), format!("{e:#}"))),
            }
        }
        eprintln!("xtask validate: drop-sphere / {name} (paper's Gauss-Seidel, {gs_steps} steps)");
        match run(mesh, GS_PAPER, gs_steps) {
            Ok(o) => {
                let sweep_limit = matches!(o.error, Some(VolumetricError::NotConverged { .. }));
                let measured = match &o.error {
                    None => format!(
                        "all {} steps, {:.0} sweeps/step, {:.1} s",
                        o.steps, o.mean_iterations, o.seconds
                    ),
                    Some(e) => format!(
                        "stopped after {} steps ({:.0} sweeps/step before): {e}",
                        o.steps, o.mean_iterations
                    ),
                };
                let kept = o.worst_cell <= CELL_BOUND && (o.steps == 0 || o.min_tet > 0.0);
                cases.push(Case::check(
                    G,
                    format!(
                        "{name}, {} cells, the paper's Gauss-Seidel (--correction scaling \
                         --over-relaxation 1, <= 500 sweeps), first {gs_steps} steps: EXPECTED \
                         to stop at the sweep limit (known, issue 16); passes if it stops there \
                         or runs through with the cells kept (max error {:.1e}) and no inversion",
                        o.cells, o.worst_cell
                    ),
                    kept && (o.error.is_none() || sweep_limit),
                    measured,
                    "sweep limit or all steps",
                ));
            }
            Err(e) => cases.push(Case::error(
                G,
                format!("{name}, the paper's Gauss-Seidel"),
                format!("{e:#}"),
            )),
        }
        if opts.quick {
            continue;
        }
        for (label, solver) in [("global", "global"), ("Gauss-Seidel", "gauss-seidel")] {
            eprintln!("xtask validate: drop-sphere / {name} (free scene, {label}, {steps} steps)");
            let argv = [("scene", "free"), ("volume_solver", solver)];
            match run(mesh, &argv, steps) {
                Ok(o) => free_completed(&mut cases, &name, label, steps, &o),
                Err(e) => cases.push(Case::error(
                    G,
                    format!("{name}, free scene, {label}"),
                    format!("{e:#}"),
                )),
            }
        }
    }
    cases
}

/// What a run reports when it ended: its steps, halvings, iterations and time, or the error.
fn ended(o: &Outcome) -> String {
    match &o.error {
        None => format!(
            "{} steps, {} halvings, {:.1} sweeps or Newton it./step, {:.1} s",
            o.steps, o.halvings, o.mean_iterations, o.seconds
        ),
        Some(e) => format!("stopped after {} steps: {e}", o.steps),
    }
}

/// The cases of a drop-sphere run that must complete: all steps, cells kept, no inversion, the
/// sphere reached the body.
fn completed(cases: &mut Vec<Case>, name: &str, label: &str, steps: usize, o: &Outcome) {
    cases.push(Case::check(
        G,
        format!(
            "{name}, {} cells, {label} solver at its defaults: {steps} steps complete",
            o.cells
        ),
        o.error.is_none() && o.steps == steps,
        ended(o),
        format!("{steps} steps"),
    ));
    cases.push(Case::at_most(
        G,
        format!("{name}, {label}: max per-cell |V/V0 - 1| from the positions"),
        o.worst_cell,
        CELL_BOUND,
    ));
    cases.push(Case::at_least(
        G,
        format!("{name}, {label}: smallest tetrahedron volume / smallest rest one (no inversion)"),
        o.min_tet,
        1e-3,
        "> 0 (1 at rest)",
    ));
    cases.push(Case::check(
        G,
        format!("{name}, {label}: the sphere reached the body"),
        o.touched,
        if o.touched { "yes" } else { "no" },
        "yes (else the impact was not tested)",
    ));
}

/// The case of a free-scene run: all steps with the cells kept and no inversion.
fn free_completed(cases: &mut Vec<Case>, name: &str, label: &str, steps: usize, o: &Outcome) {
    cases.push(Case::check(
        G,
        format!(
            "{name}, {} cells, --scene free, {label} solver at its defaults: {steps} steps \
             complete, cells kept (max error {:.1e}), no inversion",
            o.cells, o.worst_cell
        ),
        o.error.is_none() && o.steps == steps && o.worst_cell <= CELL_BOUND && o.min_tet > 0.0,
        ended(o),
        format!("{steps} steps"),
    ));
}
