//! `balloon inflate --static`: the rest shape solved directly (`ShellSimulation::solve_static`),
//! for one load or along a volume continuation (`--gas volume --volume-ratios START:END:STEP`),
//! whose pressure-volume curve is drawn into `pressure_volume.png` of the output folder.

use crate::cmd_inflate::{InflateArgs, shell_frame};
use crate::output::{OutputDir, print_json_line};
use anyhow::{Context, Result, bail};
use balloon::integrate::PhaseTimes;
use balloon::shell::ShellMaterial;
use balloon::shell::ShellSimulation;
use balloon::shell::statics::{StaticControl, StaticOptions, StaticReport};
use serde::Serialize;
use std::io::Write;

/// How the gas is held (`--gas`): the three gas models, or a given volume (static only).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum GasArg {
    /// Ambient air added at --pump-rate from the rest shape (the amount at the current time
    /// for --static).
    Pump,
    /// Isothermal ideal gas, a fixed amount (Eq. 12-14).
    Ideal,
    /// A fixed pressure.
    Constant,
    /// Polytropic (adiabatic) gas, `p V^gamma` constant (--gamma, default 1.4), starting at
    /// --pressure.
    Polytropic,
    /// Ideal gas at --pressure leaking to ambient through --leak-conductance.
    Leak,
    /// A pump at --pump-rate that stops at --supply-pressure.
    SupplyPump,
    /// A given enclosed volume (--static only; --volume-ratio or --volume-ratios): the pressure
    /// is its Lagrange multiplier.
    Volume,
}

impl GasArg {
    /// The gas model the simulation is built with (volume control builds a constant-pressure
    /// gas at --pressure, which the static solve does not use).
    pub fn kind(self) -> balloon::gas::GasKind {
        use balloon::gas::GasKind;
        match self {
            Self::Pump => GasKind::Pump,
            Self::Ideal => GasKind::Ideal,
            Self::Constant | Self::Volume => GasKind::Constant,
            Self::Polytropic => GasKind::Polytropic,
            Self::Leak => GasKind::Leak,
            Self::SupplyPump => GasKind::SupplyPump,
        }
    }
}

impl std::fmt::Display for GasArg {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Pump => "pump",
            Self::Ideal => "ideal",
            Self::Constant => "constant",
            Self::Volume => "volume",
            Self::Polytropic => "polytropic",
            Self::Leak => "leak",
            Self::SupplyPump => "supply-pump",
        })
    }
}

/// The flags of the gas laws beyond the isothermal ones (`balloon_gas::laws`), checked against
/// `--gas` by [`GasLawArgs::params`].
#[derive(Clone, Debug, Default, clap::Args)]
pub struct GasLawArgs {
    /// Polytropic exponent of `--gas polytropic`, `p V^gamma` constant (> 0; 1.4 adiabatic
    /// air, 1 isothermal) [default: 1.4].
    #[arg(long, allow_hyphen_values = true)]
    pub gamma: Option<f64>,
    /// Leak conductance of `--gas leak`, m^3/s (>= 0): the gas content nRT flows out at
    /// C (p - p_ambient) J/s, so a rigid balloon of volume V loses its gauge pressure as
    /// exp(-C t / V).
    #[arg(long, allow_hyphen_values = true)]
    pub leak_conductance: Option<f64>,
    /// Gauge supply pressure of `--gas supply-pump`, Pa (> 0): the pump adds --pump-rate until
    /// the balloon reaches it, then stops.
    #[arg(long, allow_hyphen_values = true)]
    pub supply_pressure: Option<f64>,
}

