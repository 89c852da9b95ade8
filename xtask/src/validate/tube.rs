//! The bulging tube (issue 14, item 6; `docs/membranes.md` section 10): a closed rubber tube
//! (`balloon_mesh::generate::tube`, hemispherical caps, L/R = 40; quick: 20) traced quasi-statically under
//! volume control (`ShellSimulation::solve_static` with `StaticControl::Volume`). The pressure
//! rises to an initiation maximum `P_i`, a bulge forms in the middle (seeded by a band 1 %
//! thinner), the pressure drops, and the bulge lengthens at a nearly constant propagation
//! pressure `P_p` and bulge radius. Compared with the uniform closed-end tube (M26-M28: its
//! maximum for `P_i`) and Maxwell's equal-area rule on it (M29, Chater & Hutchinson 1984,
//! Kyriakides & Chang 1990) for `P_p` and the radii of the two coexisting states.
//!
//! The material is Gent (`mu = 0.4 MPa`, `Jm = 30`), not neo-Hookean: the neo-Hookean
//! closed-end tube's uniform pressure falls monotonically after its maximum (it has no minimum,
//! M28), so a neo-Hookean bulge grows radially without bound and never propagates; a
//! propagating bulge needs the stiffening at large stretch that Gent's limiting chain
//! extensibility gives.

use super::parabola_vertex;
use super::{Figures, Options};
use crate::plot::{Chart, Series, Style, line_chart};
use crate::render::{View, render_panels};
use crate::report::Case;
use anyhow::{Context, Result, bail};
use balloon::gas::GasKind;
use balloon::material::membrane::{MembraneGent, MembraneMaterial, MembraneNeoHookean, ThinSphere};
use balloon::mesh::generate::tube;
use balloon::shell::statics::{StaticControl, StaticOptions};
use balloon::shell::{ShellBalloon, membrane_sphere_stretch};
use nalgebra::Matrix2;

const G: &str = "tube";
const MU: f64 = 4.0e5;
const JM: f64 = 30.0;
/// Rest thickness, m.
const H: f64 = 1.0e-3;
/// Rest radius (circumradius of the polygonal barrel), m.
const R: f64 = 0.05;
/// Relative thinning of the imperfection band `|z| < R`.
const IMPERFECTION: f64 = 0.01;
/// Tolerance of `P_i` and `P_p` against the analytic values (relative).
const PRESSURE_TOL: f64 = 5e-3;
/// Tolerance of the bulge radius against Maxwell's (relative).
const RADIUS_TOL: f64 = 0.01;

/// The tube and trace: segments around, tip-to-tip length (m), largest `V / V0`.
#[derive(Clone, Copy, Debug)]
struct Spec {
    segments: usize,
    length: f64,
    v_max: f64,
}

impl Spec {
    /// Half the barrel length, m.
    fn half_barrel(&self) -> f64 {
        (self.length - 2.0 * R) / 2.0
    }

    /// The volume ratios of the trace: steps of 0.25 up to 2.5, 0.1 across the maximum (near
    /// 2.9) and the drop, 0.2 along the plateau.
    fn ratios(&self) -> Vec<f64> {
        let mut r: Vec<f64> = (1..=6).map(|k| 1.0 + 0.25 * k as f64).collect();
        r.extend((1..=15).map(|k| 2.5 + 0.1 * k as f64));
        let mut k = 1;
        while 4.0 + 0.2 * k as f64 <= self.v_max + 1e-9 {
            r.push(4.0 + 0.2 * k as f64);
            k += 1;
        }
        r
    }
}

/// The uniform closed-end tube of a membrane model (`docs/membranes.md` M26-M28): hoop
/// stretch `l1`, axial stretch `l2` from the end-force balance `l1^2 S11 = 2 l2^2 S22`
/// (the Cauchy hoop stress twice the axial one), pressure `P = H S11 / (R l2)`.
pub struct UniformTube<'a, M: MembraneMaterial> {
    material: &'a M,
}

impl<'a, M: MembraneMaterial> UniformTube<'a, M> {
    /// The closed-end tube of `material`.
    pub fn new(material: &'a M) -> Self {
        Self { material }
    }

