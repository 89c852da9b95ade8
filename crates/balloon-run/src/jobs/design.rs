//! The inverse design job (`balloon design`, a scenario's `[design]` table, Python's
//! `balloon.design`): the rest shape whose static equilibrium under a gauge pressure is a target
//! surface (`balloon_design`, `docs/design.md`), checked by a forward static solve, with its
//! output folder (`rest.obj`, `inflated.obj`, `distance.csv`, `design.png`, `summary.json`)
//! and the `balloon inflate` command that repeats the check.

use anyhow::{Context, Result};
use balloon::mesh::TriMesh;
use balloon_design::{Design, DesignParams, DesignProblem, DesignProgress, design};
use balloon_render::{
    Camera, ColorScale, Framing, Image, Projection, RenderError, RenderOptions, Renderer, Surface,
    UpAxis,
};
use balloon_scenario::material::MaterialSpec;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The ambient pressure of a gas amount unless one is given, Pa (a standard atmosphere, as
/// `balloon inflate`'s).
pub const DEFAULT_AMBIENT: f64 = 101_325.0;

/// What a design job needs: the target and the wall, the load and the solve's settings.
#[derive(Clone, Debug)]
pub struct DesignJob {
    /// The target surface (closed, outward-oriented; positions in m).
    pub target: TriMesh,
    /// How the target was given (a path, `builtin:NAME`, `arrays`), for the summary.
    pub target_name: String,
    /// Gauge pressure at the target shape, Pa (unused when `gas_amount` is given).
    pub pressure: f64,
    /// The load as an amount of isothermal ideal gas instead, `nRT = p_abs V` in J
    /// (`balloon_design::DesignProblem::with_gas_amount`): its gauge pressure at the target is
    /// `gas_amount / V* - ambient`.
    pub gas_amount: Option<f64>,
    /// Ambient pressure of the gas amount, Pa [default: 101325].
    pub ambient: f64,
    /// Rest wall thickness, m.
    pub thickness: f64,
    /// The wall's material keys.
    pub material: MaterialSpec,
    /// The solve's parameters (the inverse solve, the forward check, the shape optimisation;
    /// `balloon_scenario::design::set_design_option` sets the ones the front ends expose).
    pub params: DesignParams,
    /// A rest shape to keep instead of designing one (same vertices and triangles as the
    /// target; `balloon_design::design_for_rest`): it is checked, and its wall fitted when
    /// `params.thickness.enabled`.
    pub rest: Option<TriMesh>,
    /// Output folder (none: nothing written).
    pub out: Option<PathBuf>,
    /// Replace the files of an earlier design in `out` (else such a folder is refused before
    /// the design starts; nothing else in it is touched).
    pub overwrite: bool,
    /// Print no progress.
    pub quiet: bool,
}

impl DesignJob {
    /// A job with the defaults of `balloon design` (thickness 0.3 mm, the default material,
    /// the library's [`DesignParams`], no output folder).
    pub fn new(target: TriMesh, target_name: impl Into<String>, pressure: f64) -> Self {
        Self {
            target,
            target_name: target_name.into(),
            pressure,
            gas_amount: None,
            ambient: DEFAULT_AMBIENT,
            thickness: 3.0e-4,
            material: MaterialSpec::default(),
            params: DesignParams::default(),
            rest: None,
            out: None,
            overwrite: false,
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
    /// Gauge pressure at the target, Pa (of the gas amount when one was given).
    pub pressure: f64,
    /// The gas amount `nRT` (J) when the load was one, else null.
    pub gas_amount: Option<f64>,
    /// Its ambient pressure (Pa), null without a gas amount.
    pub ambient: Option<f64>,
    /// Rest wall thickness, m.
    pub thickness: f64,
    /// Whether the inverse solve reached the full pressure and the tolerance.
    pub converged: bool,
    /// Whether the design answers its target: `converged`, or the forward check within
    /// `params.accept_distance` of the target's diagonal (`balloon_design::Design::accepted`).
    pub accepted: bool,
    /// Whether Ctrl-C stopped the design.
    pub interrupted: bool,
    /// The parameters the design ran with (`balloon_design::DesignParams`).
    pub params: DesignParams,
    /// The inverse solve's record (iterations, stages, residual, seconds).
    pub inverse: balloon_design::InverseInfo,
    /// The wall-thickness fit's record (`--fit-thickness`), null without one.
    pub thickness_fit: Option<ThicknessFitSummary>,
    /// The forward check: converged, iterations, distance to the target (m and relative).
    pub check: CheckSummary,
    /// How well the target determines the rest shape (`--conditioning`; docs/design.md D19):
    /// the smallest singular values of the inverse's Jacobian, null without it.
    pub conditioning: Option<balloon_design::RestConditioning>,
    /// The file of the conditioning report's singular vectors ([`CONDITIONING_MODES`]), null
    /// without the report or an output folder.
    pub conditioning_modes: Option<String>,
    /// Target bounding-box diagonal, m.
    pub bbox_diagonal: f64,
    /// Enclosed volume of the target, m^3.
    pub target_volume: f64,
    /// Enclosed volume of the rest shape, m^3.
    pub rest_volume: f64,
    /// The `balloon inflate` command that repeats the forward check from the written
    /// `rest.obj` (`rest.ply` with a fitted thickness; its enclosed volume is `check.volume`); null
    /// without an output folder.
    pub check_command: Option<String>,
    /// The picture of target and check side by side (`design.png`, [`design_picture`]); null
    /// without an output folder or when it could not be rendered (a warning says why).
    pub picture: Option<String>,
}

/// The wall-thickness fit in `summary.json`.
#[derive(Debug, Serialize)]
pub struct ThicknessFitSummary {
    /// Steps, forward solves, distances before and after, why it stopped, the bounds.
    #[serde(flatten)]
    pub info: balloon_design::ThicknessFitInfo,
    /// The thinnest fitted face, m.
    pub min: f64,
    /// The thickest fitted face, m.
    pub max: f64,
    /// The area-weighted mean of the fitted thickness over the target, m.
    pub mean: f64,
    /// The file with the fitted thickness as a face property (`rest.ply`); null without an
    /// output folder.
    pub file: Option<String>,
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

/// How the design's load appears in its check command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CheckLoad {
    /// A constant gauge pressure, Pa.
    Pressure(f64),
    /// An amount of ideal gas, as `balloon inflate --gas ideal` takes it: the gauge pressure
    /// at the rest volume (Pa) and the ambient pressure (Pa).
    Ideal {
        /// Gauge pressure at the rest shape's volume, Pa.
        rest_gauge: f64,
        /// Ambient pressure, Pa.
        ambient: f64,
    },
}

/// The `balloon inflate` command whose static solve is the design's forward check: the
/// written rest shape (already in metres), the load (a constant gauge pressure, or the gas
/// amount as `--gas ideal` with its gauge pressure at the rest volume), the wall at its rest
/// thickness (`--volume-projection off`: the design's equations keep `h = H`,
/// `docs/design.md`), and the same material flags.
pub fn check_command(rest: &Path, load: CheckLoad, thickness: f64, spec: &MaterialSpec) -> String {
    let gas = match load {
        CheckLoad::Pressure(p) => format!("--gas constant --pressure {p}"),
        CheckLoad::Ideal {
            rest_gauge,
            ambient,
        } => format!("--gas ideal --pressure {rest_gauge} --ambient {ambient}"),
    };
    let mut words = vec![
        "balloon inflate".to_string(),
        shell_quoted(&rest.display().to_string()),
        "--static".to_string(),
        gas,
        "--volume-projection off".to_string(),
        format!("--thickness {thickness}"),
    ];
    words.extend(material_flags(spec));
    words.join(" ")
}

/// The line printed once when the shape optimisation begins: the inverse found no exact design,
/// what the optimisation costs, and what else the user may ask for.
fn optimisation_notice(params: &DesignParams) -> String {
    let wall = if params.wall_bending == 0.0 {
        " For a wall without bending stiffness (`bending` = 0, the default) a drawn target \
         often has none (docs/design.md, \"What it can and cannot reach\"). `bending` = 1 or \
         more designs for a wall with a rubber plate's bending stiffness instead (another \
         model), whose inverse closes round trips that the wall without it does not \
         (docs/design.md D21)."
    } else {
        ""
    };
    if params.fallback.mode == balloon_design::FallbackMode::Always {
        return format!(
            "design: the shape optimisation now minimises the distance of the forward \
             equilibrium to the target (`fallback` = always), one forward static solve or more \
             per step (steps: at most {}, `fallback_iterations`). Ctrl-C keeps the best design \
             so far.",
            params.fallback.max_iterations
        );
    }
    format!(
        "design: the inverse found no exact design; the shape optimisation now minimises the \
         distance of the forward equilibrium to the target, one forward static solve or more \
         per step (steps: at most {}, `fallback_iterations`). Ctrl-C keeps the best design so \
         far. `accept_distance` accepts a design within a given fraction of the diagonal.{wall}",
        params.fallback.max_iterations
    )
}

/// The line printed once when the inverse first halves its pressure increment: the stage to
/// `load` did not converge, what the continuation does next and what a stage costs at the pace
/// so far (`seconds` per iteration).
fn halving_notice(params: &DesignParams, load: f64, seconds: f64) -> String {
    let inverse = &params.inverse;
    let next = match params.fallback.mode {
        balloon_design::FallbackMode::Off => "the design ends there (`fallback` = off)",
        _ => "the shape optimisation starts from the inverse's best design",
    };
    format!(
        "design: the stage to pressure factor {load:.3} did not converge in {} iterations; the \
         inverse now tries half the increment (a continuation, at most {} halvings of up to {} \
         iterations each, about {:.0} s each at this pace). It ends sooner when three failed \
         stages in a row show that halving does not make them easier, the sign that no fraction \
         of the pressure is held exactly; then {next}. Ctrl-C keeps the best design so far.",
        inverse.max_iterations,
        inverse.max_halvings,
        inverse.max_iterations,
        seconds * inverse.max_iterations as f64,
    )
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
    if let Some(out) = &job.out {
        crate::output::check_out_dir_files(out, job.overwrite, DESIGN_FILES, "design")?;
    }
    let thickness = vec![job.thickness; job.target.num_triangles()];
    let problem = match job.gas_amount {
        None => DesignProblem::try_new(&job.target, thickness, material, job.pressure)?,
        Some(amount) => {
            DesignProblem::with_gas_amount(&job.target, thickness, material, amount, job.ambient)?
        }
    };
    let pressure = problem.pressure();
    let quiet = job.quiet;
    let mut optimising = false;
    // The last inverse stage reported (load reached, load asked) and whether a halving was told.
    let mut last_stage = (0.0, 0.0);
    let mut halved = false;
    let started = std::time::Instant::now();
    let show = |p: &DesignProgress| {
        if !quiet {
            match p {
                DesignProgress::Inverse(p) => {
                    let (reached, load) = std::mem::replace(&mut last_stage, (p.reached, p.load));
                    if !halved && p.reached == reached && p.load < load {
                        halved = true;
                        let pace = started.elapsed().as_secs_f64() / p.iterations.max(1) as f64;
                        eprintln!("{}", halving_notice(&job.params, load, pace));
                    }
                    eprintln!(
                        "design: pressure factor {:.3} reached, stage to {:.3}: relative residual {:.3e}, iteration {}",
                        p.reached, p.load, p.relative_residual, p.iterations
                    );
                }
                DesignProgress::Fallback(p) => {
                    if !std::mem::replace(&mut optimising, true) {
                        eprintln!("{}", optimisation_notice(&job.params));
                    }
                    eprintln!(
                        "design: shape optimisation step {}, distance max {:.4e} m, RMS {:.4e} m",
                        p.iteration, p.max_distance, p.rms_distance
                    );
                }
                DesignProgress::Thickness(p) => eprintln!(
                    "design: thickness fit step {}, distance max {:.4e} m, RMS {:.4e} m",
                    p.iteration, p.max_distance, p.rms_distance
                ),
            }
        }
        crate::interrupt::pending().is_none()
    };
    let result = match &job.rest {
        None => design(&problem, &job.params, show)?,
        Some(rest) => {
            if rest.num_vertices() != job.target.num_vertices()
                || rest.triangles != job.target.triangles
            {
                anyhow::bail!(
                    "the rest shape has {} vertices and {} triangles, the target `{}` {} and {}: \
                     a rest shape to keep must have the target's vertices and triangles, in the \
                     same order",
                    rest.num_vertices(),
                    rest.num_triangles(),
                    job.target_name,
                    job.target.num_vertices(),
                    job.target.num_triangles()
                );
            }
            balloon_design::design_for_rest(&problem, rest.positions_flat(), &job.params, show)?
        }
    };
    let picture = match &job.out {
        Some(out) => write_outputs(
            out,
            job.overwrite,
            &job.target,
            &result,
            problem.target(),
            pressure,
        )?,
        None => None,
    };
    let interrupted = crate::interrupt::pending();
    let rest_volume = balloon_design::enclosed_volume(&result.rest, problem.triangles());
    let summary = DesignSummary {
        target: job.target_name.clone(),
        vertices: job.target.num_vertices(),
        triangles: job.target.num_triangles(),
        material: material_name,
        pressure,
        gas_amount: job.gas_amount,
        ambient: job.gas_amount.map(|_| job.ambient),
        thickness: job.thickness,
        converged: result.inverse.converged,
        accepted: result.accepted(job.params.accept_distance),
        interrupted: interrupted.is_some(),
        params: job.params,
        inverse: result.inverse.clone(),
        thickness_fit: result.thickness.as_ref().map(|fit| {
            let areas = triangle_areas(problem.target(), problem.triangles());
            let total: f64 = areas.iter().sum();
            ThicknessFitSummary {
                info: fit.info.clone(),
                min: fit.thickness.iter().copied().fold(f64::INFINITY, f64::min),
                max: fit.thickness.iter().copied().fold(0.0, f64::max),
                mean: fit
                    .thickness
                    .iter()
                    .zip(&areas)
                    .map(|(h, a)| h * a)
                    .sum::<f64>()
                    / total,
                file: job.out.as_ref().map(|_| FITTED_REST.to_string()),
            }
        }),
        check: CheckSummary {
            converged: result.check.converged,
            iterations: result.check.iterations,
            distance: result.check.distance,
            volume: result.check.volume,
            seconds: result.check.seconds,
        },
        conditioning: result.conditioning.clone(),
        conditioning_modes: job
            .out
            .as_ref()
            .and(result.conditioning.as_ref())
            .map(|_| CONDITIONING_MODES.to_string()),
        bbox_diagonal: balloon_design::bbox_diagonal(problem.target()),
        target_volume: balloon_design::enclosed_volume(problem.target(), problem.triangles()),
        rest_volume,
        check_command: job.out.as_ref().map(|out| {
            let load = match problem.gas_amount() {
                None => CheckLoad::Pressure(pressure),
                Some(g) => CheckLoad::Ideal {
                    rest_gauge: g.gauge_pressure(rest_volume),
                    ambient: g.ambient,
                },
            };
            let rest = if result.thickness.is_some() {
                FITTED_REST
            } else {
                "rest.obj"
            };
            let command = check_command(&out.join(rest), load, job.thickness, &job.material);
            // The check's wall bends as the design's did.
            match job.params.wall_bending {
                b if b > 0.0 => format!("{command} --bending {b}"),
                _ => command,
            }
        }),
        picture,
    };
    if let Some(out) = &job.out {
        let text = serde_json::to_string_pretty(&summary)? + "\n";
        write_file(out, SUMMARY, |tmp| {
            std::fs::write(tmp, text).map_err(anyhow::Error::from)
        })?;
    }
    Ok(DesignRun {
        design: result,
        summary,
        interrupted,
    })
}

/// Writes `rest.obj`, `inflated.obj`, `distance.csv`, `design.png` (and `rest.ply` with a
/// fitted wall, [`CONDITIONING_MODES`] with the conditioning report) into `out` (created);
/// returns the picture's file name, or `None` (with a warning on stderr) when it could not be
/// rendered: a missing picture does not fail the design.
fn write_outputs(
    out: &Path,
    overwrite: bool,
    target: &TriMesh,
    result: &Design,
    target_x: &[f64],
    pressure: f64,
) -> Result<Option<String>> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create `{}`", out.display()))?;
    crate::output::prepare_out_dir_files(out, overwrite, DESIGN_FILES, "design")?;
    // A second Ctrl-C while the files are written removes their temporary files.
    crate::output::temp::watch_out_files(out, DESIGN_FILES);
    let mut rest = target.clone();
    rest.set_positions_flat(&result.rest);
    let mut inflated = target.clone();
    inflated.set_positions_flat(&result.check.positions);
    for (name, mesh) in [("rest.obj", &rest), ("inflated.obj", &inflated)] {
        write_file(out, name, |tmp| {
            balloon::mesh::io::write_obj(tmp, mesh).map_err(anyhow::Error::from)
        })?;
    }
    if let Some(fit) = &result.thickness {
        write_file(out, FITTED_REST, |tmp| {
            balloon::mesh::io::write_ply_binary_with_face_property(
                tmp,
                &rest,
                Some(("thickness", &fit.thickness)),
            )
            .map_err(anyhow::Error::from)
        })?;
    }
    if let Some(c) = &result.conditioning {
        let csv = modes_csv(&c.modes, target.num_vertices());
        write_file(out, CONDITIONING_MODES, |tmp| {
            std::fs::write(tmp, csv).map_err(anyhow::Error::from)
        })?;
    }
    let d = balloon_design::vertex_distances(&result.check.positions, target_x);
    let csv: String = std::iter::once("vertex,distance_m\n".to_string())
        .chain(d.iter().enumerate().map(|(i, v)| format!("{i},{v:e}\n")))
        .collect();
    write_file(out, "distance.csv", |tmp| {
        std::fs::write(tmp, csv).map_err(anyhow::Error::from)
    })?;
    let caption = format!(
        "{} at {} Pa{}",
        if result.inverse.converged {
            "design inflated"
        } else {
            "best design so far inflated"
        },
        balloon_render::format_tick(pressure),
        if result.inverse.converged {
            ""
        } else {
            " (not converged)"
        },
    );
    let path = out.join(PICTURE);
    let written = design_picture(
        target_x,
        &result.check.positions,
        &target.triangles,
        &caption,
    )
    .and_then(|img| img.write_png(&path));
    Ok(match written {
        Ok(()) => Some(PICTURE.to_string()),
        Err(e) => {
            eprintln!("warning: `{}` not written: {e}", path.display());
            None
        }
    })
}

/// File name of the rest shape with the fitted wall thickness (a `thickness` face property).
pub const FITTED_REST: &str = "rest.ply";

/// File name of the design's summary.
pub const SUMMARY: &str = "summary.json";

/// Every file a design writes into its output folder: the only ones `overwrite` replaces.
pub const DESIGN_FILES: &[&str] = &[
    "rest.obj",
    FITTED_REST,
    "inflated.obj",
    "distance.csv",
    PICTURE,
    CONDITIONING_MODES,
    SUMMARY,
];

/// Writes `name` in `out` through a temporary file `.NAME.tmp` and a rename, so an earlier
/// file of that name stays whole until the new one is.
fn write_file(out: &Path, name: &str, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    crate::output::write_via_tmp(&out.join(name), &out.join(format!(".{name}.tmp")), write)
}

/// The area (m^2) of each triangle of the flat positions `x`.
fn triangle_areas(x: &[f64], triangles: &[[usize; 3]]) -> Vec<f64> {
    let p = |v: usize| nalgebra::Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
    triangles
        .iter()
        .map(|t| (p(t[1]) - p(t[0])).cross(&(p(t[2]) - p(t[0]))).norm() / 2.0)
        .collect()
}

/// File name of the conditioning report's singular vectors (`--conditioning`): a CSV with one
/// row per vertex, `vertex,mode_1_x,mode_1_y,mode_1_z,mode_2_x,...` (unit vectors over all
/// vertices, in the order of the summary's `conditioning.smallest`).
pub const CONDITIONING_MODES: &str = "conditioning_modes.csv";

/// [`CONDITIONING_MODES`]'s text for the flat vectors `modes` over `vertices` vertices.
fn modes_csv(modes: &[Vec<f64>], vertices: usize) -> String {
    let mut csv = String::from("vertex");
    for k in 1..=modes.len() {
        for axis in ["x", "y", "z"] {
            let _ = write!(csv, ",mode_{k}_{axis}");
        }
    }
    csv.push('\n');
    for v in 0..vertices {
        let _ = write!(csv, "{v}");
        for u in modes {
            for c in &u[3 * v..3 * v + 3] {
                let _ = write!(csv, ",{c:e}");
            }
        }
        csv.push('\n');
    }
    csv
}

/// File name of the design's picture in the output folder.
pub const PICTURE: &str = "design.png";

/// Size of one panel of [`design_picture`], pixels (width, height).
pub const PICTURE_PANEL: (u32, u32) = (480, 400);

/// Colour of the captions.
const INK: [u8; 3] = [20, 20, 24];

/// Height of the caption strip above the panels of [`design_picture`], pixels.
pub const PICTURE_CAPTION_HEIGHT: u32 = 2 * balloon_render::font::GLYPH_HEIGHT + 16;

/// The picture of a design (`design.png`): the target `target` on the left and the forward
/// check's equilibrium `result` (same connectivity, rigidly aligned onto the target) on the
/// right, each [`PICTURE_PANEL`] pixels under a [`PICTURE_CAPTION_HEIGHT`] caption strip
/// (`target`; `caption`). Both are drawn from the same camera (y up, from the front-left,
/// slightly above) and the same framing (the union of both shapes), so what moved between the
/// panels moved in space, and both are coloured on one scale, with its legend in each panel, by
/// the distance of each vertex of the check to the same vertex of the target, `|x_v - x*_v|` in
/// m (the `distance.csv` of the output folder; the summary's max and RMS are over these).
///
/// # Errors
/// Positions with no finite vertex, `target` and `result` of different lengths (one distance
/// per vertex is needed), triangles out of range. Vertices with a non-finite coordinate (a
/// check that blew up) are left out of the framing and their triangles are not drawn.
pub fn design_picture(
    target: &[f64],
    result: &[f64],
    triangles: &[[usize; 3]],
    caption: &str,
) -> Result<Image, RenderError> {
    let d = balloon_design::vertex_distances(result, target);
    let framing = Framing::of_points(target)
        .into_iter()
        .chain(Framing::of_points(result))
        .reduce(|a, b| a.union(&b))
        .ok_or(RenderError::NothingToFrame)?;
    let dmax = d
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let opts = RenderOptions {
        camera: Camera {
            azimuth_deg: 30.0,
            elevation_deg: 20.0,
            up: UpAxis::Y,
            projection: Projection::Perspective { fov_y_deg: 30.0 },
        },
        color_scale: Some(ColorScale::new(0.0, dmax, "distance (m)")),
        ..RenderOptions::new(PICTURE_PANEL.0, PICTURE_PANEL.1)
    };
    let (pw, ph) = PICTURE_PANEL;
    let mut picture = Image::new(2 * pw, ph + PICTURE_CAPTION_HEIGHT, opts.background)?;
    let mut renderer = Renderer::new();
    for (k, (x, text)) in [(target, "target"), (result, caption)]
        .into_iter()
        .enumerate()
    {
        let panel = renderer.render(
            &Surface::new(x, triangles).with_scalars(&d),
            &opts,
            Some(&framing),
        )?;
        let x0 = k * pw as usize;
        let (src, row) = (panel.pixels(), 3 * pw as usize);
        let width = 3 * 2 * pw as usize;
        let dst = picture.pixels_mut();
        for y in 0..ph as usize {
            let at = (y + PICTURE_CAPTION_HEIGHT as usize) * width + 3 * x0;
            dst[at..at + row].copy_from_slice(&src[y * row..(y + 1) * row]);
        }
        let scale = if balloon_render::font::text_width(text, 2) + 16 <= pw {
            2
        } else {
            1
        };
        balloon_render::font::draw_text(&mut picture, x0 as i64 + 8, 8, text, scale, INK);
    }
    Ok(picture)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fraction of the pixels of the two panels (below the captions) that differ by more than
    /// 8 levels in a channel.
    pub fn panels_differ(img: &Image) -> f64 {
        let (pw, ph) = PICTURE_PANEL;
        let mut differ = 0usize;
        for y in PICTURE_CAPTION_HEIGHT..PICTURE_CAPTION_HEIGHT + ph {
            for x in 0..pw {
                let (a, b) = (img.get(x, y).unwrap(), img.get(x + pw, y).unwrap());
                differ += usize::from(a.iter().zip(&b).any(|(p, q)| p.abs_diff(*q) > 8));
            }
        }
        differ as f64 / (pw * ph) as f64
    }

    #[test]
    fn the_panels_share_camera_and_colours_and_differ_where_the_shapes_do() {
        let target = balloon::mesh::generate::icosphere(0.1, 2).unwrap();
        let x = target.positions_flat();
        let t = &target.triangles;
        // The same shape: the panels are the same picture (one camera, one framing, one scale).
        let same = design_picture(&x, &x, t, "check").unwrap();
        assert_eq!(
            (same.width(), same.height()),
            (
                2 * PICTURE_PANEL.0,
                PICTURE_PANEL.1 + PICTURE_CAPTION_HEIGHT
            )
        );
        assert_eq!(panels_differ(&same), 0.0);
        // The upper half (y > 0) pushed out by 10 %: the panels differ, but not at the bottom
        // of the picture (up is +y), where both show the unmoved lower half.
        let bulged: Vec<f64> = x
            .chunks(3)
            .flat_map(|p| {
                let f = if p[1] > 0.0 { 1.1 } else { 1.0 };
                [p[0] * f, p[1] * f, p[2] * f]
            })
            .collect();
        let img = design_picture(&x, &bulged, t, "check").unwrap();
        assert!(panels_differ(&img) > 0.02, "{}", panels_differ(&img));
        let (pw, ph) = PICTURE_PANEL;
        let row_differs = |y: u32| {
            (0..pw).any(|x| {
                let (a, b) = (img.get(x, y).unwrap(), img.get(x + pw, y).unwrap());
                a.iter().zip(&b).any(|(p, q)| p.abs_diff(*q) > 8)
            })
        };
        // The bottom fifth of the panels shows only the unmoved lower half.
        let bottom = PICTURE_CAPTION_HEIGHT + ph - ph / 5;
        assert!((bottom..PICTURE_CAPTION_HEIGHT + ph).all(|y| !row_differs(y)));
        assert!((PICTURE_CAPTION_HEIGHT..bottom).any(row_differs));
        // A result with no finite vertex cannot be drawn.
        let lost = vec![f64::NAN; x.len()];
        assert!(design_picture(&lost, &lost, t, "check").is_err());
    }
}