impl GasLawArgs {
    /// The gas-law parameters for `gas`: each flag only with its gas, the required ones present,
    /// every value in range; an error names the flag and its value.
    pub fn params(&self, gas: GasArg) -> Result<balloon::gas::GasLawParams> {
        let mut law = balloon::gas::GasLawParams::default();
        let flags = [
            ("--gamma", self.gamma, GasArg::Polytropic),
            ("--leak-conductance", self.leak_conductance, GasArg::Leak),
            (
                "--supply-pressure",
                self.supply_pressure,
                GasArg::SupplyPump,
            ),
        ];
        for (flag, value, owner) in flags {
            if let Some(v) = value
                && gas != owner
            {
                bail!("{flag} {v} is a parameter of --gas {owner}, but --gas is {gas}");
            }
        }
        if let Some(g) = self.gamma {
            if !(g.is_finite() && g > 0.0) {
                bail!("invalid --gamma {g}: the polytropic exponent must be positive and finite");
            }
            law.gamma = g;
        }
        match (gas, self.leak_conductance) {
            (GasArg::Leak, None) => bail!("--gas leak needs --leak-conductance C (m^3/s)"),
            (_, Some(c)) if !(c.is_finite() && c >= 0.0) => {
                bail!("invalid --leak-conductance {c}: must be a finite conductance >= 0 m^3/s")
            }
            (_, c) => law.leak_conductance = c,
        }
        match (gas, self.supply_pressure) {
            (GasArg::SupplyPump, None) => {
                bail!("--gas supply-pump needs --supply-pressure P (gauge, Pa)")
            }
            (_, Some(p)) if !(p.is_finite() && p > 0.0) => {
                bail!("invalid --supply-pressure {p}: the gauge supply pressure must be positive")
            }
            (_, p) => law.supply_pressure = p,
        }
        Ok(law)
    }
}

/// `--volume-ratios START:END:STEP`: the volume ratios (to the rest volume) of the points, from
/// START to END inclusive in steps of STEP (either direction).
pub fn parse_volume_ratios(s: &str) -> Result<Vec<f64>, String> {
    let parts: Vec<&str> = s.split(':').collect();
    let bad = || format!("`{s}` is not START:END:STEP with positive ratios and a non-zero step");
    if parts.len() != 3 {
        return Err(bad());
    }
    let v: Vec<f64> = parts
        .iter()
        .map(|p| p.trim().parse::<f64>().map_err(|_| bad()))
        .collect::<Result<_, _>>()?;
    let (start, end, step) = (v[0], v[1], v[2]);
    let finite = [start, end, step].iter().all(|v| v.is_finite());
    if !(finite && start > 0.0 && end > 0.0 && step != 0.0) || (end - start) * step < 0.0 {
        return Err(bad());
    }
    let count = ((end - start) / step + 1e-9).floor() as usize + 1;
    if count > 100_000 {
        return Err(format!("`{s}` asks for {count} points; at most 100000"));
    }
    Ok((0..count).map(|i| start + i as f64 * step).collect())
}

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
    /// Points solved (1 without --volume-ratios).
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

