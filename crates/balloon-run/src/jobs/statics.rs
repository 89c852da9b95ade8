//! The static solve of a shell scenario (`static`): the rest shape solved directly
//! (`ShellSimulation::solve_static`), for one load or along a volume continuation (`gas` =
//! volume, `volume_ratios`), whose pressure-volume curve is drawn into `pressure_volume.png`
//! of the output folder.

use super::shell_frame::shell_frame;
use crate::output::{OutputDir, print_json_line};
use anyhow::{Context, Result};
use balloon::integrate::PhaseTimes;
use balloon::shell::ShellMaterial;
use balloon::shell::ShellSimulation;
use balloon::shell::statics::{StabilityReport, StaticControl, StaticReport};
use balloon_scenario::shell::ShellScenario;
use serde::Serialize;
use std::io::Write;

/// One line of `stats.jsonl` per static point.
#[derive(Debug, Serialize)]
struct StaticPoint {
    /// Point index (0-based).
    point: usize,
    /// Target volume over the rest volume (volume control), else null.
    volume_ratio: Option<f64>,
    /// Enclosed gas volume, m^3.
    gas_volume: f64,
    /// Gauge pressure, Pa.
    gauge_pressure: f64,
    /// Smallest element area stretch.
    min_area_stretch: f64,
    /// Largest element area stretch.
    max_area_stretch: f64,
    /// Mean thickness, m.
    thickness_mean: f64,
    /// Smallest thickness, m.
    thickness_min: f64,
    /// Largest thickness, m.
    thickness_max: f64,
    /// Whether the point converged.
    converged: bool,
    /// Relative Newton residual.
    newton_residual: f64,
    /// Newton iterations.
    newton_iterations: usize,
    /// Load-continuation stages.
    load_steps: usize,
    /// Wall-clock ms.
    solve_ms: f64,
    /// Where the point's time went, ms (forces, energies, assembly, factorisations, solves,
    /// projections).
    times: PhaseTimes,
    /// With `stability`: the smallest eigenvalue of the equilibrium's stiffness.
    #[serde(skip_serializing_if = "Option::is_none")]
    stability: Option<StabilityReport>,
}

impl StaticPoint {
    fn new(point: usize, volume_ratio: Option<f64>, r: &StaticReport) -> Self {
        Self {
            point,
            volume_ratio,
            gas_volume: r.gas_volume,
            gauge_pressure: r.gauge_pressure,
            min_area_stretch: r.min_area_stretch,
            max_area_stretch: r.max_area_stretch,
            thickness_mean: r.thickness_mean,
            thickness_min: r.thickness_min,
            thickness_max: r.thickness_max,
            converged: r.converged,
            newton_residual: r.relative_residual,
            newton_iterations: r.newton_iterations,
            load_steps: r.load_steps,
            solve_ms: r.solve_ms,
            times: r.times,
            stability: r.stability,
        }
    }
}

/// `summary.json` of a static run.
#[derive(Debug, Default, Serialize)]
struct StaticSummary {
    mesh: String,
    mode: &'static str,
    gas: String,
    vertices: usize,
    triangles: usize,
    /// Points solved (1 without `volume_ratios`).
    points: usize,
    /// Whether every point converged.
    converged: bool,
    /// Relative Newton residual of the last point.
    newton_residual: f64,
    /// Largest relative residual over the points.
    newton_residual_max: f64,
    /// Newton iterations over all points.
    newton_iterations_total: usize,
    /// Load-continuation stages over all points.
    load_steps_total: usize,
    initial_gas_volume: f64,
    final_gas_volume: f64,
    final_gauge_pressure: f64,
    shell_volume_ratio_final: f64,
    final_thickness_mean: f64,
    final_thickness_min: f64,
    final_thickness_max: f64,
    min_area_stretch: f64,
    max_area_stretch: f64,
    /// Wall-clock ms of all solves.
    solve_ms: f64,
    /// Where the solves' time went, ms, summed over the points.
    phase_times_ms: PhaseTimes,
    /// Frame files written (the rest shape included).
    frames: usize,
    /// Stopped by SIGINT / SIGTERM between two points.
    interrupted: bool,
    /// With `stability`: the points whose equilibrium is unstable under the load as held.
    #[serde(skip_serializing_if = "Option::is_none")]
    unstable_points: Option<Vec<usize>>,
    /// What the user should know about a run that converged (printed too).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    warnings: Vec<String>,
    error: Option<String>,
}

