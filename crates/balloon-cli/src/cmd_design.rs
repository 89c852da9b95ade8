//! `balloon design TARGET --pressure P [material and wall flags] --out DIR`: the rest shape
//! whose static equilibrium under the gauge pressure P is the target (inverse statics,
//! `docs/design.md`), checked by a forward static solve.
//!
//! Writes `DIR/rest.obj` (the designed rest shape), `DIR/inflated.obj` (the forward check's
//! equilibrium, rigidly aligned onto the target), `DIR/distance.csv` (per-vertex distance of
//! the check to the target, m), `DIR/design.png` (target and check side by side, coloured by
//! that distance) and `DIR/summary.json` (iterations, distance in m and over the bounding-box
//! diagonal, pressure, volumes, times). Ctrl-C stops the design and keeps the best
//! rest shape so far (then checked and written, and the process exits with 130).
//!
//! The forward check keeps a three-prism wall at its rest thickness; the summary prints (and
//! records as `check_command`) the `balloon inflate ... --volume-projection off` command that
//! repeats it from `rest.obj` (`docs/design.md`, "Repeating the check").

use anyhow::{Context, Result, bail};
use balloon_design::{DesignParams, FallbackMode, FallbackParams, InverseParams};
use balloon_mesh::TriMesh;
use balloon_run::jobs::design::{DesignJob, DesignRun};
use balloon_scenario::design::{OptionError, OptionValue, set_design_option};
use std::path::PathBuf;

use crate::material_args::MaterialArgs;
use crate::params::real;
use balloon_scenario::range::End;

