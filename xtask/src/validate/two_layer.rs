//! Two-layer elastic objects (Song 2009): measured orders of the explicit integrators, energy
//! drift of an undamped body, and the settled radii of a pressurised two-layer circle against
//! the analytic radial force balance (docs/two-layer.md).

use super::{Figures, Options};
use crate::plot::{Chart, Series, Style, line_chart};
use crate::report::{Case, loglog_slope};
use anyhow::{Context, Result};
use balloon::two_layer::analytic::CircleBody;
use balloon::two_layer::{ExplicitMethod, SpringKind, TwoLayerBody};

const G: &str = "two-layer";

/// The 1D hanging spring (Song 2009, Sec. 3.3) released at its rest length is a harmonic oscillator
/// about `L + m g / k`: `x(t) = -L - (m g / k)(1 - cos(omega t))`. The global error at t = 1 s
/// must fall like `dt^order` (Euler and symplectic Euler 1, midpoint 2, RK4 4; Song 2009, Ch. 5).
fn orders(figs: &mut Figures, cases: &mut Vec<Case>) -> Result<()> {
    let (mass, k, g, length): (f64, f64, f64, f64) = (1.0, 100.0, 9.81, 0.5);
    let omega = (k / mass).sqrt();
    let mut series = Vec::new();
    for (ci, method) in ExplicitMethod::ALL.into_iter().enumerate() {
        let mut pts = Vec::new();
        for dt in [0.004f64, 0.002, 0.001, 0.0005] {
            let body = TwoLayerBody::line(length)
                .with_masses(mass, mass)
                .with_spring(SpringKind::Structural, k, 0.0)
                .with_gravity(g);
            let mut sim = body.simulate(method, dt)?;
            sim.run((1.0 / dt).round() as usize)?;
            let t = sim.time();
            let exact = -length - mass * g / k * (1.0 - (omega * t).cos());
            let exact_v = -mass * g / k * omega * (omega * t).sin();
            let err = ((sim.positions()[3] - exact).powi(2)
                + ((sim.velocities()[3] - exact_v) / omega).powi(2))
            .sqrt();
            pts.push((dt, err));
        }
        let slope = loglog_slope(&pts);
        cases.push(Case::absolute(
            G,
            format!("hanging spring: fitted order of {method} (dt 4e-3 .. 5e-4)"),
            slope,
            method.order() as f64,
            0.3,
        ));
        series.push(Series::new(
            format!("{method} (fitted order {slope:.2})"),
            pts,
            Style::LinePoints,
            ci,
        ));
    }
    figs.add(
        "integrator_orders.png",
        "Explicit integrators: error at t = 1 s vs time step (hanging spring)",
        |p| {
            line_chart(
                p,
                &Chart {
                    title: "Hanging spring: global error at t = 1 s",
                    x_label: "time step dt (s)",
                    y_label: "error (m)",
                    log_x: true,
                    log_y: true,
                    legend_lower_right: true,
                },
                &series,
                (800, 560),
            )
        },
    )?;
    Ok(())
}

/// Largest deviation of the total energy from its start over 1.5 s, and the kinetic peak.
fn energy_drift(method: ExplicitMethod, dt: f64) -> Result<(f64, f64)> {
    let body = TwoLayerBody::octahedron_sphere(1)
        .with_radii(0.7, 1.0)
        .with_pressure(40.0, 20.0)
        .with_damping(0.0);
    let mut sim = body.simulate(method, dt)?;
    let e0 = sim.energies().total();
    let (mut drift, mut kmax) = (0.0f64, 0.0f64);
    for _ in 0..(1.5 / dt).round() as usize {
        let s = sim.step()?;
        drift = drift.max((s.total - e0).abs());
        kmax = kmax.max(s.kinetic);
    }
    Ok((drift, kmax))
}