/// What a static run found: its summary (the keys of `summary.json`) and one value per
/// converged point (the lines of `stats.jsonl`).
#[derive(Clone, Debug, Default)]
pub struct StaticRun {
    /// The run's summary, as `summary.json` holds it.
    pub summary: serde_json::Value,
    /// One value per converged point, as the `stats.jsonl` lines.
    pub points: Vec<serde_json::Value>,
}

/// Runs the static solve(s) of a shell scenario on the built simulation. `quiet` prints
/// nothing (no summary line or `json` line), for callers that take the returned [`StaticRun`]
/// instead; `record_text` is the resolved scenario the summary repeats.
pub fn run<M: ShellMaterial>(
    args: &ShellScenario,
    sim: &mut ShellSimulation<M>,
    mut out: Option<OutputDir>,
    quiet: bool,
    record_text: Option<&str>,
) -> Result<StaticRun> {
    let ratios = args.static_points().map_err(anyhow::Error::msg)?;
    if ratios.is_empty() {
        // A range whose step underflows (or whose end is not reached) would run "0 points,
        // converged".
        anyhow::bail!(
            "`volume_ratios` gives no point to solve (an empty range, or a step too small to \
             leave its start); give START:END:STEP with a step that reaches END"
        );
    }
    let mut options = args.static_options();
    let mut summary = StaticSummary {
        mesh: args.mesh.path.clone(),
        mode: "static",
        gas: args.gas.model.to_string(),
        vertices: sim.positions().len() / 3,
        triangles: sim.triangles().len(),
        initial_gas_volume: sim.rest_gas_volume(),
        converged: true,
        ..Default::default()
    };
    if let Some(o) = &mut out {
        o.frame(&shell_frame(sim, 0)?, true)?;
        summary.frames += 1;
    }
    let mut failure = None;
    // An output that could not be written (a full disk) ends the run too, after the summary.
    let mut output_error: Option<anyhow::Error> = None;
    let mut interrupted = None;
    // (V / V0, gauge pressure) of every converged point, for the pressure-volume plot.
    let mut curve = Vec::new();
    let mut points = Vec::new();
    // The last converged point when it was unstable (index, smallest eigenvalue).
    let mut last_stability: Option<(usize, f64)> = None;
    for (i, ratio) in ratios.iter().enumerate() {
        if let Some(sig) = crate::interrupt::pending() {
            interrupted = Some(sig);
            break;
        }
        options.control = match ratio {
            Some(r) => StaticControl::Volume {
                target: r * sim.rest_gas_volume(),
            },
            None => StaticControl::Gas,
        };
        let solving = std::time::Instant::now();
        match sim.solve_static(&options) {
            Ok(report) => {
                summary.points += 1;
                summary.newton_residual = report.relative_residual;
                summary.newton_residual_max =
                    summary.newton_residual_max.max(report.relative_residual);
                summary.newton_iterations_total += report.newton_iterations;
                summary.load_steps_total += report.load_steps;
                summary.final_gauge_pressure = report.gauge_pressure;
                summary.min_area_stretch = report.min_area_stretch;
                summary.max_area_stretch = report.max_area_stretch;
                summary.solve_ms += report.solve_ms;
                summary.phase_times_ms += report.times;
                curve.push((
                    report.gas_volume / summary.initial_gas_volume,
                    report.gauge_pressure,
                ));
                last_stability = None;
                if let Some(s) = &report.stability {
                    let unstable = summary.unstable_points.get_or_insert_with(Vec::new);
                    if s.unstable() {
                        unstable.push(i);
                        last_stability = Some((i, s.smallest_eigenvalue));
                    }
                }
                let point = StaticPoint::new(i, *ratio, &report);
                points.push(serde_json::to_value(&point)?);
                if let Some(o) = &mut out {
                    let written = o.append_stats(&point).and_then(|()| {
                        if ratios.len() > 1 {
                            o.frame(&shell_frame(sim, i + 1)?, true)?;
                            summary.frames += 1;
                        }
                        Ok(())
                    });
                    if let Err(e) = written {
                        summary.converged = false;
                        output_error = Some(e);
                        break;
                    }
                }
            }
            Err(e) => {
                summary.converged = false;
                // The iterations the failed point spent count too (its error says how many).
                summary.newton_iterations_total += e.static_newton_iterations().unwrap_or(0);
                summary.solve_ms += solving.elapsed().as_secs_f64() * 1e3;
                // The residual it ended at, not the 0 of a point never solved.
                if let Some(r) = e.static_residual() {
                    summary.newton_residual = r;
                    summary.newton_residual_max = summary.newton_residual_max.max(r);
                }
                // A solve stopped by a signal during its Newton iterations is an interruption
                // (the point is not reached; the state is the last accepted iterate).
                match crate::interrupt::pending() {
                    Some(sig) => interrupted = Some(sig),
                    None => failure = Some(e),
                }
                break;
            }
        }
    }
    let th = sim.thickness();
    summary.final_gas_volume = sim.gas_volume();
    summary.shell_volume_ratio_final = sim.shell_volume() / sim.rest_shell_volume();
    summary.final_thickness_mean = th.iter().sum::<f64>() / th.len() as f64;
    summary.final_thickness_min = th.iter().copied().fold(f64::INFINITY, f64::min);
    summary.final_thickness_max = th.iter().copied().fold(0.0, f64::max);
    let failure = failure.map(|e| {
        let mut message = failure_message(&e, args);
        if let Some((i, lambda)) = last_stability {
            message.push_str(&unstable_before_failure(i, lambda, &ratios));
        }
        message
    });
    summary.error = failure
        .clone()
        .or_else(|| output_error.as_ref().map(|e| format!("{e:#}")));
    summary.interrupted = interrupted.is_some();
    if let Some(unstable) = summary.unstable_points.as_ref().filter(|u| !u.is_empty()) {
        summary.warnings.push(unstable_warning(unstable, &ratios));
    }
    let mut record = serde_json::to_value(&summary)?;
    if let Some(text) = record_text {
        crate::run::insert_scenario(&mut record, text);
    }
    // Everything below is attempted even when a part fails (the summary above all); the first
    // error is kept, later ones are warnings.
    let failed = failure.is_some() || output_error.is_some();
    if let Some(o) = &mut out {
        let mut keep = |r: Result<()>| {
            if let Err(e) = r {
                if output_error.is_none() {
                    output_error = Some(e);
                } else {
                    eprintln!("warning: {e:#}");
                }
            }
        };
        if ratios.len() > 1 && curve.len() > 1 {
            keep(write_pressure_volume_plot(o, &args.mesh.path, &curve));
        }
        let last = shell_frame(sim, summary.points.max(1))?;
        keep(o.write_named_frame("final", &last).map(drop));
        keep(o.write_json("summary.json", &record).map(drop));
        match o.finish(&last, failed) {
            Ok(warnings) => warnings.iter().for_each(|w| eprintln!("warning: {w}")),
            Err(e) if failed => eprintln!("warning: {e:#}"),
            Err(e) => keep(Err(e)),
        }
    }
    if quiet {
    } else if args.output.json {
        print_json_line(&record)?;
    } else {
        let mut w = std::io::stdout().lock();
        // A solve that ends with an error before its first point has nothing to report here
        // (its error says what happened); "0 point(s)" would read as a result.
        let nothing = summary.points == 0 && (failure.is_some() || interrupted.is_some());
        if !nothing {
            writeln!(
                w,
                "static: {} point(s), gas volume {:.4e} -> {:.4e} m^3 (x{:.4}), gauge pressure {:.2} Pa, Newton residual {:.2e} after {} iterations, {:.1} ms{}",
                summary.points,
                summary.initial_gas_volume,
                summary.final_gas_volume,
                summary.final_gas_volume / summary.initial_gas_volume,
                summary.final_gauge_pressure,
                summary.newton_residual,
                summary.newton_iterations_total,
                summary.solve_ms,
                if summary.converged { ", converged" } else { "" }
            )?;
        }
        for warning in &summary.warnings {
            writeln!(w, "warning: {warning}")?;
        }
        if let Some(o) = &out
            && output_error.is_none()
        {
            writeln!(w, "output written to {}", o.path().display())?;
        }
        w.flush()?;
    }
    if let Some(e) = output_error {
        if let Some(f) = &failure {
            eprintln!("warning: {f}");
        }
        return Err(e);
    }
    match failure {
        Some(e) => Err(anyhow::Error::msg(e).context(format!(
            "the static solve of `{}` did not converge (the simulation is left at the last converged point)",
            args.mesh.path
        ))),
        None => match interrupted {
            Some(signal) => Err(crate::interrupt::Interrupted {
                signal,
                steps: summary.points,
            }
            .into()),
            None => Ok(StaticRun {
                summary: record,
                points,
            }),
        },
    }
}