/// The flags of `balloon design`.
#[derive(Debug, clap::Args)]
#[command(group = clap::ArgGroup::new("load").required(true).args(["pressure", "gas_amount"]))]
pub struct DesignArgs {
    /// The target inflated shape: a closed, outward-oriented mesh file (.obj, .off, .ply, .stl)
    /// or `builtin[:NAME]`.
    pub target: String,
    /// Gauge pressure the balloon holds at the target shape, Pa (> 0).
    #[arg(long, value_parser = real(End::Open(0.0), End::Closed(1e9)))]
    pub pressure: Option<f64>,
    /// The load as an amount of isothermal ideal gas instead of a pressure: nRT = p_abs V, in
    /// J (Pa m^3); its gauge pressure at the target is gas_amount / V - ambient, which must be
    /// positive. The forward check and the shape optimisation solve with the gas.
    #[arg(long, value_parser = real(End::Open(0.0), End::Closed(1e12)))]
    pub gas_amount: Option<f64>,
    /// Ambient pressure of --gas-amount, Pa (> 0) [default: 101325].
    #[arg(long, value_parser = real(End::Open(0.0), End::Closed(1e7)))]
    pub ambient: Option<f64>,
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
    /// When the shape optimisation runs after the inverse solve: `unconverged` (when the
    /// inverse has no exact answer: it minimises the distance of the forward equilibrium to
    /// the target, docs/design.md), `always`, or `off`.
    #[arg(long, default_value = "unconverged", value_parser = parse_fallback)]
    pub fallback: FallbackMode,
    /// Steps allowed to the shape optimisation (each one forward static solve or more), 1 to
    /// 100000.
    #[arg(long, default_value_t = FallbackParams::default().max_iterations,
          value_parser = parse_steps)]
    pub fallback_iterations: usize,
    /// Accept a design whose inverse has no exact answer when its forward check lies within
    /// this fraction of the target's bounding-box diagonal, in [0, 1]: the design then ends
    /// without the error (0: only an exact design; docs/design.md).
    #[arg(long, default_value = "0", value_parser = option_parser("accept_distance"))]
    pub accept_distance: OptionValue,
    /// The shape optimisation's outer loop: `gauss-newton` (Levenberg-Marquardt-damped
    /// Gauss-Newton on the exact sensitivity) or `lbfgs` (docs/design.md D15, D13).
    #[arg(long, default_value = "gauss-newton", value_parser = option_parser("method"))]
    pub method: OptionValue,
    /// Weight gamma_0 of the rest-mesh shape term in the shape optimisation, in [0, 1e6]
    /// (0: off; docs/design.md D16).
    #[arg(long, default_value = "0", value_parser = option_parser("shape_weight"))]
    pub shape_weight: OptionValue,
    /// Stages of the shape optimisation with the shape term (weights gamma_0 0.1^k), 1 to 20.
    #[arg(long, default_value = "3", value_parser = option_parser("shape_stages"))]
    pub shape_stages: OptionValue,
    /// Weight kappa_0 of the rest-mesh bending term (dihedral angles against the target's) in
    /// the shape optimisation, in [0, 1e6] (0: off; stages as --shape-stages; docs/design.md
    /// D17).
    #[arg(long, default_value = "0", value_parser = option_parser("bending_weight"))]
    pub bending_weight: OptionValue,
    /// Weight of the rest-mesh bending term in the inverse solve's continuation, in [0, 1e6]
    /// (0: off; docs/design.md D17).
    #[arg(long, default_value = "0", value_parser = option_parser("inverse_bending_weight"))]
    pub inverse_bending_weight: OptionValue,
    /// Stages of the inverse solve with the bending term, 1 to 20.
    #[arg(long, default_value = "3", value_parser = option_parser("inverse_bending_stages"))]
    pub inverse_bending_stages: OptionValue,
    /// Bending stiffness of the wall, as a factor on that of a plate of its material and
    /// thickness, `Y h^3 / (12 (1 - nu^2))`, in [0, 1e6], as `balloon inflate --bending`: the
    /// design's equations, its check and the shape optimisation use that wall. 0 (the
    /// default): none, the wall of Wang et al. 2015 (docs/design.md D20).
    #[arg(long, default_value = "0", allow_hyphen_values = true,
          value_parser = option_parser("bending"))]
    pub bending: OptionValue,
    /// Hand the optimised rest shape to the inverse's Newton solve at the full pressure and keep
    /// its answer when it converges closer to the target.
    #[arg(long)]
    pub newton_polish: bool,
    /// Start each forward solve of the shape optimisation and of the thickness fit from the last
    /// equilibrium (faster; where the forward problem has several equilibria the check, which
    /// solves from the rest shape, may differ, docs/design.md).
    #[arg(long)]
    pub warm_start: bool,
    /// Keep this rest shape instead of designing one (a mould one has; read with --scale, with
    /// the target's vertices and triangles): it is checked, and with --fit-thickness its wall
    /// is fitted.
    #[arg(long)]
    pub rest: Option<String>,
    /// After the rest shape, fit the wall's rest thickness per face to the target with that
    /// rest shape fixed (docs/design.md D18); writes rest.ply with the fitted `thickness` as a
    /// face property, which `balloon inflate rest.ply` reads.
    #[arg(long)]
    pub fit_thickness: bool,
    /// Smallest thickness the fit may give a face, m, in (0, 1] [default: a quarter of
    /// --thickness].
    #[arg(long, value_parser = option_parser("thickness_min"))]
    pub thickness_min: Option<OptionValue>,
    /// Largest thickness the fit may give a face, m, in (0, 1] [default: four times
    /// --thickness].
    #[arg(long, value_parser = option_parser("thickness_max"))]
    pub thickness_max: Option<OptionValue>,
    /// Steps allowed to the thickness fit (each one forward static solve or more), 1 to 100000.
    #[arg(long, default_value = "40", value_parser = option_parser("thickness_iterations"))]
    pub thickness_iterations: OptionValue,
    /// After the check, compute the smallest singular values of the inverse's Jacobian at the
    /// rest shape (how well the target determines the rest shape, docs/design.md D19): printed
    /// and written to summary.json as `conditioning`.
    #[arg(long)]
    pub conditioning: bool,
    /// Singular values the conditioning report seeks, 1 to 64.
    #[arg(long, default_value = "6", value_parser = option_parser("conditioning_modes"))]
    pub conditioning_modes: OptionValue,
    /// Block inverse iterations of the conditioning report, 1 to 1000.
    #[arg(long, default_value = "30", value_parser = option_parser("conditioning_iterations"))]
    pub conditioning_iterations: OptionValue,
    /// Output folder: rest.obj, inflated.obj, distance.csv, design.png (target and check side
    /// by side, coloured by the distance), summary.json, rest.ply with --fit-thickness and
    /// conditioning_modes.csv with --conditioning (created; a folder holding any of these is
    /// refused before the design starts, unless --overwrite).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the files of an earlier design in --out (only the files named under --out;
    /// nothing else in the folder is touched).
    #[arg(long)]
    pub overwrite: bool,
    /// Print no progress.
    #[arg(long)]
    pub quiet: bool,
}

