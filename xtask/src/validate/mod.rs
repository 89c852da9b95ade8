//! `cargo xtask validate`: every validation case of the three systems, a table on the terminal,
//! `docs/validation.md` with the table and the figures in `docs/figures/`, and a non-zero exit
//! when a case fails.

mod connected;
mod design;
mod drop_sphere;
mod floppy;
mod membrane;
pub mod meshes;
mod shell;
mod thin_parts;
mod tube;
mod two_layer;
mod volumetric;

use crate::report::{Case, markdown_table, text_table};
use anyhow::{Context, Result, bail};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `cargo xtask validate`.
#[derive(Clone, Debug)]
pub struct Options {
    /// The quick subset.
    pub quick: bool,
    /// Folder of meshes to load, validate and inflate (default: built-ins + shared meshes).
    pub meshes: Option<PathBuf>,
    /// Write docs/validation.md and docs/figures.
    pub write: bool,
    /// Run only this group ("shell", "membrane", "connected", "tube", "volumetric",
    /// "drop-sphere", "two-layer", "floppy", "thin-parts", "design", "meshes"); nothing is written.
    pub only: Option<String>,
}

/// The figures written by the cases: file name (under `docs/figures/`) and caption.
pub struct Figures {
    dir: Option<PathBuf>,
    list: Vec<(String, String)>,
}

impl Figures {
    /// Draws one figure with `draw(path)` unless writing is off.
    pub fn add(
        &mut self,
        file: &str,
        caption: &str,
        draw: impl FnOnce(&Path) -> Result<()>,
    ) -> Result<()> {
        if let Some(dir) = &self.dir {
            draw(&dir.join(file)).with_context(|| format!("figure {file}"))?;
            self.list.push((file.to_string(), caption.to_string()));
        }
        Ok(())
    }
}

/// The built-in models every `validate` run inflates.
const BUILTIN_MODELS: &[&str] = &[
    "teddy",
    "icosphere",
    "octasphere",
    "uvsphere",
    "torus",
    "box",
];

/// Runs every case; see the module docs.
pub fn run(opts: &Options) -> Result<()> {
    let root = crate::workspace_root();
    let fig_dir = root.join("docs").join("figures");
    if opts.write && opts.only.is_none() {
        std::fs::create_dir_all(&fig_dir)
            .with_context(|| format!("cannot create {}", fig_dir.display()))?;
    }
    let write = opts.write && opts.only.is_none();
    // One group alone leaves docs/ as it is but still draws its figures, into target/, to be
    // looked at.
    let only_dir = root.join("target").join("validate-figures");
    if opts.write && opts.only.is_some() {
        std::fs::create_dir_all(&only_dir)
            .with_context(|| format!("cannot create {}", only_dir.display()))?;
        eprintln!(
            "xtask validate: figures of this group go to {}",
            only_dir.display()
        );
    }
    let mut figs = Figures {
        dir: if write {
            Some(fig_dir.clone())
        } else {
            (opts.write && opts.only.is_some()).then(|| only_dir.clone())
        },
        list: Vec::new(),
    };
    let start = Instant::now();
    let mut sources: Vec<meshes::Source> = Vec::new();
    let mut mesh_note = String::new();
    match &opts.meshes {
        Some(dir) => {
            sources = meshes::folder(dir)?;
            let _ = write!(mesh_note, "meshes from `{}`", dir.display());
        }
        None => {
            sources.extend(BUILTIN_MODELS.iter().map(|n| meshes::Source::Builtin(n)));
            mesh_note.push_str("the built-in models");
            if let Some(dir) = meshes::shared_meshes_dir() {
                sources.extend(meshes::folder(&dir)?);
                mesh_note.push_str(" and `../shared/meshes`");
            } else {
                eprintln!("xtask validate: ../shared/meshes not found, only built-in models");
            }
        }
    }
    let want = |g: &str| opts.only.as_deref().is_none_or(|o| o == g);
    let mut cases = Vec::new();
    if want("shell") {
        cases.extend(shell::cases(opts, &mut figs));
    }
    // Real surfaces for the lattice-volume comparison: the shared spot model when present.
    let mut soups = Vec::new();
    if !opts.quick {
        for src in &sources {
            if let meshes::Source::File(p) = src
                && p.file_name().is_some_and(|n| n == "spot.obj")
                && let Ok(mut m) = src.load()
            {
                meshes::normalise(&mut m, 1.0);
                soups.push(("spot.obj (scaled to 1 m)".to_string(), m));
            }
        }
    }
    if want("membrane") {
        cases.extend(membrane::cases(opts, &mut figs));
    }
    if want("connected") {
        cases.extend(connected::cases(opts, &mut figs));
    }
    if want("tube") {
        cases.extend(tube::cases(opts, &mut figs));
    }
    if want("volumetric") {
        cases.extend(volumetric::cases(opts, &soups));
    }
    if want("drop-sphere") {
        cases.extend(drop_sphere::cases(opts));
    }
    if want("two-layer") {
        cases.extend(two_layer::cases(opts, &mut figs));
    }
    if want("floppy") {
        cases.extend(floppy::cases());
    }
    if want("thin-parts") && !opts.quick {
        cases.extend(thin_parts::cases());
    }
    if want("design") {
        cases.extend(design::cases(&sources, !opts.quick));
    }
    let steps = if opts.quick { 10 } else { 40 };
    if opts.quick {
        sources.retain(|s| !matches!(s, meshes::Source::File(_)));
        sources.truncate(3);
    }
    if want("meshes") {
        cases.extend(meshes::cases(&sources, steps));
    }
    let elapsed = start.elapsed().as_secs_f64();

    println!("{}", text_table(&cases));
    let failed = cases.iter().filter(|c| !c.passed).count();
    println!(
        "{} cases, {} passed, {failed} failed ({elapsed:.0} s)",
        cases.len(),
        cases.len() - failed
    );
    if write {
        let md = render_markdown(opts, &cases, &figs.list, &mesh_note, elapsed);
        let path = root.join("docs").join("validation.md");
        std::fs::write(&path, md).with_context(|| format!("cannot write {}", path.display()))?;
        println!(
            "wrote {} and {} figures in {}",
            path.display(),
            figs.list.len(),
            fig_dir.display()
        );
    }
    if failed > 0 {
        bail!("{failed} validation case(s) failed");
    }
    Ok(())
}