/// The warning for unstable equilibria (`unstable`: their point indices, not empty; `ratios`:
/// the volume ratio of each point under volume control).
fn unstable_warning(unstable: &[usize], ratios: &[Option<f64>]) -> String {
    let at = |i: usize| match ratios.get(i).copied().flatten() {
        Some(r) => format!("point {i} (V/V0 = {r})"),
        None => format!("point {i}"),
    };
    let list = if unstable.len() <= 3 {
        unstable
            .iter()
            .map(|&i| at(i))
            .collect::<Vec<_>>()
            .join(", ")
    } else {
        format!(
            "{} points from {} to {}",
            unstable.len(),
            at(unstable[0]),
            at(unstable[unstable.len() - 1])
        )
    };
    let volume_held = unstable
        .iter()
        .any(|&i| ratios.get(i).copied().flatten().is_some());
    let why = if volume_held {
        "even with the volume held, so the branch followed has met a bifurcation: a real balloon \
         leaves it for another shape (for a sphere, the aspherical inflation of Alexander 1971 and \
         Haughton and Ogden 1978), and this branch is followed only because the mesh keeps its \
         symmetry"
    } else {
        "so a real balloon held at this load leaves this shape (past a pressure maximum, or at a \
         bifurcation); hold the volume (`gas` = volume) to follow a pressure maximum"
    };
    format!(
        "unstable equilibrium at {list}: the smallest eigenvalue of the stiffness is negative \
         (`stability` in stats.jsonl), {why}"
    )
}