/// A value parser for the flag of the design option `key`: the value read as a number where it
/// is one, else as text, and checked by the one function that sets the option
/// ([`set_design_option`], as a scenario's `[design]` table and Python are).
fn option_parser(key: &'static str) -> impl Fn(&str) -> Result<OptionValue, String> + Clone {
    move |s: &str| {
        let number = s.trim().parse::<f64>().ok().map(OptionValue::Number);
        let mut why = "";
        for value in number.into_iter().chain([OptionValue::Text(s.to_owned())]) {
            match set_design_option(&mut DesignParams::default(), key, &value) {
                Ok(_) => return Ok(value),
                Err(OptionError::Expected(kind)) => why = kind,
                Err(OptionError::Invalid(kind)) => {
                    why = kind;
                    break;
                }
            }
        }
        Err(format!("`{s}` is not {}", allowed(why)))
    }
}

/// "in (0, 1)" as "in (0, 1)", "a number" as "a number", a list of words as "one of ...".
fn allowed(kind: &str) -> String {
    if kind.starts_with('"') {
        format!("one of {kind}")
    } else {
        kind.to_owned()
    }
}

/// The job's parameters: the library's defaults with the flags set.
fn params(args: &DesignArgs) -> DesignParams {
    let mut p = DesignParams::default();
    p.inverse.tolerance = args.tolerance;
    p.inverse.tangential_weight = args.tangential_weight;
    p.fallback.mode = args.fallback;
    p.fallback.max_iterations = args.fallback_iterations;
    p.fallback.newton_polish = args.newton_polish;
    p.fallback.warm_start = args.warm_start;
    p.thickness.warm_start = args.warm_start;
    p.thickness.enabled = args.fit_thickness;
    p.conditioning.enabled = args.conditioning;
    for (key, value) in [
        ("thickness_min", &args.thickness_min),
        ("thickness_max", &args.thickness_max),
    ] {
        if let Some(value) = value {
            // Checked by the flag's value parser with the same function.
            let _ = set_design_option(&mut p, key, value);
        }
    }
    for (key, value) in [
        ("thickness_iterations", &args.thickness_iterations),
        ("accept_distance", &args.accept_distance),
        ("conditioning_modes", &args.conditioning_modes),
        ("conditioning_iterations", &args.conditioning_iterations),
        ("method", &args.method),
        ("shape_weight", &args.shape_weight),
        ("shape_stages", &args.shape_stages),
        ("bending_weight", &args.bending_weight),
        ("inverse_bending_weight", &args.inverse_bending_weight),
        ("inverse_bending_stages", &args.inverse_bending_stages),
        ("bending", &args.bending),
    ] {
        // Checked by the flag's value parser with the same function.
        let _ = set_design_option(&mut p, key, value);
    }
    p
}

/// `--fallback`'s value.
fn parse_fallback(s: &str) -> Result<FallbackMode, String> {
    s.parse()
}

/// `--fallback-iterations`' value: a whole number in 1..=100000.
fn parse_steps(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) if (1..=100_000).contains(&n) => Ok(n),
        _ => Err(format!("`{s}` is not a whole number from 1 to 100000")),
    }
}

/// The target mesh `spec` scaled by `scale`.
///
/// # Errors
/// A mesh that cannot be loaded.
pub fn load_target(spec: &str, scale: f64) -> Result<TriMesh> {
    let mut mesh =
        balloon_mesh::load(spec).with_context(|| format!("cannot load mesh `{spec}`"))?;
    if scale != 1.0 {
        mesh.scale(scale);
    }
    Ok(mesh)
}

/// The rest shape `spec` to keep (`--rest`, a scenario's `rest`), scaled by `scale`.
///
/// # Errors
/// A mesh that cannot be loaded.
pub fn load_rest(spec: &str, scale: f64) -> Result<TriMesh> {
    let mut mesh =
        balloon_mesh::load(spec).with_context(|| format!("cannot load rest shape `{spec}`"))?;
    if scale != 1.0 {
        mesh.scale(scale);
    }
    Ok(mesh)
}

