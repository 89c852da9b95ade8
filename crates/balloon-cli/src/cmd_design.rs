//! `balloon design TARGET --pressure P [material and wall flags] --out DIR`: the rest shape
//! whose static equilibrium under the gauge pressure P is the target (inverse statics,
//! `docs/design.md`), checked by a forward static solve.
//!
//! Writes `DIR/rest.obj` (the designed rest shape), `DIR/inflated.obj` (the forward check's
//! equilibrium, rigidly aligned onto the target), `DIR/distance.csv` (per-vertex distance of
//! the check to the target, m) and `DIR/summary.json` (iterations, distance in m and over the
//! bounding-box diagonal, pressure, volumes, times). Ctrl-C stops the design and keeps the best
//! rest shape so far (then checked and written, and the process exits with 130).
//!
//! The forward check keeps a three-prism wall at its rest thickness; the summary prints (and
//! records as `check_command`) the `balloon inflate ... --volume-projection off` command that
//! repeats it from `rest.obj` (`docs/design.md`, "Repeating the check").

use anyhow::{Context, Result, bail};
use balloon_design::{DesignParams, DesignProblem, InverseParams, design};
use balloon_mesh::TriMesh;
use balloon_scenario::material::MaterialSpec;
use serde::Serialize;
use std::path::PathBuf;

use crate::material_args::MaterialArgs;
use crate::params::real;
use balloon_scenario::range::End;

/// The flags of `balloon design`.
#[derive(Debug, clap::Args)]
pub struct DesignArgs {
    /// The target inflated shape: a closed, outward-oriented mesh file (.obj, .off, .ply, .stl)
    /// or `builtin[:NAME]`.
    pub target: String,
    /// Gauge pressure the balloon holds at the target shape, Pa (> 0).
    #[arg(long, value_parser = real(End::Open(0.0), End::Closed(1e9)))]
    pub pressure: f64,
    /// Rest wall thickness, m, in (0, 1].
    #[arg(long, default_value_t = 3.0e-4, value_parser = real(End::Open(0.0), End::Closed(1.0)))]
    pub thickness: f64,
    /// Multiply the target's coordinates by this factor (mesh units -> metres), > 0.
    #[arg(long, default_value_t = 1.0, value_parser = real(End::Open(0.0), End::Closed(1e6)))]
    pub scale: f64,
    /// The material of the wall.
    #[command(flatten)]
    pub material: MaterialArgs,
    /// Relative equilibrium residual at which the design stops, in (0, 1).
    #[arg(long, default_value_t = InverseParams::default().tolerance,
          value_parser = real(End::Open(0.0), End::Open(1.0)))]
    pub tolerance: f64,
    /// Weight of the tangential regulariser of the rest mesh (relative to the mean diagonal of
    /// J^T J; 0 = none, the design exact; docs/design.md), >= 0.
    #[arg(long, default_value_t = 0.0, value_parser = real(End::Closed(0.0), End::Closed(1e6)))]
    pub tangential_weight: f64,
    /// Output folder (created; existing files of the same names are replaced).
    #[arg(long)]
    pub out: PathBuf,
    /// Print no progress.
    #[arg(long)]
    pub quiet: bool,
}