/// Runs the static solve(s) of `balloon inflate --static` on the built simulation. `quiet`
/// prints nothing (no summary line or `--json` line), for callers that take the returned
/// [`StaticRun`] instead; `record_text` is the resolved scenario the summary repeats.
pub fn run<M: ShellMaterial>(
    args: &InflateArgs,
    sim: &mut ShellSimulation<M>,
    mut out: Option<OutputDir>,
    quiet: bool,
    record_text: Option<&str>,
) -> Result<StaticRun> {
    if matches!(args.gas, GasArg::Pump | GasArg::SupplyPump) && sim.time() == 0.0 {
        // The amount of a pump at the start is the rest amount: the equilibrium is the mesh
        // itself, a run that "succeeds" with nothing solved.
        bail!(
            "--static with --gas {} solves at the gas amount at the start, which is the rest \
             amount (no gauge pressure): the rest shape would be the mesh itself. For an inflated \
             rest shape give --gas constant --pressure P (a gauge pressure, Pa), --gas ideal \
             --pressure P (that gauge pressure in the rest volume, then expanding), or --gas volume \
             --volume-ratio R",
            args.gas
        );
    }
    let ratios: Vec<Option<f64>> = match (args.gas, args.volume_ratio, &args.volume_ratios) {
        (GasArg::Volume, Some(r), None) => vec![Some(r)],
        (GasArg::Volume, None, Some(list)) => list.iter().map(|r| Some(*r)).collect(),
        (GasArg::Volume, Some(_), Some(_)) => {
            bail!("give either --volume-ratio or --volume-ratios, not both")
        }
        (GasArg::Volume, None, None) => {
            bail!("--gas volume needs --volume-ratio R or --volume-ratios START:END:STEP")
        }
        (_, None, None) => vec![None],
        _ => bail!("--volume-ratio and --volume-ratios need --gas volume"),
    };
    if let Some(r) = ratios
        .iter()
        .flatten()
        .find(|r| !(r.is_finite() && **r > 0.0))
    {
        bail!("invalid volume ratio {r}: must be positive");
    }
    let mut options = StaticOptions::default();
    if args.newton_tol > 0.0 {
        options.solver.tolerance = args.newton_tol;
    }
    options.solver.tangent = args.tangent;
    options.solver.inexact_forcing = args.inexact_forcing;
    options.solver.solver.linear.kind = args.linear_solver;
    options.solver.solver.linear.max_iterations = args.cg_max_iters;
    options.solver.solver.pcg_preconditioner = args.pcg_preconditioner;
    let mut summary = StaticSummary {
        mesh: args.mesh.clone(),
        mode: "static",
        gas: args.gas.to_string(),
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
    let mut interrupted = None;
    // (V / V0, gauge pressure) of every converged point, for the pressure-volume plot.
    let mut curve = Vec::new();
    let mut points = Vec::new();
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
                let point = StaticPoint::new(i, *ratio, &report);
                points.push(serde_json::to_value(&point)?);
                if let Some(o) = &mut out {
                    o.append_stats(&point)?;
                    if ratios.len() > 1 {
                        o.frame(&shell_frame(sim, i + 1)?, true)?;
                        summary.frames += 1;
                    }
                }
            }
            Err(e) => {
                summary.converged = false;
                failure = Some(e);
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
    summary.error = failure.as_ref().map(|e| e.to_string());
    summary.interrupted = interrupted.is_some();
    let mut record = serde_json::to_value(&summary)?;
    if let Some(text) = record_text {
        crate::run::insert_scenario(&mut record, text);
    }
    if let Some(o) = &mut out
        && ratios.len() > 1
        && curve.len() > 1
    {
        write_pressure_volume_plot(o, &args.mesh, &curve)?;
    }
    if let Some(o) = &mut out {
        let last = shell_frame(sim, summary.points.max(1))?;
        o.write_named_frame("final", &last)?;
        o.write_json("summary.json", &record)?;
        match o.finish(&last, failure.is_some()) {
            Ok(warnings) => warnings.iter().for_each(|w| eprintln!("warning: {w}")),
            Err(e) if failure.is_some() => eprintln!("warning: {e:#}"),
            Err(e) => return Err(e),
        }
    }
    if quiet {
    } else if args.json {
        print_json_line(&record)?;
    } else {
        let mut w = std::io::stdout().lock();
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
        if let Some(o) = &out {
            writeln!(w, "output written to {}", o.path().display())?;
        }
        w.flush()?;
    }
    match failure {
        Some(e) => Err(anyhow::Error::new(e).context(format!(
            "the static solve of `{}` did not converge (the simulation is left at the last converged point)",
            args.mesh
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

/// Writes `pressure_volume.png` into the output folder: the gauge pressure over the volume
/// ratio of a `--volume-ratios` continuation (one marker per converged point).
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
    use super::*;

    #[test]
    fn volume_ratios_parse_both_directions_and_reject_nonsense() {
        assert_eq!(parse_volume_ratios("1:2:0.5").unwrap(), vec![1.0, 1.5, 2.0]);
        assert_eq!(
            parse_volume_ratios("3:2:-0.5").unwrap(),
            vec![3.0, 2.5, 2.0]
        );
        assert_eq!(parse_volume_ratios("1:1.05:0.1").unwrap(), vec![1.0]);
        for bad in ["1:2", "1:2:0", "2:1:0.5", "0:1:0.1", "a:b:c", "1:2:inf"] {
            assert!(parse_volume_ratios(bad).is_err(), "{bad}");
        }
    }
}