    fn stress(&self, l1: f64, l2: f64) -> Matrix2<f64> {
        self.material
            .stress(&Matrix2::new(l1 * l1, 0.0, 0.0, l2 * l2))
    }

    /// The axial stretch of the closed-end tube at hoop stretch `l1 >= 1` (M27), by bisection
    /// on `g(l2) = l1^2 S11 - 2 l2^2 S22` (positive at `l2 = 1`, negative for large `l2` or past
    /// the model's admissible set). `None` when no root is bracketed.
    pub fn axial_stretch(&self, l1: f64) -> Option<f64> {
        let g = |l2: f64| {
            let s = self.stress(l1, l2);
            l1 * l1 * s[(0, 0)] - 2.0 * l2 * l2 * s[(1, 1)]
        };
        let (mut lo, mut hi) = (1.0, l1.max(1.0) + 1.0);
        if g(lo).is_nan() || g(lo) < 0.0 {
            return None;
        }
        while g(hi) > 0.0 {
            hi *= 2.0;
            if hi > 1e3 {
                return None;
            }
        }
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            // NaN (past the admissible set) counts as "too long".
            if g(mid) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Some(0.5 * (lo + hi))
    }

    /// `(l2, P R / H)` at hoop stretch `l1` (M28), or `None` (see [`Self::axial_stretch`]).
    pub fn state(&self, l1: f64) -> Option<(f64, f64)> {
        let l2 = self.axial_stretch(l1)?;
        let p = self.stress(l1, l2)[(0, 0)] / l2;
        p.is_finite().then_some((l2, p))
    }
}

/// A point of the uniform curve: hoop and axial stretch, barrel volume ratio `v = l1^2 l2`,
/// `P R / H` (Pa).
#[derive(Clone, Copy, Debug)]
struct Uniform {
    l1: f64,
    l2: f64,
    v: f64,
    p: f64,
}

/// The uniform curve from `l1 = 1` to `l1_max` (or the model's limit), `steps` points.
fn uniform_curve<M: MembraneMaterial>(m: &M, l1_max: f64, steps: usize) -> Vec<Uniform> {
    let t = UniformTube::new(m);
    (0..=steps)
        .map_while(|i| {
            let l1 = 1.0 + (l1_max - 1.0) * i as f64 / steps as f64;
            t.state(l1).map(|(l2, p)| Uniform {
                l1,
                l2,
                v: l1 * l1 * l2,
                p,
            })
        })
        .collect()
}

/// Maxwell's equal-area line on a rising-falling-rising curve `P(v)` (M29): the pressure `P_p`
/// between the curve's minimum and maximum at which `int_{v_a}^{v_b} (P - P_p) dv = 0`, `v_a`
/// on the first rising branch and `v_b` on the last. Returns `(P_p, a, b)` with the two states
/// interpolated on the curve.
fn maxwell(curve: &[Uniform]) -> Option<(f64, Uniform, Uniform)> {
    let imax = (1..curve.len() - 1)
        .find(|&i| curve[i].p > curve[i - 1].p && curve[i].p >= curve[i + 1].p)?;
    let imin = (imax + 1..curve.len() - 1)
        .find(|&i| curve[i].p < curve[i - 1].p && curve[i].p <= curve[i + 1].p)?;
    let lerp = |a: &Uniform, b: &Uniform, t: f64| Uniform {
        l1: a.l1 + t * (b.l1 - a.l1),
        l2: a.l2 + t * (b.l2 - a.l2),
        v: a.v + t * (b.v - a.v),
        p: a.p + t * (b.p - a.p),
    };
    // The crossing of level `pp` on the rising segment range, interpolated.
    let crossing = |range: std::ops::Range<usize>, pp: f64| -> Option<(usize, Uniform)> {
        range.into_iter().find_map(|i| {
            let (a, b) = (&curve[i], &curve[i + 1]);
            (a.p <= pp && b.p >= pp).then(|| (i, lerp(a, b, (pp - a.p) / (b.p - a.p))))
        })
    };
    let area = |pp: f64| -> Option<(f64, Uniform, Uniform)> {
        let (ia, a) = crossing(0..imax, pp)?;
        let (ib, b) = crossing(imin..curve.len() - 1, pp)?;
        let mut s = 0.5 * (a.p + curve[ia + 1].p) * (curve[ia + 1].v - a.v);
        for i in ia + 1..ib {
            s += 0.5 * (curve[i].p + curve[i + 1].p) * (curve[i + 1].v - curve[i].v);
        }
        s += 0.5 * (curve[ib].p + b.p) * (b.v - curve[ib].v);
        Some((s - pp * (b.v - a.v), a, b))
    };
    let (mut lo, mut hi) = (curve[imin].p, curve[imax].p);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        // Too low a line leaves more area above it than below.
        if area(mid)?.0 > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let pp = 0.5 * (lo + hi);
    let (_, a, b) = area(pp)?;
    Some((pp, a, b))
}

