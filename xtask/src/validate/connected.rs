//! Connected balloons (issue 14, item 4): the two-balloon experiment on icospheres of 642
//! vertices, with a finite tube and with instant equalisation, against the analytic thin-sphere
//! end state (`ThinSphere::joined_pair`), with the path of both balloons drawn over the
//! analytic pressure curve and a picture of the pair before and after.

use super::{Figures, Options};
use crate::plot::{Chart, Series, Style, line_chart};
use crate::render::{View, render_panels};
use crate::report::Case;
use anyhow::{Context, Result};
use balloon::gas::GasKind;
use balloon::material::membrane::{MembraneNeoHookean, ThinSphere};
use balloon::mesh::generate::icosphere;
use balloon::mesh::geometry;
use balloon::shell::connected::{Conductance, ConnectedBalloons, Tube};
use balloon::shell::statics::StaticOptions;
use balloon::shell::{Membrane, ShellBalloon, ShellSimulation};

const G: &str = "connected";
const MU: f64 = 4.0e5;
const H: f64 = 1.0e-3;
const LEVEL: u32 = 3;

type Rubber = ShellSimulation<Membrane<MembraneNeoHookean>>;

/// A balloon held at stretch `l` by volume control, then holding that gas as an ideal gas.
fn balloon_at(l: f64, offset: f64) -> Result<Rubber> {
    let mut mesh = icosphere(0.1, LEVEL)?;
    for v in &mut mesh.vertices {
        v.x += offset;
    }
    let mut sim = ShellBalloon::new(mesh)
        .with_membrane(MembraneNeoHookean::try_new(MU)?)
        .with_thickness(H)
        .with_gas(GasKind::Ideal)
        .build()?;
    sim.configure_integrator(|p| p.mass_damping = 5.0)?;
    let target = sim.rest_gas_volume() * l * l * l;
    sim.inflate_to_volume(target, &StaticOptions::default())
        .with_context(|| format!("inflating to the stretch {l}"))?;
    Ok(sim)
}

/// All connected-balloon cases.
pub fn cases(opts: &Options, figs: &mut Figures) -> Vec<Case> {
    let mut cases = Vec::new();
    if let Err(e) = run(opts, figs, &mut cases) {
        cases.push(Case::error(G, "two-balloon experiment", format!("{e:#}")));
    }
    cases
}