fn render_markdown(
    opts: &Options,
    cases: &[Case],
    figures: &[(String, String)],
    mesh_note: &str,
    elapsed: f64,
) -> String {
    let failed = cases.iter().filter(|c| !c.passed).count();
    let mut s = String::new();
    s.push_str("# Validation report\n\n");
    s.push_str(
        "Generated by `cargo xtask validate` (release build; source: `xtask/src/validate/`). \
         Do not edit by hand: rerun the command. Equation numbers refer to the papers \
         (Wang et al. 2015 shells, Diziol, Bender and Bayer 2011 volumetric bodies, Song 2009 \
         two-layer objects); see `docs/theory.md`.\n\n",
    );
    let _ = writeln!(
        s,
        "Run: `cargo xtask validate{}`, {} cases, **{} passed, {failed} failed**, {elapsed:.0} s on {}. \
         Meshes: {mesh_note}.\n",
        if opts.quick { " --quick" } else { "" },
        cases.len(),
        cases.len() - failed,
        crate::report::machine()
    );
    s.push_str("## What is checked\n\n");
    s.push_str(
        "* **shell**: quasi-static inflation of icospheres (constant gauge pressure, sparse Cholesky, \
         dt = 1 s, stepped until the volume changes by < 1e-13 per step) against the analytic pressure-stretch \
         curve `p(lambda) = H / (R lambda^2) (P_11 + P_22)` (docs/analytic-sphere.md, `R = 3 V0 / A0`), \
         for St. Venant-Kirchhoff (Eq. 6-9) and neo-Hookean, at two resolutions; the thickness scaling \
         of Eq. 5-9 (`p` proportional to `H` at a fixed stretch); the isothermal gas law (Eq. 12-14); \
         zero net force and torque of the pressure load (Eq. 15) on a perturbed closed surface; the \
         shell-volume projection (Eq. 24-28, Alg. 2) over a long pump inflation of the teddy.\n",
    );
    s.push_str(
        "* **membrane**: rubber membranes (docs/membranes.md section 9): for neo-Hookean, \
         Mooney-Rivlin, Gent, Ogden (natural-rubber preset) and Yeoh, the pressure-volume curve \
         of an icosphere of 2562 vertices traced under volume control (the pressure is the \
         constraint's multiplier), its maximum and minimum located (refined ratios, parabola) and \
         compared with the analytic thin sphere `P(l) = H / (R l^2) w'(l)` (M18-M21) in location \
         and height (0.5 %); past the maximum, the spread of the element area stretches shows \
         whether the sphere stays uniform (a bifurcation would grow it).\n",
    );
    s.push_str(
        "* **tube**: the bulging tube (docs/membranes.md section 10): a closed Gent tube \
         (L/R = 40, hemispherical caps, a band 1 % thinner in the middle) traced under volume \
         control; the initiation pressure against the uniform closed-end tube's maximum, the \
         propagation pressure and bulge radius against Maxwell's equal-area rule on it, and the \
         localisation of the bulge.\n",
    );
    s.push_str(
        "* **volumetric**: per-cell volume after every step (Diziol, Bender and Bayer 2011, Eq. 1-2, tolerance 1e-10), \
         momentum of a free body, lattice volume vs the enclosed volume of the input surface, \
         contacts in the drop-sphere scene.\n",
    );
    s.push_str(
        "* **drop-sphere**: `balloon volumetric`'s default drop-sphere scene (sphere and springs \
         scaled to the body, lattice of about 1000 cells) on the teddy and every shared model at \
         its natural size, 2000 steps with each cell solver at its defaults (global; Gauss-Seidel \
         with the gradient correction and adaptive over-relaxation): every step completes, the \
         cells keep their volume and no tetrahedron inverts (both recomputed from the positions), \
         the sphere reaches the body; `--scene free` 2000 steps with both solvers; the paper's \
         exact Gauss-Seidel sweeps on the same scenes, recorded as an expected stop at the \
         500-sweep limit.\n",
    );
    s.push_str(
        "* **two-layer**: fitted global order of each explicit integrator (Song 2009, Ch. 5) on the \
         hanging spring with a closed-form solution, energy drift of an undamped pressurised sphere, \
         settled radii of a pressurised 12-gon vs its radial force balance (docs/two-layer.md).\n",
    );
    s.push_str(
        "* **floppy**: the Newton iterations and sub-steps of the first steps of a default pump \
         inflation of the shared bunny at 0.1 m, under bounds (the floppy start, issue 30).\n",
    );
    s.push_str(
        "* **thin-parts**: the static solve (constant 1500 Pa, StVK wall of 0.5 mm) on a box with \
         sharp edges and on flattened ellipsoids with 8 mm and 6 mm thin fins converges, within a \
         bound on its Newton iterations, to a stable equilibrium (smallest eigenvalue of \
         `K y = lambda M y` positive; docs/benchmarks.md, \"The static solve on thin parts\").\n",
    );
    s.push_str(
        "* **design**: round trips of the inverse design (docs/design.md, D20): each model at \
         0.1 m is inflated statically (neo-Hookean prism wall, 1 mm, 2 kPa, bending twice the \
         plate modulus), designed back from the inflated shape alone, and the designed rest \
         shape must be the known one within 1e-3 of the diagonal, its forward check on the \
         target within 1e-4 (the built-in Teddy; with the full run also the shared meshes).\n",
    );
    s.push_str(
        "* **meshes**: every mesh is loaded, validated (closed, oriented 2-manifold), scaled to \
         0.3 m and inflated by the pump (3 Newton iterations, sparse Cholesky, projection on).\n\n",
    );
    s.push_str("## Results\n\n");
    if failed > 0 {
        s.push_str("Failed cases (reported to the owners of the code they exercise; no tolerance was widened to hide them):\n\n");
        for c in cases.iter().filter(|c| !c.passed) {
            let _ = writeln!(s, "* {} / {}: {}", c.group, c.name, c.measured);
        }
        s.push('\n');
    }
    s.push_str(&markdown_table(cases));
    s.push_str("\n## Figures\n\n");
    for (file, caption) in figures {
        let _ = writeln!(s, "### {caption}\n\n![{caption}](figures/{file})\n");
    }
    s.push_str("## Reproduce\n\n");
    s.push_str(
        "* Everything above (table and every figure): `cargo xtask validate` (about 14.5 minutes on \
         2 cores, 6.5 of them the membrane traces, 2.5 the bulging tube; `--quick` for a 1-2 minute subset, `--meshes DIR` for another mesh folder, \
         `--no-write` to only print the table).\n",
    );
    s.push_str(
        "* The same checks at smaller sizes run in the default test suite: \
         `cargo test -p balloon-tests` (shell, volumetric, two-layer integration tests).\n",
    );
    s
}