/// One traced equilibrium.
#[derive(Clone, Debug)]
struct TracePoint {
    /// `V / V0` (whole tube).
    volume_ratio: f64,
    /// Gauge pressure, Pa.
    pressure: f64,
    /// Largest distance from the axis of the barrel vertices over `R`.
    r_max: f64,
    /// Smallest distance from the axis of the barrel vertices at least `R` from the caps, over
    /// `R`.
    r_min: f64,
}

struct Trace {
    points: Vec<TracePoint>,
    /// Positions at the snapshot ratios.
    snapshots: Vec<(f64, Vec<f64>)>,
    /// Rest `z` of every vertex.
    rest_z: Vec<f64>,
    triangles: Vec<[usize; 3]>,
    vertices: usize,
    rest_volume: f64,
    seconds: f64,
    spec: Spec,
}

/// Traces the tube of `model` along `spec.ratios()`, snapshots at the `snap` ratios.
fn trace<M: MembraneMaterial>(model: M, spec: Spec, snap: &[f64]) -> Result<Trace> {
    let started = std::time::Instant::now();
    let mesh = tube(R, spec.length, spec.segments)?;
    let half = spec.half_barrel();
    let rest_z: Vec<f64> = mesh.vertices.iter().map(|p| p.z).collect();
    let thickness: Vec<f64> = mesh
        .triangles
        .iter()
        .map(|t| {
            let z = t.iter().map(|&i| rest_z[i]).sum::<f64>() / 3.0;
            if z.abs() < R {
                (1.0 - IMPERFECTION) * H
            } else {
                H
            }
        })
        .collect();
    let triangles = mesh.triangles.clone();
    let vertices = mesh.vertices.len();
    let mut sim = ShellBalloon::new(mesh)
        .with_membrane(model)
        .with_thickness_per_face(thickness)
        .with_gas(GasKind::Constant)
        .with_gauge_pressure(0.0)
        .build()?;
    let v0 = sim.rest_gas_volume();
    let mut points = Vec::new();
    let mut snapshots = Vec::new();
    for ratio in spec.ratios() {
        let report = sim
            .solve_static(&StaticOptions {
                control: StaticControl::Volume { target: v0 * ratio },
                ..Default::default()
            })
            .with_context(|| format!("static solve at V / V0 = {ratio:.2}"))?;
        let x = sim.positions();
        let (mut r_max, mut r_min) = (0.0f64, f64::INFINITY);
        for (i, z) in rest_z.iter().enumerate() {
            if z.abs() <= half {
                let r = x[3 * i].hypot(x[3 * i + 1]) / R;
                r_max = r_max.max(r);
                if z.abs() <= half - R {
                    r_min = r_min.min(r);
                }
            }
        }
        points.push(TracePoint {
            volume_ratio: report.gas_volume / v0,
            pressure: report.gauge_pressure,
            r_max,
            r_min,
        });
        if snap.iter().any(|s| (s - ratio).abs() < 1e-9) {
            snapshots.push((ratio, x.to_vec()));
        }
    }
    Ok(Trace {
        points,
        snapshots,
        rest_z,
        triangles,
        vertices,
        rest_volume: v0,
        seconds: started.elapsed().as_secs_f64(),
        spec,
    })
}

/// The tube cases: `P_i`, `P_p`, the bulge radius and the localisation, with the figures.
pub fn cases(opts: &Options, figs: &mut Figures) -> Vec<Case> {
    let mut cases = Vec::new();
    if let Err(e) = run(opts, figs, &mut cases) {
        cases.push(Case::error(G, "bulging tube trace", format!("{e:#}")));
    }
    cases
}