/// Without damping or collisions every force (gravity, springs, gas `-nRT ln V`) is
/// conservative, so the total energy is constant up to the integrator's error.
fn drift(cases: &mut Vec<Case>) -> Result<()> {
    let (d1, kmax) = energy_drift(ExplicitMethod::Rk4, 1e-3)?;
    let (d2, _) = energy_drift(ExplicitMethod::Rk4, 5e-4)?;
    cases.push(Case::at_most(
        G,
        format!("undamped sphere, RK4 dt = 5e-4: max |E - E0| / max kinetic ({kmax:.2} J)"),
        d2 / kmax,
        1e-4,
    ));
    cases.push(Case::at_least(
        G,
        "undamped sphere, RK4: energy drift ratio dt 1e-3 / dt 5e-4 (4th order: 16)",
        d1 / d2,
        16.0,
        "16",
    ));
    let (ds, _) = energy_drift(ExplicitMethod::Symplectic, 2.5e-4)?;
    cases.push(Case::at_most(
        G,
        "undamped sphere, symplectic Euler dt = 2.5e-4: max |E - E0| / max kinetic",
        ds / kmax,
        0.05,
    ));
    Ok(())
}

/// Radial force balance of the 2D two-layer N-gon (docs/two-layer.md): inner radius `a`, outer
/// `b`, structural sides `2 r sin(pi/N)`, radius springs `b - a`, shear springs
/// `sqrt(a^2 + b^2 - 2ab cos(2pi/N))`, gas energy `-c ln A` with `A ~ r^2`. Solved by Newton
/// here; a damped simulation must settle at the root.
fn settling(cases: &mut Vec<Case>) -> Result<()> {
    let (nn, a0, b0) = (12usize, 0.6, 1.0);
    let (ks, kr, ksh) = (100.0, 50.0, 40.0);
    let (p_out, p_in) = (150.0, 80.0);
    let body = TwoLayerBody::circle(nn)
        .with_radii(a0, b0)
        .with_spring(SpringKind::Structural, ks, 0.4)
        .with_spring(SpringKind::Radius, kr, 0.4)
        .with_spring(SpringKind::ShearLeft, ksh, 0.4)
        .with_spring(SpringKind::ShearRight, ksh, 0.4)
        .with_pressure(p_out, p_in)
        .with_gravity(0.0);
    let (a, b) = CircleBody {
        particles: nn,
        inner_radius: a0,
        outer_radius: b0,
        structural: ks,
        radius: kr,
        shear: ksh,
        outer_pressure: p_out,
        inner_pressure: p_in,
    }
    .equilibrium_radii()
    .context("the analytic N-gon equilibrium did not converge")?;
    let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-3)?;
    sim.run(5000)?;
    let x = sim.positions();
    let mean_radius = |range: std::ops::Range<usize>| {
        let n = range.len() as f64;
        let c: [f64; 3] =
            std::array::from_fn(|k| range.clone().map(|i| x[3 * i + k]).sum::<f64>() / n);
        range
            .map(|i| {
                (0..3)
                    .map(|k| (x[3 * i + k] - c[k]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .sum::<f64>()
            / n
    };
    cases.push(Case::relative(
        G,
        "pressurised 12-gon, RK4, 5 s damped: outer radius vs force balance",
        mean_radius(nn..2 * nn),
        b,
        1e-4,
    ));
    cases.push(Case::relative(
        G,
        "pressurised 12-gon: inner radius vs force balance",
        mean_radius(0..nn),
        a,
        1e-4,
    ));
    Ok(())
}

/// All two-layer cases.
pub fn cases(_opts: &Options, figs: &mut Figures) -> Vec<Case> {
    let mut cases = Vec::new();
    eprintln!("xtask validate: two-layer");
    if let Err(e) = orders(figs, &mut cases) {
        cases.push(Case::error(G, "integrator orders", e));
    }
    if let Err(e) = drift(&mut cases) {
        cases.push(Case::error(G, "energy drift", e));
    }
    if let Err(e) = settling(&mut cases) {
        cases.push(Case::error(G, "settling radius", e));
    }
    cases
}