/// Runs `balloon design`.
///
/// # Errors
/// A target that cannot be read or is not closed, invalid material flags, a failed design or
/// forward check, an output folder that cannot be written; an interruption after the records
/// are written.
pub fn run(args: &DesignArgs) -> Result<()> {
    if args.ambient.is_some() && args.gas_amount.is_none() {
        bail!("--ambient is the ambient pressure of --gas-amount, which is not given");
    }
    let job = DesignJob {
        target: load_target(&args.target, args.scale)?,
        target_name: args.target.clone(),
        pressure: args.pressure.unwrap_or(f64::NAN),
        gas_amount: args.gas_amount,
        ambient: args
            .ambient
            .unwrap_or(balloon_run::jobs::design::DEFAULT_AMBIENT),
        thickness: args.thickness,
        material: args.material.spec(),
        params: params(args),
        rest: args
            .rest
            .as_deref()
            .map(|r| load_rest(r, args.scale))
            .transpose()?,
        out: Some(args.out.clone()),
        overwrite: args.overwrite,
        quiet: args.quiet,
    };
    report(&job, &balloon_run::jobs::design::run(&job)?)
}

/// Why the shape optimisation stopped, in words.
fn stop_reason(stop: balloon_design::FallbackStop) -> &'static str {
    use balloon_design::FallbackStop::*;
    match stop {
        Distance => "on the target",
        Gradient => "a local minimum of the distance",
        Iterations => "the step limit",
        LineSearch => "no step reduced the distance further",
        Interrupted => "interrupted",
        NoEquilibrium => "no forward equilibrium",
    }
}

/// "N steps (M forward solves, stopped: why), forward distance max a -> b m (of the
/// diagonal), RMS a -> b m (of the diagonal)": a descent of the shape optimisation or the
/// thickness fit, from its record; `None` when it has no start or end (it did not run).
fn descent(
    steps: usize,
    forward_solves: usize,
    stopped: balloon_design::FallbackStop,
    start: Option<balloon_design::Distance>,
    end: Option<balloon_design::Distance>,
) -> Option<String> {
    let (a, b) = (start?, end?);
    Some(format!(
        "{steps} steps ({forward_solves} forward solves, stopped: {}), forward distance max \
         {:.3e} m -> {:.3e} m ({:.3e} of the diagonal), RMS {:.3e} m -> {:.3e} m ({:.3e} of the \
         diagonal)",
        stop_reason(stopped),
        a.max,
        b.max,
        b.max_relative,
        a.rms,
        b.rms,
        b.rms_relative
    ))
}

/// The printed line of a [`balloon_design::RestConditioning`]: the smallest singular values of
/// `dr/dX` outside the rigid motions, relative to the largest, and how much of them is normal
/// to the rest surface.
fn conditioning_line(c: &balloon_design::RestConditioning) -> String {
    let list = |v: &[f64], f: &dyn Fn(f64) -> String| {
        v.iter().map(|x| f(*x)).collect::<Vec<_>>().join(", ")
    };
    format!(
        "rest-shape conditioning: the {} smallest singular values of dr/dX outside the rigid \
         motions are at most {} N/m, {} of the largest ({:.3e} N/m); normal to the rest surface: {}; \
         the inflated shape moves by {} of a rest change along them ({:.1} s). Small values \
         are rest changes the target hardly determines (docs/design.md D19).",
        c.smallest.len(),
        list(&c.smallest, &|x| format!("{x:.2e}")),
        list(&c.relative, &|x| format!("{x:.1e}")),
        c.largest,
        list(&c.normal_fraction, &|x| format!("{:.0} %", 100.0 * x)),
        c.forward_gain.as_deref().map_or_else(
            || "(no forward equilibrium)".to_string(),
            |g| list(g, &|x| format!("{x:.1e}"))
        ),
        c.seconds
    )
}