fn run(opts: &Options, figs: &mut Figures, cases: &mut Vec<Case>) -> Result<()> {
    // Full: L / R = 40, so that the bulge's flat top and its two fronts fit in the barrel;
    // quick: L / R = 20, 16 segments.
    let spec = if opts.quick {
        Spec {
            segments: 16,
            length: 1.0,
            v_max: 12.0,
        }
    } else {
        Spec {
            segments: 32,
            length: 2.0,
            v_max: 12.0,
        }
    };
    let segments = spec.segments;
    let snap = [2.0, 2.9, 3.5, 5.0, 8.0, 12.0];
    let t = trace(MembraneGent::try_new(MU, JM)?, spec, &snap)?;
    // The polygonal barrel is exactly a tube of the inradius R cos(pi / n) (2 V / A of the
    // prism), the radius the analytic curve needs (as R = 3 V / A for the icosphere).
    let r_eff = R * (std::f64::consts::PI / segments as f64).cos();
    let scale = MU * H / r_eff;
    let gent = MembraneGent::try_new(MU, JM)?;
    let curve = uniform_curve(&gent, 5.0, 8000);
    let Some(imax) = (1..curve.len() - 1).find(|&i| curve[i].p >= curve[i + 1].p) else {
        bail!("the uniform closed-end Gent tube has no pressure maximum");
    };
    let p_max = curve[imax].p * H / r_eff;
    let Some((pp_unit, state_a, state_b)) = maxwell(&curve) else {
        bail!("no Maxwell line on the uniform closed-end Gent tube");
    };
    let p_maxwell = pp_unit * H / r_eff;

    // The traced initiation maximum (parabola through the largest point and its neighbours).
    let pts = &t.points;
    let Some(i) = (1..pts.len() - 1).max_by(|&a, &b| pts[a].pressure.total_cmp(&pts[b].pressure))
    else {
        bail!("trace too short");
    };
    let (v_i, p_i) = parabola_vertex([
        (pts[i - 1].volume_ratio, pts[i - 1].pressure),
        (pts[i].volume_ratio, pts[i].pressure),
        (pts[i + 1].volume_ratio, pts[i + 1].pressure),
    ])
    .unwrap_or((pts[i].volume_ratio, pts[i].pressure));
    // The propagation window: after the maximum, once the bulge has (nearly) reached its final
    // radius.
    let last = pts.last().map_or(0.0, |p| p.r_max);
    let window: Vec<&TracePoint> = pts[i..].iter().filter(|p| p.r_max >= 0.97 * last).collect();
    if window.len() < 3 {
        bail!("no propagation window: the bulge did not settle to a radius");
    }
    let p_p = window.iter().map(|p| p.pressure).sum::<f64>() / window.len() as f64;
    let (w_lo, w_hi) = window.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), p| {
        (lo.min(p.pressure), hi.max(p.pressure))
    });
    let (wv0, wv1) = (
        window[0].volume_ratio,
        window[window.len() - 1].volume_ratio,
    );
    let label = format!(
        "Gent tube (mu 0.4 MPa, Jm 30), R 0.05 m, L {} m, {segments} segments, {} vertices",
        spec.length, t.vertices
    );
    cases.push(Case::relative(
        G,
        format!("{label}: initiation pressure P_i (Pa) vs the uniform tube's maximum (M28)"),
        p_i,
        p_max,
        PRESSURE_TOL,
    ));
    cases.push(Case::relative(
        G,
        format!(
            "propagation pressure P_p (Pa, mean over V/V0 = {wv0:.1}..{wv1:.1}) vs Maxwell (M29)"
        ),
        p_p,
        p_maxwell,
        PRESSURE_TOL,
    ));
    cases.push(Case::check(
        G,
        "plateau below the maximum and nearly constant",
        p_p < 0.97 * p_i && (w_hi - w_lo) / p_p < 0.01,
        format!(
            "P_p / P_i = {:.4}; P varies by {:.2} % over the window",
            p_p / p_i,
            100.0 * (w_hi - w_lo) / p_p
        ),
        "P_p / P_i < 0.97, variation < 1 %",
    ));
    let bulge = window.iter().map(|p| p.r_max).sum::<f64>() / window.len() as f64;
    cases.push(Case::relative(
        G,
        "bulge radius r / R (mean over the window) vs Maxwell's bulged state l1_b",
        bulge,
        state_b.l1,
        RADIUS_TOL,
    ));
    let at_peak = pts[i].r_max / pts[i].r_min;
    let at_end = pts[pts.len() - 1].r_max / pts[pts.len() - 1].r_min;
    cases.push(Case::check(
        G,
        "the bulge localises: max / min radius along the barrel",
        at_peak < 1.3 && at_end > 1.8,
        format!("{at_peak:.3} at the maximum (V/V0 = {v_i:.2}), {at_end:.3} at the end"),
        "< 1.3 at the maximum, > 1.8 at the end",
    ));
    eprintln!(
        "xtask validate tube: P_i = {p_i:.1} Pa (analytic {p_max:.1}), P_p = {p_p:.1} Pa (Maxwell {p_maxwell:.1}), bulge r/R {bulge:.3} (Maxwell {:.3}, l2 {:.3}), unbulged Maxwell l1_a {:.3} (l2 {:.3}), {:.0} s",
        state_b.l1, state_b.l2, state_a.l1, state_a.l2, t.seconds
    );
    let neo = neo_hookean(cases)?;
    figures(figs, &t, &neo, &curve, scale, r_eff, p_maxwell, (p_i, p_p))?;
    Ok(())
}