/// What a failure after an unstable point adds to its message: the solve most likely stalled at
/// a bifurcation of the branch it followed.
fn unstable_before_failure(i: usize, lambda: f64, ratios: &[Option<f64>]) -> String {
    let at = match ratios.get(i).copied().flatten() {
        Some(r) => format!("point {i}, V/V0 = {r}"),
        None => format!("point {i}"),
    };
    format!(
        "; the last converged point ({at}) is unstable (smallest eigenvalue of the stiffness \
         {lambda:.3e} 1/s^2): the branch followed has passed a bifurcation or a limit point, \
         where a static solve can stall (docs/membranes.md, section 9)"
    )
}

/// The message of a failed static solve, with the hints that fit the scenario: no
/// `tangent` = projected when it was the tangent used, and, under a pressure (not volume)
/// control, that the pressure may exceed the largest the balloon can hold (rubber's pressure
/// has a maximum, the limit point, above which no equilibrium exists), with the volume
/// control that passes it.
fn failure_message(e: &balloon::shell::ShellError, args: &ShellScenario) -> String {
    use balloon::integrate::TangentKind;
    use balloon::shell::ShellError;
    use balloon_scenario::gas::GasControl;
    let limit_hint = (args.gas.model != GasControl::Volume).then(|| {
        let pressure = match args.gas.model {
            GasControl::Constant | GasControl::Ideal | GasControl::Polytropic => {
                format!("the gauge pressure {} Pa", args.gas.pressure)
            }
            _ => "the load".to_owned(),
        };
        format!(
            "{pressure} may exceed the largest the balloon can hold (a rubber balloon's pressure \
             has a maximum, the limit point): above it no equilibrium exists at that pressure, \
             whatever the solver settings; solve under volume control instead (`gas` = volume \
             with `volume_ratio` R, or `volume_ratios` START:END:STEP to trace the pressure \
             through its maximum), or give a smaller pressure"
        )
    });
    match e {
        // A stall is its own evidence (where the residual sits, the smallest eigenvalue): the
        // wall wrinkles or buckles along the load path, under any material, so the rubber
        // limit-point hint does not apply.
        ShellError::Static { outer, source, .. }
            if matches!(
                **source,
                balloon::integrate::statics::StaticError::NoEquilibrium(_)
            ) =>
        {
            format!(
                "static solve (outer iteration {outer}): {source}; the dynamic run \
                 (`until_converged`) follows such a wall through its wrinkling or buckling in \
                 time, where the static solve finds no smooth path"
            )
        }
        ShellError::Static { outer, source, .. } => {
            let mut tries = vec!["a looser `newton_tol`"];
            if args.run.tangent != TangentKind::Projected {
                tries.push("`tangent` = projected");
            }
            tries.push("the dynamic run (`until_converged`)");
            let tries = format!(
                "{} or {}",
                tries[..tries.len() - 1].join(", "),
                tries[tries.len() - 1]
            );
            match limit_hint {
                Some(hint) => format!(
                    "static solve (outer iteration {outer}): {source}; {hint}. If it is below \
                     that maximum, try {tries}"
                ),
                None => format!("static solve (outer iteration {outer}): {source}; try {tries}"),
            }
        }
        ShellError::StaticNotConverged { .. } => match limit_hint {
            Some(hint) => format!("{e}; {hint}"),
            None => e.to_string(),
        },
        e => e.to_string(),
    }
}

