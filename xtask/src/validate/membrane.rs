//! Rubber membranes against the analytic thin sphere (issue 14, item 3; `docs/membranes.md`
//! M18-M21): for every membrane model, the pressure-volume curve of an icosphere of 2562
//! vertices is traced under volume control (`ShellSimulation::solve_static` with
//! `StaticControl::Volume`, the pressure being the constraint's multiplier), the maximum and
//! minimum of the traced curve are located (the ratios are refined near each one and a parabola
//! is fitted through the three finest points around it) and compared with `ThinSphere::extrema`
//! (location in stretch and height, 0.5 %). Along the trace the spread of the element area
//! stretches measures whether the sphere stays uniform (a bifurcation to a non-spherical shape
//! shows as a growing spread).

use super::parabola_vertex;
use super::{Figures, Options};
use crate::plot::{Chart, Series, Style, line_chart};
use crate::report::Case;
use anyhow::{Context, Result};
use balloon::gas::GasKind;
use balloon::material::MembraneModel;
use balloon::material::membrane::{
    ExtremumKind, MembraneGent, MembraneMaterial, MembraneMooneyRivlin, MembraneNeoHookean,
    MembranePreset, MembraneYeoh, ThinSphere,
};
use balloon::mesh::generate::icosphere;
use balloon::mesh::{TriMesh, geometry};
use balloon::shell::statics::{StaticControl, StaticOptions};
use balloon::shell::{ShellBalloon, ShellSimulation};

const G: &str = "membrane";
/// Rest thickness `H`, m.
const H: f64 = 1.0e-3;
/// Tolerance of the extrema (location in stretch and height), relative.
const EXTREMUM_TOL: f64 = 5e-3;
/// Largest relative spread of the element area stretches (`max / min - 1`) accepted as "still
/// the uniform sphere": the icosphere's own discretisation spread is about 0.1 %, a
/// non-spherical branch spreads by tens of percent.
const UNIFORM_SPREAD: f64 = 0.02;

/// One model of the validation: its name, parameters and how far to trace.
struct ModelCase {
    label: &'static str,
    model: MembraneModel,
    /// Largest stretch `l = (V / V0)^(1/3)` of the trace.
    max_stretch: f64,
}

fn models() -> Result<Vec<ModelCase>> {
    Ok(vec![
        ModelCase {
            label: "neo-Hookean, mu = 0.4 MPa",
            model: MembraneNeoHookean::try_new(4.0e5)?.into(),
            max_stretch: 2.0,
        },
        ModelCase {
            label: "Mooney-Rivlin, c1 = 0.2 MPa, c2 = 0.03 MPa",
            model: MembraneMooneyRivlin::try_new(2.0e5, 3.0e4)?.into(),
            max_stretch: 2.9,
        },
        ModelCase {
            label: "Gent, mu = 0.4 MPa, Jm = 30",
            model: MembraneGent::try_new(4.0e5, 30.0)?.into(),
            max_stretch: 2.7,
        },
        ModelCase {
            label: "Ogden, natural-rubber preset",
            model: MembranePreset::NaturalRubber.model(),
            max_stretch: 4.8,
        },
        ModelCase {
            label: "Yeoh, c = (0.2, -0.005, 0.0003) MPa",
            model: MembraneYeoh::try_new(2.0e5, -5.0e3, 3.0e2)?.into(),
            max_stretch: 2.9,
        },
    ])
}

/// A point of a traced curve.
#[derive(Clone, Copy, Debug)]
struct Point {
    /// `l = (V / V0)^(1/3)`.
    stretch: f64,
    /// Gauge pressure (the multiplier), Pa.
    pressure: f64,
    /// `max / min - 1` of the element area stretches.
    spread: f64,
}

/// An extremum of a traced curve: the parabola through the finest three points around it.
#[derive(Clone, Copy, Debug)]
struct Extremum {
    kind: ExtremumKind,
    stretch: f64,
    pressure: f64,
}

struct Trace {
    points: Vec<Point>,
    extrema: Vec<Extremum>,
    solves: usize,
    seconds: f64,
}

/// Whether the middle of three pressures is a maximum / minimum.
fn turn(a: f64, b: f64, c: f64) -> Option<ExtremumKind> {
    if b > a && b > c {
        Some(ExtremumKind::Maximum)
    } else if b < a && b < c {
        Some(ExtremumKind::Minimum)
    } else {
        None
    }
}

struct Tracer<M: balloon::shell::ShellMaterial> {
    sim: ShellSimulation<M>,
    options: StaticOptions,
    v0: f64,
    solves: usize,
}

impl<M: balloon::shell::ShellMaterial> Tracer<M> {
    fn solve(&mut self, stretch: f64) -> Result<Point> {
        self.options.control = StaticControl::Volume {
            target: self.v0 * stretch.powi(3),
        };
        let r = self
            .sim
            .solve_static(&self.options)
            .with_context(|| format!("static solve at stretch {stretch:.4}"))?;
        self.solves += 1;
        Ok(Point {
            stretch: (r.gas_volume / self.v0).cbrt(),
            pressure: r.gauge_pressure,
            spread: r.max_area_stretch / r.min_area_stretch - 1.0,
        })
    }
}