/// The same experiment with a neo-Hookean membrane (16 segments, L / R = 20, to `V / V0 = 4.6`):
/// the initiation pressure against the neo-Hookean closed-end tube's maximum, and the absence
/// of a plateau (the uniform curve has no minimum, M28: the bulge keeps growing radially and
/// the pressure keeps falling). Returns the trace for the pressure-volume figure.
fn neo_hookean(cases: &mut Vec<Case>) -> Result<Trace> {
    let spec = Spec {
        segments: 16,
        length: 1.0,
        v_max: 4.6,
    };
    let rubber = MembraneNeoHookean::try_new(MU)?;
    let t = trace(rubber, spec, &[])?;
    let r_eff = R * (std::f64::consts::PI / spec.segments as f64).cos();
    let curve = uniform_curve(&rubber, 3.0, 4000);
    let Some(imax) = (1..curve.len() - 1).find(|&i| curve[i].p >= curve[i + 1].p) else {
        bail!("the uniform closed-end neo-Hookean tube has no pressure maximum");
    };
    let p_max = curve[imax].p * H / r_eff;
    let pts = &t.points;
    let Some(i) = (1..pts.len() - 1).max_by(|&a, &b| pts[a].pressure.total_cmp(&pts[b].pressure))
    else {
        bail!("neo-Hookean trace too short");
    };
    let (_, p_i) = parabola_vertex([
        (pts[i - 1].volume_ratio, pts[i - 1].pressure),
        (pts[i].volume_ratio, pts[i].pressure),
        (pts[i + 1].volume_ratio, pts[i + 1].pressure),
    ])
    .unwrap_or((pts[i].volume_ratio, pts[i].pressure));
    cases.push(Case::relative(
        G,
        "neo-Hookean tube (mu 0.4 MPa), L 1 m, 16 segments: initiation pressure P_i (Pa) vs the uniform tube's maximum (M28)",
        p_i,
        p_max,
        PRESSURE_TOL,
    ));
    let end = &pts[pts.len() - 1];
    let before = &pts[pts.len() - 6];
    eprintln!("xtask validate tube: neo-Hookean trace {:.0} s", t.seconds);
    cases.push(Case::check(
        G,
        "neo-Hookean tube: no propagation plateau (the bulge keeps growing, the pressure keeps falling)",
        end.pressure < before.pressure && end.r_max > 1.02 * before.r_max,
        format!(
            "V/V0 {:.1} -> {:.1}: P {:.0} -> {:.0} Pa, bulge r/R {:.3} -> {:.3}",
            before.volume_ratio,
            end.volume_ratio,
            before.pressure,
            end.pressure,
            before.r_max,
            end.r_max
        ),
        "P falls and r/R grows by > 2 % over the last 5 points",
    ));
    Ok(t)
}