/// Prints a design's summary line and the command that repeats its check; an interruption or
/// an unconverged design as the error (after the outputs are written).
///
/// # Errors
/// As described.
pub fn report(job: &DesignJob, run: &DesignRun) -> Result<()> {
    let result = &run.design;
    let dist = &result.check.distance;
    println!(
        "design {}: {} inverse iterations, forward check {} (max distance {:.3e} m = {:.3e} of the \
         diagonal, RMS {:.3e} m, volume {:.4e} m^3){}",
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
        job.out
            .as_ref()
            .map(|o| format!("; written to {}", o.display()))
            .unwrap_or_default(),
    );
    if let Some(f) = &result.inverse.fallback {
        match descent(f.iterations, f.forward_solves, f.stopped, f.start, f.end) {
            Some(line) => println!("shape optimisation: {line}"),
            None => println!(
                "shape optimisation: not run, the best inverse design has no forward equilibrium"
            ),
        }
    }
    if job.rest.is_some() {
        println!(
            "rest shape given and kept: relative equilibrium residual {:.3e} at the target with \
             the wall given, {} the design tolerance {:e}",
            result.inverse.relative_residual,
            if result.inverse.converged {
                "within"
            } else {
                "above"
            },
            job.params.inverse.tolerance
        );
    }
    if let Some(fit) = &run.summary.thickness_fit {
        let f = &fit.info;
        match descent(f.iterations, f.forward_solves, f.stopped, f.start, f.end) {
            Some(line) => println!(
                "thickness fit: {line}; thickness {:.3e} to {:.3e} m (mean {:.3e} m, bounds \
                 {:.3e} to {:.3e} m, {} faces at a bound)",
                fit.min, fit.max, fit.mean, f.lower, f.upper, f.at_bounds
            ),
            None => println!("thickness fit: not run, the rest shape has no forward equilibrium"),
        }
    }
    if let Some(c) = &run.design.conditioning {
        println!("{}", conditioning_line(c));
    }
    if let Some(command) = &run.summary.check_command {
        println!("repeat the check: {command}");
    }
    if let Some(signal) = run.interrupted {
        return Err(balloon_run::interrupt::Interrupted {
            signal,
            steps: result.inverse.iterations
                + result.inverse.fallback.as_ref().map_or(0, |f| f.iterations)
                + result.thickness.as_ref().map_or(0, |f| f.info.iterations),
        }
        .into());
    }
    if job.rest.is_some() {
        // A given rest shape is checked, not designed: the residual and distances above say
        // how well it holds the target; only a failed check is an error.
        if !result.check.converged {
            bail!("the forward check from the given rest shape did not converge");
        }
        return Ok(());
    }
    if !result.inverse.converged && run.summary.accepted {
        println!(
            "design accepted: no rest shape holds the target exactly (the inverse reached {} \
             of the load), and the design's forward equilibrium lies within {:.3e} of the \
             diagonal, inside `accept_distance` = {:e}",
            load_fraction(result.inverse.load_reached),
            dist.max_relative,
            job.params.accept_distance
        );
        return Ok(());
    }
    if !result.inverse.converged {
        bail!(
            "no rest shape holds the target exactly at {} (the inverse reached {} of it, \
             relative residual {:.3e}{}); the best design so far is written{}: its forward \
             equilibrium lies within {:.3e} m of the target ({:.3e} of the diagonal, RMS \
             {:.3e} m){}",
            match job.gas_amount {
                None => format!("`pressure` = {} Pa", run.summary.pressure),
                Some(a) => format!(
                    "`gas_amount` = {a} J (a gauge pressure of {} Pa at the target)",
                    run.summary.pressure
                ),
            },
            load_fraction(result.inverse.load_reached),
            result.inverse.relative_residual,
            if result.inverse.full_attempt_kept {
                " at the full pressure, where its best attempt ended nearer equilibrium than the \
                 last converged stage"
            } else {
                ""
            },
            if result.inverse.fallback.is_some() {
                ", the shape optimisation's"
            } else {
                ""
            },
            dist.max,
            dist.max_relative,
            dist.rms,
            if job.params.accept_distance > 0.0 {
                format!(
                    ", outside `accept_distance` = {:e}",
                    job.params.accept_distance
                )
            } else {
                "; `accept_distance` accepts a design within a given fraction of the diagonal"
                    .to_owned()
            }
        );
    }
    Ok(())
}

/// The load factor the inverse reached, with the digits that keep a factor short of 1 from
/// reading as 1 (0.999756, not 1.000).
fn load_fraction(reached: f64) -> String {
    if reached < 1.0 && format!("{reached:.3}") == "1.000" {
        format!("{reached:.6}")
    } else {
        format!("{reached:.3}")
    }
}

#[cfg(test)]
mod tests {
    use super::load_fraction;

    #[test]
    fn a_load_factor_short_of_one_does_not_read_as_one() {
        assert_eq!(load_fraction(0.999755859375), "0.999756");
        assert_eq!(load_fraction(0.984375), "0.984");
        assert_eq!(load_fraction(1.0), "1.000");
        assert_eq!(load_fraction(0.0), "0.000");
    }
}