/// Traces `P(l)` from `l = 1` to `max_stretch` in steps `dl` under volume control; where three
/// coarse points turn, the stretch range of the turn is traced again in steps `dl / 10` and the
/// extremum is the vertex of the parabola through the finest three points around it.
fn trace(mesh: &TriMesh, model: &MembraneModel, max_stretch: f64, dl: f64) -> Result<Trace> {
    let started = std::time::Instant::now();
    let sim = ShellBalloon::new(mesh.clone())
        .with_membrane(model.clone())
        .with_thickness(H)
        .with_gas(GasKind::Constant)
        .with_gauge_pressure(0.0)
        .build()?;
    let v0 = sim.rest_gas_volume();
    let mut t = Tracer {
        sim,
        options: StaticOptions::default(),
        v0,
        solves: 0,
    };
    let mut coarse = vec![t.solve(1.0)?];
    let mut fine_all: Vec<Point> = Vec::new();
    let mut extrema = Vec::new();
    let steps = ((max_stretch - 1.0) / dl).round() as usize;
    for k in 1..=steps {
        let l = 1.0 + dl * k as f64;
        coarse.push(t.solve(l)?);
        let n = coarse.len();
        if n < 3 {
            continue;
        }
        let (a, b, c) = (coarse[n - 3], coarse[n - 2], coarse[n - 1]);
        let Some(kind) = turn(a.pressure, b.pressure, c.pressure) else {
            continue;
        };
        // Refine between the outer two points, then come back to the last coarse one.
        let fine_steps = 20;
        let h = (c.stretch - a.stretch) / fine_steps as f64;
        let fine: Vec<Point> = (0..=fine_steps)
            .map(|i| t.solve(a.stretch + h * i as f64))
            .collect::<Result<_>>()?;
        let best = (1..fine.len() - 1)
            .filter(|&i| {
                turn(fine[i - 1].pressure, fine[i].pressure, fine[i + 1].pressure) == Some(kind)
            })
            .max_by(|&i, &j| {
                let s = if kind == ExtremumKind::Maximum {
                    1.0
                } else {
                    -1.0
                };
                (s * fine[i].pressure).total_cmp(&(s * fine[j].pressure))
            });
        if let Some(i) = best
            && let Some((stretch, pressure)) = parabola_vertex([
                (fine[i - 1].stretch, fine[i - 1].pressure),
                (fine[i].stretch, fine[i].pressure),
                (fine[i + 1].stretch, fine[i + 1].pressure),
            ])
        {
            extrema.push(Extremum {
                kind,
                stretch,
                pressure,
            });
        }
        fine_all.extend(fine);
        t.solve(c.stretch)?;
    }
    let mut points = coarse;
    points.extend(fine_all);
    points.sort_by(|a, b| a.stretch.total_cmp(&b.stretch));
    Ok(Trace {
        points,
        extrema,
        solves: t.solves,
        seconds: started.elapsed().as_secs_f64(),
    })
}

fn kind_name(k: ExtremumKind) -> &'static str {
    match k {
        ExtremumKind::Maximum => "maximum",
        ExtremumKind::Minimum => "minimum",
    }
}

/// The membrane cases: per model, each extremum's location and height, and the uniform-branch
/// check past the maximum; the figures of the traced against the analytic curves and of the
/// spread of the area stretches.
pub fn cases(opts: &Options, figs: &mut Figures) -> Vec<Case> {
    let mut cases = Vec::new();
    if let Err(e) = run(opts, figs, &mut cases) {
        cases.push(Case::error(G, "membrane sphere traces", format!("{e:#}")));
    }
    cases
}