/// `V / V0` of the whole discrete tube on the uniform curve: the barrel at `l1^2 l2`, the caps
/// as the thin sphere at the same pressure (their junction with the barrel ignored).
fn uniform_volume_ratio(u: &Uniform, r_eff: f64, t: &Trace) -> f64 {
    let n = t.spec.segments as f64;
    let barrel0 = 0.5 * n * R * R * (std::f64::consts::TAU / n).sin() * 2.0 * t.spec.half_barrel();
    let caps0 = t.rest_volume - barrel0;
    let Ok(sphere) = ThinSphere::try_new(r_eff, H) else {
        return f64::NAN;
    };
    let Ok(gent) = MembraneGent::try_new(MU, JM) else {
        return f64::NAN;
    };
    let p = u.p * H / r_eff;
    let ls = membrane_sphere_stretch(&sphere, &gent, p).unwrap_or(f64::NAN);
    (barrel0 * u.v + caps0 * ls.powi(3)) / t.rest_volume
}

#[allow(clippy::too_many_arguments)]
fn figures(
    figs: &mut Figures,
    t: &Trace,
    neo: &Trace,
    curve: &[Uniform],
    scale: f64,
    r_eff: f64,
    p_maxwell: f64,
    (p_i, p_p): (f64, f64),
) -> Result<()> {
    let analytic: Vec<(f64, f64)> = curve
        .iter()
        .step_by(10)
        .map(|u| (uniform_volume_ratio(u, r_eff, t), u.p * H / r_eff / scale))
        .filter(|(v, _)| v.is_finite() && *v <= t.spec.v_max + 0.5)
        .collect();
    let series = vec![
        Series::new(
            "uniform closed-end tube (analytic, M28)",
            analytic,
            Style::Line,
            0,
        ),
        Series::new(
            format!("Maxwell line P_p (M29) = {:.4}", p_maxwell / scale),
            vec![(1.0, p_maxwell / scale), (t.spec.v_max, p_maxwell / scale)],
            Style::Line,
            2,
        ),
        Series::new(
            format!(
                "traced (static, volume control): P_i = {:.4}, P_p = {:.4}",
                p_i / scale,
                p_p / scale
            ),
            t.points
                .iter()
                .map(|p| (p.volume_ratio, p.pressure / scale))
                .collect(),
            Style::Points(3),
            1,
        ),
        Series::new(
            "neo-Hookean tube (traced, 16 segments, L/R = 20): no plateau",
            neo.points
                .iter()
                .map(|p| {
                    let r = R * (std::f64::consts::PI / neo.spec.segments as f64).cos();
                    (p.volume_ratio, p.pressure / (MU * H / r))
                })
                .collect(),
            Style::Points(2),
            3,
        ),
    ];
    figs.add(
        "tube_pv.png",
        "Bulging tube (Gent, Jm = 30) under volume control: traced pressure against the uniform closed-end tube and Maxwell's equal-area line, and a neo-Hookean tube (no plateau), P / (mu H / R_eff) over V / V0",
        |p| {
            line_chart(
                p,
                &Chart {
                    title: "Bulging tube: P / (mu H / R) vs V / V0",
                    x_label: "V / V0",
                    y_label: "P / (mu H / R)",
                    log_x: false,
                    log_y: false,
                    legend_lower_right: true,
                },
                &series,
                (1000, 650),
            )
        },
    )?;
    let half = t.spec.half_barrel();
    let profiles: Vec<Series> = t
        .snapshots
        .iter()
        .enumerate()
        .map(|(k, (ratio, x))| {
            // One point per barrel ring: the mean radius and height of its vertices.
            let mut rings: Vec<(f64, f64, f64, usize)> = Vec::new();
            for (i, z0) in t.rest_z.iter().enumerate() {
                if z0.abs() > half + 1e-12 {
                    continue;
                }
                let r = x[3 * i].hypot(x[3 * i + 1]) / R;
                match rings.iter_mut().find(|e| (e.0 - z0).abs() < 1e-9) {
                    Some(e) => {
                        e.1 += x[3 * i + 2];
                        e.2 += r;
                        e.3 += 1;
                    }
                    None => rings.push((*z0, x[3 * i + 2], r, 1)),
                }
            }
            rings.sort_by(|a, b| a.0.total_cmp(&b.0));
            Series::new(
                format!("V / V0 = {ratio:.1}"),
                rings
                    .iter()
                    .map(|e| (e.1 / e.3 as f64, e.2 / e.3 as f64))
                    .collect(),
                Style::Line,
                k,
            )
        })
        .collect();
    figs.add(
        "tube_profiles.png",
        "Bulging tube: radius r / R along the axis (current z, barrel only) at several volumes; the bulge forms in the middle, then lengthens at a nearly constant radius",
        |p| {
            line_chart(
                p,
                &Chart {
                    title: "Bulging tube: radius profiles",
                    x_label: "z (m, current)",
                    y_label: "r / R",
                    log_x: false,
                    log_y: false,
                    legend_lower_right: false,
                },
                &profiles,
                (1000, 600),
            )
        },
    )?;
    // The snapshots stacked into one picture: the axis turned to the horizontal (x), each
    // tube shifted down by a fixed gap.
    let mut all = Vec::new();
    let mut tris = Vec::new();
    let gap = 8.0 * R;
    for (k, (_, x)) in t.snapshots.iter().enumerate() {
        let base = all.len() / 3;
        for p in x.chunks_exact(3) {
            // (x, y, z) -> (z, x - k gap, y): a proper rotation plus a shift.
            all.extend_from_slice(&[p[2], p[0] - gap * k as f64, p[1]]);
        }
        tris.extend(t.triangles.iter().map(|tr| tr.map(|i| i + base)));
    }
    let (w, h) = (1200u32, 1000u32);
    let img = render_panels(
        &[(&all, &tris)],
        View {
            yaw: 0.0,
            pitch: 0.35,
        },
        w,
        h,
        [0.92, 0.55, 0.25],
    );
    let caption = format!(
        "top to bottom: V / V0 = {}",
        t.snapshots
            .iter()
            .map(|(r, _)| format!("{r:.1}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    figs.add(
        "tube_renders.png",
        "Bulging tube at several volumes (top to bottom, the V / V0 of the profiles): the bulge forms in the middle and propagates towards the caps",
        |p| crate::plot::image_with_caption(p, &img, (w, h), &[(20, &caption)]),
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neo_hookean_closed_tube_matches_its_closed_form() {
        // l2^2 = (l1^2 + sqrt(l1^4 + 8 / l1^2)) / 4 and P R / (mu H) = (1 - 1 / (l1^4 l2^2)) / l2
        // (docs/membranes.md M28); maximum near l1 = 1.575, no minimum.
        let nh = MembraneNeoHookean::try_new(1.0).unwrap();
        let t = UniformTube::new(&nh);
        for l1 in [1.0, 1.3, 2.0, 4.0] {
            let (l2, p) = t.state(l1).unwrap();
            let exact = ((l1 * l1 + (l1.powi(4) + 8.0 / (l1 * l1)).sqrt()) / 4.0).sqrt();
            assert!((l2 - exact).abs() < 1e-10, "{l2} vs {exact}");
            let pe = (1.0 - 1.0 / (l1.powi(4) * l2 * l2)) / l2;
            assert!((p - pe).abs() < 1e-10);
        }
        let c = uniform_curve(&nh, 6.0, 2000);
        assert!(maxwell(&c).is_none(), "neo-Hookean has no Maxwell line");
    }

    #[test]
    fn gent_tube_has_a_maxwell_line_between_its_extrema() {
        let g = MembraneGent::try_new(1.0, 30.0).unwrap();
        let c = uniform_curve(&g, 5.0, 8000);
        let (pp, a, b) = maxwell(&c).unwrap();
        // Equal areas, checked independently with a fine sum.
        let mut s = 0.0;
        for w in c.windows(2) {
            let (lo, hi) = (w[0].v.max(a.v), w[1].v.min(b.v));
            if hi > lo {
                s += (0.5 * (w[0].p + w[1].p) - pp) * (hi - lo);
            }
        }
        assert!(s.abs() < 1e-3 * pp * (b.v - a.v), "{s}");
        assert!((a.p - pp).abs() < 1e-9 && (b.p - pp).abs() < 1e-9);
        assert!(a.l1 < 1.66 && b.l1 > 2.67, "{a:?} {b:?}");
    }
}
