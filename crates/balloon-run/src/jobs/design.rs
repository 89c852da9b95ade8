//! The inverse design job (`balloon design`, a scenario's `[design]` table, Python's
//! `balloon.design`): the rest shape whose static equilibrium under a gauge pressure is a target
//! surface (`balloon_design`, `docs/design.md`), checked by a forward static solve, with its
//! output folder (`rest.obj`, `inflated.obj`, `distance.csv`, `summary.json`) and the
//! `balloon inflate` command that repeats the check.

use anyhow::{Context, Result};
use balloon::mesh::TriMesh;
use balloon_design::{Design, DesignParams, DesignProblem, InverseParams, design};
use balloon_scenario::material::MaterialSpec;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// What a design job needs: the target and the wall, the load and the solve's settings.
#[derive(Clone, Debug)]
pub struct DesignJob {
    /// The target surface (closed, outward-oriented; positions in m).
    pub target: TriMesh,
    /// How the target was given (a path, `builtin:NAME`, `arrays`), for the summary.
    pub target_name: String,
    /// Gauge pressure at the target shape, Pa.
    pub pressure: f64,
    /// Rest wall thickness, m.
    pub thickness: f64,
    /// The wall's material keys.
    pub material: MaterialSpec,
    /// Relative equilibrium residual at which the inverse solve stops.
    pub tolerance: f64,
    /// Weight of the tangential regulariser (0: none).
    pub tangential_weight: f64,
    /// Output folder (none: nothing written).
    pub out: Option<PathBuf>,
    /// Print no progress.
    pub quiet: bool,
}

impl DesignJob {
    /// A job with the defaults of `balloon design` (thickness 0.3 mm, the default material,
    /// the inverse solve's tolerance, no regulariser, no output folder).
    pub fn new(target: TriMesh, target_name: impl Into<String>, pressure: f64) -> Self {
        Self {
            target,
            target_name: target_name.into(),
            pressure,
            thickness: 3.0e-4,
            material: MaterialSpec::default(),
            tolerance: InverseParams::default().tolerance,
            tangential_weight: 0.0,
            out: None,
            quiet: true,
        }
    }
}

/// `summary.json` of a design.
#[derive(Debug, Serialize)]
pub struct DesignSummary {
    /// The target as given.
    pub target: String,
    /// Vertices of the target (and of the rest shape).
    pub vertices: usize,
    /// Triangle count.
    pub triangles: usize,
    /// The material's name.
    pub material: String,
    /// Gauge pressure, Pa.
    pub pressure: f64,
    /// Rest wall thickness, m.
    pub thickness: f64,
    /// Whether the inverse solve reached the full pressure and the tolerance.
    pub converged: bool,
    /// Whether Ctrl-C stopped the design.
    pub interrupted: bool,
    /// The inverse solve's record (iterations, stages, residual, seconds).
    pub inverse: balloon_design::InverseInfo,
    /// The forward check: converged, iterations, distance to the target (m and relative).
    pub check: CheckSummary,
    /// Target bounding-box diagonal, m.
    pub bbox_diagonal: f64,
    /// Enclosed volume of the target, m^3.
    pub target_volume: f64,
    /// Enclosed volume of the rest shape, m^3.
    pub rest_volume: f64,
    /// The `balloon inflate` command that repeats the forward check from the written
    /// `rest.obj` (its enclosed volume is `check.volume`); null without an output folder.
    pub check_command: Option<String>,
}

/// The forward check in `summary.json`.
#[derive(Debug, Serialize)]
pub struct CheckSummary {
    /// Whether the static solve converged.
    pub converged: bool,
    /// Newton iterations.
    pub iterations: usize,
    /// Distance of the equilibrium to the target.
    pub distance: balloon_design::Distance,
    /// Enclosed volume of the equilibrium, m^3.
    pub volume: f64,
    /// Seconds.
    pub seconds: f64,
}

/// What a design job found.
#[derive(Debug)]
pub struct DesignRun {
    /// The design: rest positions, the inverse solve's record, the forward check.
    pub design: Design,
    /// The summary (`summary.json`).
    pub summary: DesignSummary,
    /// The signal that stopped the design, if one did (the best design so far is kept).
    pub interrupted: Option<i32>,
}

/// `text` quoted for a POSIX shell when it holds anything but plain path characters.
fn shell_quoted(text: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "/._-+:=,@".contains(c);
    if !text.is_empty() && text.chars().all(plain) {
        text.to_string()
    } else {
        format!("'{}'", text.replace('\'', r"'\''"))
    }
}

/// The material flags that give `spec` (numbers in their shortest exact form, so the command
/// reproduces the values bit for bit).
fn material_flags(spec: &MaterialSpec) -> Vec<String> {
    let list = |v: &[f64]| v.iter().map(f64::to_string).collect::<Vec<_>>().join(",");
    let mut flags = Vec::new();
    let mut push = |flag: &str, value: Option<String>| {
        if let Some(v) = value {
            flags.push(format!("--{flag} {v}"));
        }
    };
    push("material", spec.material.map(|m| m.to_string()));
    push(
        "material-preset",
        spec.material_preset.map(|m| m.to_string()),
    );
    push("young", spec.young.map(|v| v.to_string()));
    push("poisson", spec.poisson.map(|v| v.to_string()));
    push("mu", spec.mu.map(|v| v.to_string()));
    push("c1", spec.c1.map(|v| v.to_string()));
    push("c2", spec.c2.map(|v| v.to_string()));
    push("jm", spec.jm.map(|v| v.to_string()));
    push("ogden-mu", spec.ogden_mu.as_deref().map(list));
    push("ogden-alpha", spec.ogden_alpha.as_deref().map(list));
    push("yeoh", spec.yeoh.as_deref().map(list));
    flags
}