fn run(opts: &Options, figs: &mut Figures, cases: &mut Vec<Case>) -> Result<()> {
    let mesh = icosphere(0.1, LEVEL)?;
    let radius = 3.0 * geometry::enclosed_volume(&mesh) / geometry::surface_area(&mesh);
    let sphere = ThinSphere::try_new(radius, H)?;
    let rubber = MembraneNeoHookean::try_new(MU)?;
    let scale = MU * H / radius;
    let (la, lb) = (1.35, 1.6);
    let max_steps = 5000;
    let mut paths = Vec::new();
    let conductances = if opts.quick {
        vec![Conductance::Instant]
    } else {
        vec![Conductance::Finite(5.0), Conductance::Instant]
    };
    let mut picture = None;
    for conductance in conductances {
        let label = match conductance {
            Conductance::Finite(k) => format!("tube {k} m^3/s"),
            Conductance::Instant => "instant equalisation".to_string(),
        };
        let a = balloon_at(la, 0.0)?;
        let b = balloon_at(lb, 0.45)?;
        let v0 = a.rest_gas_volume();
        let before: Vec<Vec<f64>> = vec![a.positions().to_vec(), b.positions().to_vec()];
        let ambient = a.ambient_pressure();
        let mut pair = ConnectedBalloons::new(
            vec![a, b],
            vec![Tube {
                a: 0,
                b: 1,
                conductance,
            }],
        )?;
        let total = pair.total_amount();
        let (ea, eb, ep) = sphere
            .joined_pair(&rubber, ambient, v0, total, 10.0)?
            .context("no analytic end state on opposite branches")?;
        let mut path = [Vec::new(), Vec::new()];
        let t0 = std::time::Instant::now();
        let mut last: Option<balloon::shell::connected::ConnectedStepStats> = None;
        let mut taken = 0;
        // Until the volumes settle (relative change per step below 1e-8 for 20 steps in a row).
        let mut calm = 0;
        while taken < max_steps && calm < 20 {
            let s = pair.step()?;
            taken += 1;
            for i in 0..2 {
                path[i].push(((s.volumes[i] / v0).cbrt(), s.gauge_pressures[i] / scale));
            }
            let moved = last.as_ref().map_or(f64::INFINITY, |l| {
                (0..2)
                    .map(|i| (s.volumes[i] / l.volumes[i] - 1.0).abs())
                    .fold(0.0, f64::max)
            });
            calm = if moved < 1e-8 { calm + 1 } else { 0 };
            last = Some(s);
        }
        let steps = taken;
        let seconds = t0.elapsed().as_secs_f64();
        let s = last.context("no steps")?;
        let (fa, fb) = ((s.volumes[0] / v0).cbrt(), (s.volumes[1] / v0).cbrt());
        let name =
            |what: &str| format!("two balloons ({label}, {steps} steps, {seconds:.0} s): {what}");
        cases.push(Case::relative(
            G,
            name("small one's end stretch vs analytic"),
            fa,
            ea,
            1e-3,
        ));
        cases.push(Case::relative(
            G,
            name("large one's end stretch vs analytic"),
            fb,
            eb,
            1e-3,
        ));
        cases.push(Case::relative(
            G,
            name("end gauge pressure vs analytic"),
            s.gauge_pressures[1],
            ep,
            3e-3,
        ));
        cases.push(Case::at_most(
            G,
            name("|P_small / P_large - 1| at the end"),
            (s.gauge_pressures[0] / s.gauge_pressures[1] - 1.0).abs(),
            1e-3,
        ));
        cases.push(Case::at_most(
            G,
            name("|total amount / start - 1|"),
            (pair.total_amount() / total - 1.0).abs(),
            1e-12,
        ));
        for (i, p) in path.into_iter().enumerate() {
            paths.push(Series::new(
                format!("{label}: {} balloon", ["small", "large"][i]),
                p,
                Style::Line,
                1 + paths.len(),
            ));
        }
        if picture.is_none() {
            let after: Vec<Vec<f64>> = pair
                .balloons()
                .iter()
                .map(|b| b.positions().to_vec())
                .collect();
            let tris = pair.balloons()[0].triangles().to_vec();
            picture = Some((before, after, tris, (ea, eb)));
        }
    }
    let curve: Vec<(f64, f64)> = (0..=400)
        .map(|i| {
            let l = 1.0 + 1.0 * i as f64 / 400.0;
            (l, sphere.pressure(&rubber, l) / scale)
        })
        .collect();
    let mut series = vec![Series::new("analytic thin sphere", curve, Style::Line, 0)];
    series.extend(paths);
    figs.add(
        "two_balloons_pv.png",
        "Two-balloon experiment: two equal neo-Hookean balloons (icospheres of 642 vertices) held at stretches 1.35 and 1.6, on opposite sides of the pressure maximum, then connected: the smaller one empties into the larger along the analytic curve until both have one pressure",
        |p| {
            line_chart(
                p,
                &Chart {
                    title: "Two balloons: P / (mu H / R) vs stretch",
                    x_label: "stretch l = (V / V0)^(1/3)",
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
    if let Some((before, after, tris, (ea, eb))) = picture {
        let (w, h) = (1000u32, 420u32);
        let merged = |pos: &[Vec<f64>]| -> (Vec<f64>, Vec<[usize; 3]>) {
            let n = pos[0].len() / 3;
            let x: Vec<f64> = pos.concat();
            let t: Vec<[usize; 3]> = tris
                .iter()
                .copied()
                .chain(tris.iter().map(|t| [t[0] + n, t[1] + n, t[2] + n]))
                .collect();
            (x, t)
        };
        let (xb, tb) = merged(&before);
        let (xa, ta) = merged(&after);
        let img = render_panels(
            &[(&xb, &tb), (&xa, &ta)],
            View {
                yaw: 0.0,
                pitch: 0.2,
            },
            w,
            h,
            [0.92, 0.35, 0.30],
        );
        figs.add(
            "two_balloons.png",
            "Two-balloon experiment: the pair when connected (left: stretches 1.35 and 1.6) and at the end (right)",
            |p| {
                crate::plot::image_with_caption(
                    p,
                    &img,
                    (w, h),
                    &[
                        (20, "connected: l = 1.35 and 1.60"),
                        (520, &format!("end: l = {ea:.3} and {eb:.3} (analytic)")),
                    ],
                )
            },
        )?;
    }
    Ok(())
}