fn run(opts: &Options, figs: &mut Figures, cases: &mut Vec<Case>) -> Result<()> {
    let mesh = icosphere(0.1, 4)?;
    // The radius for which the analytic sphere is exact on the polyhedron
    // (docs/analytic-sphere.md).
    let radius = 3.0 * geometry::enclosed_volume(&mesh) / geometry::surface_area(&mesh);
    let sphere = ThinSphere::try_new(radius, H)?;
    let mut list = models()?;
    if opts.quick {
        list.truncate(1);
    }
    let mut curve_series = Vec::new();
    let mut spread_series = Vec::new();
    for (index, m) in list.iter().enumerate() {
        let trace = match trace(&mesh, &m.model, m.max_stretch, 0.05) {
            Ok(t) => t,
            Err(e) => {
                cases.push(Case::error(
                    G,
                    format!("{}: trace", m.label),
                    format!("{e:#}"),
                ));
                continue;
            }
        };
        let mu0 = m.model.initial_shear_modulus();
        let scale = mu0 * H / radius;
        let analytic = sphere.extrema(&m.model, m.max_stretch)?;
        compare_extrema(m.label, &analytic, &trace, cases);
        uniform_branch(m.label, &analytic, &trace, cases);
        let curve: Vec<(f64, f64)> = (0..=400)
            .map(|i| {
                let l = 1.0 + (m.max_stretch - 1.0) * i as f64 / 400.0;
                (l, sphere.pressure(&m.model, l) / scale)
            })
            .collect();
        curve_series.push(Series::new(
            format!("{} (analytic)", m.label),
            curve,
            Style::Line,
            index,
        ));
        curve_series.push(Series::new(
            format!("traced, {} solves, {:.0} s", trace.solves, trace.seconds),
            trace
                .points
                .iter()
                .map(|p| (p.stretch, p.pressure / scale))
                .collect(),
            Style::Points(3),
            index,
        ));
        spread_series.push(Series::new(
            m.label,
            trace
                .points
                .iter()
                .map(|p| (p.stretch, 100.0 * p.spread))
                .collect(),
            Style::LinePoints,
            index,
        ));
    }
    figs.add(
        "membrane_sphere_pv.png",
        "Membrane spheres under volume control: traced pressure (points, icosphere of 2562 vertices) against the analytic thin sphere (lines), P / (mu0 H / R) over the stretch (V / V0)^(1/3)",
        |p| {
            line_chart(
                p,
                &Chart {
                    title: "Membrane sphere: P / (mu0 H / R) vs stretch",
                    x_label: "stretch l = (V / V0)^(1/3)",
                    y_label: "P / (mu0 H / R)",
                    log_x: false,
                    log_y: false,
                    legend_lower_right: true,
                },
                &curve_series,
                (1000, 700),
            )
        },
    )?;
    figs.add(
        "membrane_sphere_spread.png",
        "Membrane spheres under volume control: spread of the element area stretches (max / min - 1, %) along the trace; a bifurcation away from the sphere would show as a growing spread",
        |p| {
            line_chart(
                p,
                &Chart {
                    title: "Membrane sphere: area-stretch spread (%) vs stretch",
                    x_label: "stretch l = (V / V0)^(1/3)",
                    y_label: "max / min area stretch - 1 (%)",
                    log_x: false,
                    log_y: false,
                    legend_lower_right: false,
                },
                &spread_series,
                (1000, 600),
            )
        },
    )?;
    Ok(())
}

fn compare_extrema(
    label: &str,
    analytic: &[balloon::material::membrane::PressureExtremum],
    trace: &Trace,
    cases: &mut Vec<Case>,
) {
    for a in analytic {
        let which = kind_name(a.kind);
        let found = trace
            .extrema
            .iter()
            .filter(|e| e.kind == a.kind)
            .min_by(|x, y| {
                (x.stretch - a.stretch)
                    .abs()
                    .total_cmp(&(y.stretch - a.stretch).abs())
            });
        match found {
            Some(e) => {
                cases.push(Case::relative(
                    G,
                    format!("{label}: stretch of the pressure {which}"),
                    e.stretch,
                    a.stretch,
                    EXTREMUM_TOL,
                ));
                cases.push(Case::relative(
                    G,
                    format!("{label}: height of the pressure {which} (Pa)"),
                    e.pressure,
                    a.pressure,
                    EXTREMUM_TOL,
                ));
            }
            None => cases.push(Case::error(
                G,
                format!("{label}: pressure {which} at l = {:.4}", a.stretch),
                "not found on the traced curve",
            )),
        }
    }
    // A traced extremum the analytic curve does not have.
    for e in &trace.extrema {
        if !analytic
            .iter()
            .any(|a| a.kind == e.kind && (a.stretch - e.stretch).abs() < 0.05)
        {
            cases.push(Case::error(
                G,
                format!(
                    "{label}: traced {} at l = {:.4}",
                    kind_name(e.kind),
                    e.stretch
                ),
                "not on the analytic curve",
            ));
        }
    }
}

/// Past the first maximum: the largest area-stretch spread, where it occurs, and whether the
/// sphere stayed uniform.
fn uniform_branch(
    label: &str,
    analytic: &[balloon::material::membrane::PressureExtremum],
    trace: &Trace,
    cases: &mut Vec<Case>,
) {
    let Some(first_max) = analytic.iter().find(|a| a.kind == ExtremumKind::Maximum) else {
        return;
    };
    let before = trace
        .points
        .iter()
        .filter(|p| p.stretch <= first_max.stretch)
        .fold(0.0f64, |m, p| m.max(p.spread));
    let past: Vec<&Point> = trace
        .points
        .iter()
        .filter(|p| p.stretch > first_max.stretch)
        .collect();
    let Some(worst) = past.iter().max_by(|a, b| a.spread.total_cmp(&b.spread)) else {
        return;
    };
    let last = past.last().map_or(first_max.stretch, |p| p.stretch);
    cases.push(Case::check(
        G,
        format!(
            "{label}: uniform branch past the maximum (l = {:.3} .. {last:.3}), area-stretch spread",
            first_max.stretch
        ),
        worst.spread <= UNIFORM_SPREAD,
        format!(
            "largest {:.3} % at l = {:.3} (up to the maximum: {:.3} %)",
            100.0 * worst.spread,
            worst.stretch,
            100.0 * before
        ),
        format!("< {:.0} % (no bifurcation)", 100.0 * UNIFORM_SPREAD),
    ));
}