/// The `balloon inflate` command whose static solve is the design's forward check: the
/// written rest shape (already in metres), the gauge pressure held constant, the wall at its
/// rest thickness (`--volume-projection off`: the design's equations keep `h = H`,
/// `docs/design.md`), and the same material flags.
pub fn check_command(rest: &Path, pressure: f64, thickness: f64, spec: &MaterialSpec) -> String {
    let mut words = vec![
        "balloon inflate".to_string(),
        shell_quoted(&rest.display().to_string()),
        "--static --gas constant".to_string(),
        format!("--pressure {pressure}"),
        "--volume-projection off".to_string(),
        format!("--thickness {thickness}"),
    ];
    words.extend(material_flags(spec));
    words.join(" ")
}

/// Runs a design: checks the target, resolves the material, designs (progress on stderr unless
/// `quiet`; Ctrl-C keeps the best design so far), checks it, and writes the output folder when
/// one is given.
///
/// # Errors
/// A target that is not closed and oriented, invalid material keys, a parameter out of range
/// (named in backticks), a design or check that fails outright, an output that cannot be
/// written. A design that stops unconverged is not an error here: `design.inverse.converged`
/// says so (the CLI turns it into one after writing).
pub fn run(job: &DesignJob) -> Result<DesignRun> {
    balloon::mesh::validate::validate_closed_manifold(&job.target).with_context(|| {
        format!(
            "target `{}` is not a closed, oriented manifold",
            job.target_name
        )
    })?;
    let material = job
        .material
        .resolve()
        .map_err(anyhow::Error::msg)
        .context("material")?;
    let material_name = material.name();
    let problem = DesignProblem::try_new(
        &job.target,
        vec![job.thickness; job.target.num_triangles()],
        material,
        job.pressure,
    )?;
    let params = DesignParams {
        inverse: InverseParams {
            tolerance: job.tolerance,
            tangential_weight: job.tangential_weight,
            ..InverseParams::default()
        },
        ..DesignParams::default()
    };
    let quiet = job.quiet;
    let result = design(&problem, &params, |p| {
        if !quiet {
            eprintln!(
                "design: pressure factor {:.3}, relative residual {:.3e}, iteration {}",
                p.load, p.relative_residual, p.iterations
            );
        }
        crate::interrupt::pending().is_none()
    })?;
    if let Some(out) = &job.out {
        write_outputs(out, &job.target, &result, problem.target())?;
    }
    let interrupted = crate::interrupt::pending();
    let summary = DesignSummary {
        target: job.target_name.clone(),
        vertices: job.target.num_vertices(),
        triangles: job.target.num_triangles(),
        material: material_name,
        pressure: job.pressure,
        thickness: job.thickness,
        converged: result.inverse.converged,
        interrupted: interrupted.is_some(),
        inverse: result.inverse.clone(),
        check: CheckSummary {
            converged: result.check.converged,
            iterations: result.check.iterations,
            distance: result.check.distance,
            volume: result.check.volume,
            seconds: result.check.seconds,
        },
        bbox_diagonal: balloon_design::bbox_diagonal(problem.target()),
        target_volume: balloon_design::enclosed_volume(problem.target(), problem.triangles()),
        rest_volume: balloon_design::enclosed_volume(&result.rest, problem.triangles()),
        check_command: job.out.as_ref().map(|out| {
            check_command(
                &out.join("rest.obj"),
                job.pressure,
                job.thickness,
                &job.material,
            )
        }),
    };
    if let Some(out) = &job.out {
        let path = out.join("summary.json");
        std::fs::write(&path, serde_json::to_string_pretty(&summary)? + "\n")
            .with_context(|| format!("cannot write `{}`", path.display()))?;
    }
    Ok(DesignRun {
        design: result,
        summary,
        interrupted,
    })
}

/// Writes `rest.obj`, `inflated.obj` and `distance.csv` into `out` (created).
fn write_outputs(out: &Path, target: &TriMesh, result: &Design, target_x: &[f64]) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create `{}`", out.display()))?;
    let mut rest = target.clone();
    rest.set_positions_flat(&result.rest);
    let mut inflated = target.clone();
    inflated.set_positions_flat(&result.check.positions);
    for (name, mesh) in [("rest.obj", &rest), ("inflated.obj", &inflated)] {
        let path = out.join(name);
        balloon::mesh::io::write_obj(&path, mesh)
            .with_context(|| format!("cannot write `{}`", path.display()))?;
    }
    let d = balloon_design::vertex_distances(&result.check.positions, target_x);
    let csv: String = std::iter::once("vertex,distance_m\n".to_string())
        .chain(d.iter().enumerate().map(|(i, v)| format!("{i},{v:e}\n")))
        .collect();
    let path = out.join("distance.csv");
    std::fs::write(&path, csv).with_context(|| format!("cannot write `{}`", path.display()))?;
    Ok(())
}