/// Writes `pressure_volume.png` into the output folder: the gauge pressure over the volume
/// ratio of a `volume_ratios` continuation (one marker per converged point).
fn write_pressure_volume_plot(out: &OutputDir, mesh: &str, curve: &[(f64, f64)]) -> Result<()> {
    use balloon_render::plot::{LinePlot, PlotSeries};
    let plot = LinePlot::new(
        format!("pressure-volume curve of {mesh} (volume control)"),
        "gas volume V / V0",
        "gauge pressure (Pa)",
    )
    .with_series(PlotSeries::line_points(
        format!("{} static points", curve.len()),
        curve.to_vec(),
        0,
    ));
    let path = out.path().join("pressure_volume.png");
    plot.render(960, 640)
        .and_then(|img| img.write_png(&path))
        .with_context(|| format!("cannot write {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::unstable_warning;

    /// A stalled static solve is reported with its evidence and the dynamic run, not with the
    /// rubber limit-point hint (a StVK wall has no limit point); a solve that did not converge
    /// keeps the hint.
    #[test]
    fn a_stalled_static_solve_is_not_blamed_on_the_limit_point() {
        use balloon::integrate::newton::Stall;
        use balloon::integrate::statics::StaticError;
        use balloon::shell::ShellError;
        let mut args = balloon_scenario::shell::ShellScenario::default();
        args.gas.model = balloon_scenario::gas::GasControl::Constant;
        args.gas.pressure = 1500.0;
        let stall = Stall {
            iterations: 400,
            residual: 0.2,
            load_factor: 0.0,
            stalled_stages: 3,
            vertex: 17,
            position: [-0.047, -0.006, 0.004],
            share: 0.48,
            smallest_eigenvalue: Some(-3.0e6),
            relative_eigenvalue: Some(-1.1e-3),
        };
        let stalled = ShellError::Static {
            outer: 0,
            newton_iterations: 400,
            source: Box::new(StaticError::NoEquilibrium(Box::new(stall))),
        };
        let m = super::failure_message(&stalled, &args);
        assert!(m.contains("until_converged") && m.contains("-3.0"), "{m}");
        assert!(!m.contains("limit point"), "{m}");
        let unconverged = ShellError::Static {
            outer: 0,
            newton_iterations: 2600,
            source: Box::new(StaticError::NotConverged {
                iterations: 2600,
                residual: 0.28,
                tolerance: 1e-6,
                load_factor: Some(0.5),
            }),
        };
        assert!(super::failure_message(&unconverged, &args).contains("limit point"));
    }

    #[test]
    fn a_failure_after_an_unstable_point_says_so() {
        let m = super::unstable_before_failure(3, -1.021e4, &[None, None, None, Some(12.0)]);
        assert!(
            m.contains("point 3, V/V0 = 12") && m.contains("-1.021e4"),
            "{m}"
        );
        assert!(m.contains("bifurcation"), "{m}");
    }

    #[test]
    fn the_unstable_warning_names_the_points_and_what_to_do() {
        let ratios = [Some(2.0), Some(3.0), Some(4.0), Some(5.0), Some(6.0)];
        let few = unstable_warning(&[1, 2], &ratios);
        assert!(few.contains("point 1 (V/V0 = 3)") && few.contains("point 2 (V/V0 = 4)"));
        assert!(
            few.contains("bifurcation") && few.contains("Alexander 1971"),
            "{few}"
        );
        let pressure = unstable_warning(&[0], &[None]);
        assert!(pressure.contains("`gas` = volume"), "{pressure}");
        let many = unstable_warning(&[1, 2, 3, 4], &ratios);
        assert!(
            many.contains("4 points from point 1 (V/V0 = 3) to point 4 (V/V0 = 6)"),
            "{many}"
        );
        assert!(unstable_warning(&[0], &[None]).contains("at point 0:"));
    }
}