/// The vertex of the parabola through three points `(x, y)` (a traced curve's extremum located
/// from its finest three points), or `None` when they are collinear.
pub(crate) fn parabola_vertex(p: [(f64, f64); 3]) -> Option<(f64, f64)> {
    let [(x0, y0), (x1, y1), (x2, y2)] = p;
    let d01 = (y1 - y0) / (x1 - x0);
    let d12 = (y2 - y1) / (x2 - x1);
    let a = (d12 - d01) / (x2 - x0);
    if a == 0.0 || !a.is_finite() {
        return None;
    }
    let b = d01 - a * (x0 + x1);
    let x = -b / (2.0 * a);
    Some((x, y1 + (x - x1) * (d01 + a * (x - x0))))
}

#[cfg(test)]
mod tests {
    use super::parabola_vertex;

    /// The vertex of `y = 2 (x - 1.3)^2 - 0.7` from three unevenly spaced points; `None` for
    /// collinear points.
    #[test]
    fn parabola_vertex_of_a_known_parabola() {
        let f = |x: f64| 2.0 * (x - 1.3) * (x - 1.3) - 0.7;
        let (x, y) = parabola_vertex([(0.2, f(0.2)), (1.0, f(1.0)), (2.5, f(2.5))]).unwrap();
        assert!(
            (x - 1.3).abs() < 1e-12 && (y + 0.7).abs() < 1e-12,
            "({x}, {y})"
        );
        assert_eq!(parabola_vertex([(0.0, 1.0), (1.0, 2.0), (3.0, 4.0)]), None);
    }
}
