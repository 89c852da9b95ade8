//! The floppy start (issue 30): `balloon inflate` at the defaults (the pump from the rest shape)
//! on the shared bunny scaled to a 0.1 m longest side, its first steps, while the gauge pressure
//! is a few pascals and the shell buckles. The Newton iteration and sub-step counts are
//! deterministic (they do not depend on the machine's speed), so their bounds catch a solver
//! change that makes this phase costlier without timing anything.
//!
//! The bounds are about 20 % above what the solver does today (308 Newton iterations, 32
//! sub-steps and 190 factorisations over the first 5 steps; `cargo xtask validate --only
//! floppy`), with room for round-off differences of the parallel assembly between machines;
//! the aim of issue 30 is at most 3 Newton iterations and 2 sub-steps per step. Lower the bounds
//! with the solver.
//!
//! The same run with the wall's bending stiffness (`[shell] bending = 1`, the plate modulus of
//! the wall; the paper's three-prism wall has none) has its own bounds, about 20 % above what it
//! does today (29 Newton iterations and 5 sub-steps over the first 5 steps): the buckling that
//! makes the paper's wall slow is resisted there, and a change that loses that shows here.

use crate::report::Case;
use crate::validate::meshes;
use balloon_scenario::shell::ShellScenario;

const G: &str = "floppy";

/// Steps of the run (the same in quick and full mode: the counts are per run).
const STEPS: usize = 5;
/// Most Newton iterations over the [`STEPS`] steps.
const MAX_NEWTON: usize = 370;
/// Most sub-steps over the [`STEPS`] steps.
const MAX_SUBSTEPS: usize = 40;
/// Most Newton iterations over the [`STEPS`] steps with the wall's bending stiffness.
const MAX_NEWTON_BENDING: usize = 36;
/// Most sub-steps over the [`STEPS`] steps with the wall's bending stiffness.
const MAX_SUBSTEPS_BENDING: usize = 6;

/// The bunny's longest side in the shared file, m (so `scale` gives 0.1 m).
fn scale_to(path: &std::path::Path, size: f64) -> anyhow::Result<f64> {
    let mesh = balloon::mesh::io::read_mesh(path)?;
    let b = balloon::mesh::geometry::bounding_box(&mesh)
        .ok_or_else(|| anyhow::anyhow!("{}: empty mesh", path.display()))?;
    let ext = b.max - b.min;
    Ok(size / ext.x.max(ext.y).max(ext.z))
}

/// The floppy-start cases (none without the shared meshes; CI requires them).
pub fn cases() -> Vec<Case> {
    let Some(dir) = meshes::shared_meshes_dir() else {
        return Vec::new();
    };
    let path = dir.join("bunny_closed_libigl.off");
    let run = |bending: f64| -> anyhow::Result<(usize, usize, usize)> {
        let mut scenario = ShellScenario::default();
        scenario.mesh.path = path.display().to_string();
        scenario.mesh.scale = scale_to(&path, 0.1)?;
        scenario.shell.bending = bending;
        scenario.validate()?;
        let (mut sim, mut loads) = scenario.build(None)?;
        let (mut newton, mut substeps, mut factorizations) = (0, 0, 0);
        for _ in 0..STEPS {
            loads.before_step(&mut sim)?;
            let s = sim.step()?;
            newton += s.newton_iterations;
            substeps += s.substeps;
            factorizations += s.factorizations;
        }
        Ok((newton, substeps, factorizations))
    };
    let mut cases = Vec::new();
    for (bending, wall, max_newton, max_substeps) in [
        (0.0, "default pump", MAX_NEWTON, MAX_SUBSTEPS),
        (
            1.0,
            "default pump, wall bending 1",
            MAX_NEWTON_BENDING,
            MAX_SUBSTEPS_BENDING,
        ),
    ] {
        match run(bending) {
            Ok((newton, substeps, factorizations)) => {
                eprintln!(
                    "xtask validate: floppy bunny, bending {bending}, {STEPS} steps: {newton} \
                     Newton iterations, {substeps} sub-steps, {factorizations} factorisations"
                );
                cases.push(Case::at_most(
                    G,
                    format!(
                        "bunny at 0.1 m, {wall}, first {STEPS} steps: Newton iterations \
                         (aim: {})",
                        3 * STEPS
                    ),
                    newton as f64,
                    max_newton as f64,
                ));
                cases.push(Case::at_most(
                    G,
                    format!(
                        "bunny at 0.1 m, {wall}, first {STEPS} steps: sub-steps (aim: {})",
                        2 * STEPS
                    ),
                    substeps as f64,
                    max_substeps as f64,
                ));
            }
            Err(e) => cases.push(Case::error(
                G,
                format!("bunny at 0.1 m, {wall}: floppy start"),
                format!("{e:#}"),
            )),
        }
    }
    cases
}