/// `summary.json` of `balloon design`.
#[derive(Debug, Serialize)]
pub struct DesignSummary {
    /// The target as given.
    pub target: String,
    /// Vertices and triangles.
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
    /// Enclosed volumes, m^3.
    pub target_volume: f64,
    /// Enclosed volume of the rest shape, m^3.
    pub rest_volume: f64,
    /// The `balloon inflate` command that repeats the forward check from the written
    /// `rest.obj` (its enclosed volume is `check.volume`).
    pub check_command: String,
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

/// `text` quoted for a POSIX shell when it holds anything but plain path characters.
fn shell_quoted(text: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "/._-+:=,@".contains(c);
    if !text.is_empty() && text.chars().all(plain) {
        text.to_string()
    } else {
        format!("'{}'", text.replace('\'', r"'\''"))
    }
}

/// The material flags that give `spec` (the flags as the user gave them; numbers in their
/// shortest exact form, so the command reproduces the values bit for bit).
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
/// rest thickness (`--volume-projection off`: the design's equations keep `h = H`, see
/// `docs/design.md`), and the same material flags.
pub fn check_command(
    rest: &std::path::Path,
    pressure: f64,
    thickness: f64,
    spec: &MaterialSpec,
) -> String {
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

fn load_target(spec: &str, scale: f64) -> Result<TriMesh> {
    let mut mesh =
        balloon_mesh::load(spec).with_context(|| format!("cannot load mesh `{spec}`"))?;
    if scale != 1.0 {
        mesh.scale(scale);
    }
    balloon_mesh::validate::validate_closed_manifold(&mesh)
        .with_context(|| format!("target `{spec}` is not a closed, oriented manifold"))?;
    Ok(mesh)
}

/// Runs `balloon design`.
///
/// # Errors
/// A target that cannot be read or is not closed, invalid material flags, a failed design or
/// forward check, an output folder that cannot be written; an interruption after the records
/// are written.
pub fn run(args: &DesignArgs) -> Result<()> {
    let target = load_target(&args.target, args.scale)?;
    let material = args
        .material
        .spec()
        .resolve()
        .map_err(|e| anyhow::anyhow!(e))
        .context("material")?;
    let material_name = material.name();
    let problem = DesignProblem::try_new(
        &target,
        vec![args.thickness; target.num_triangles()],
        material,
        args.pressure,
    )?;
    let params = DesignParams {
        inverse: InverseParams {
            tolerance: args.tolerance,
            tangential_weight: args.tangential_weight,
            ..InverseParams::default()
        },
        ..DesignParams::default()
    };
    let quiet = args.quiet;
    let result = design(&problem, &params, |p| {
        if !quiet {
            eprintln!(
                "design: pressure factor {:.3}, relative residual {:.3e}, iteration {}",
                p.load, p.relative_residual, p.iterations
            );
        }
        balloon_run::interrupt::pending().is_none()
    })?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create `{}`", args.out.display()))?;
    let mut rest = target.clone();
    rest.set_positions_flat(&result.rest);
    let mut inflated = target.clone();
    inflated.set_positions_flat(&result.check.positions);
    for (name, mesh) in [("rest.obj", &rest), ("inflated.obj", &inflated)] {
        let path = args.out.join(name);
        balloon_mesh::io::write_obj(&path, mesh)
            .with_context(|| format!("cannot write `{}`", path.display()))?;
    }
    let d = balloon_design::vertex_distances(&result.check.positions, problem.target());
    let csv: String = std::iter::once("vertex,distance_m\n".to_string())
        .chain(d.iter().enumerate().map(|(i, v)| format!("{i},{v:e}\n")))
        .collect();
    let path = args.out.join("distance.csv");
    std::fs::write(&path, csv).with_context(|| format!("cannot write `{}`", path.display()))?;
    let interrupted = balloon_run::interrupt::pending();
    let summary = DesignSummary {
        target: args.target.clone(),
        vertices: target.num_vertices(),
        triangles: target.num_triangles(),
        material: material_name,
        pressure: args.pressure,
        thickness: args.thickness,
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
        check_command: check_command(
            &args.out.join("rest.obj"),
            args.pressure,
            args.thickness,
            &args.material.spec(),
        ),
    };
    let path = args.out.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&summary)? + "\n")
        .with_context(|| format!("cannot write `{}`", path.display()))?;
    let dist = &result.check.distance;
    println!(
        "design {}: {} inverse iterations, forward check {} (max distance {:.3e} m = {:.3e} of the \
         diagonal, RMS {:.3e} m, volume {:.4e} m^3); written to {}\nrepeat the check: {}",
        if result.inverse.converged {
            "converged"
        } else {
            "NOT converged"
        },
        result.inverse.iterations,
        if result.check.converged {
            "converged"
        } else {
            "did not converge"
        },
        dist.max,
        dist.max_relative,
        dist.rms,
        result.check.volume,
        args.out.display(),
        summary.check_command
    );
    if let Some(signal) = interrupted {
        return Err(balloon_run::interrupt::Interrupted {
            signal,
            steps: result.inverse.iterations,
        }
        .into());
    }
    if !result.inverse.converged {
        bail!(
            "no rest shape holds the target at `pressure` = {} Pa (reached {:.3} of it, relative \
             residual {:.3e}); the best design so far is written",
            args.pressure,
            result.inverse.load_reached,
            result.inverse.relative_residual
        );
    }
    Ok(())
}
