//! The coarse limit point of a rubber balloon (issue 14, items 2-3): a neo-Hookean membrane
//! sphere traced under volume control passes its pressure maximum, which sits where the
//! analytic thin sphere puts it (`docs/membranes.md` M21: `l = 7^(1/6)`,
//! `P_max = 1.2395 mu H / R`), and stays on the falling uniform branch past it. The fine version
//! (icosphere of 2562 vertices, every model, 0.5 %) runs in `cargo xtask validate`.

use balloon::gas::GasKind;
use balloon::material::membrane::{ExtremumKind, MembraneNeoHookean, ThinSphere};
use balloon::mesh::generate::icosphere;
use balloon::mesh::geometry;
use balloon::shell::ShellBalloon;
use balloon::shell::statics::{StaticControl, StaticOptions};

#[test]
fn neo_hookean_sphere_passes_its_pressure_maximum_under_volume_control() {
    let mesh = icosphere(0.1, 2).unwrap();
    let (mu, h) = (4.0e5, 1.0e-3);
    let radius = 3.0 * geometry::enclosed_volume(&mesh) / geometry::surface_area(&mesh);
    let rubber = MembraneNeoHookean::try_new(mu).unwrap();
    let sphere = ThinSphere::try_new(radius, h).unwrap();
    let analytic = sphere.extrema(&rubber, 2.0).unwrap();
    assert_eq!(analytic.len(), 1);
    assert_eq!(analytic[0].kind, ExtremumKind::Maximum);
    assert!((analytic[0].stretch - 7f64.powf(1.0 / 6.0)).abs() < 1e-9);

    let mut sim = ShellBalloon::new(mesh)
        .with_membrane(rubber)
        .with_thickness(h)
        .with_gas(GasKind::Constant)
        .with_gauge_pressure(0.0)
        .build()
        .unwrap();
    let v0 = sim.rest_gas_volume();
    // A handful of stretches across the maximum, then well past it.
    let stretches = [1.2, 1.3, 1.35, 1.4, 1.45, 1.55, 1.8];
    let mut points = Vec::new();
    let mut spreads = Vec::new();
    for &l in &stretches {
        let options = StaticOptions {
            control: StaticControl::Volume {
                target: v0 * l * l * l,
            },
            ..Default::default()
        };
        let report = sim.solve_static(&options).unwrap();
        assert!(
            report.converged && report.volume_error <= 1e-8,
            "{report:?}"
        );
        points.push(((report.gas_volume / v0).cbrt(), report.gauge_pressure));
        spreads.push(report.max_area_stretch / report.min_area_stretch - 1.0);
    }
    // The discrete maximum and the parabola through it and its neighbours.
    let i = (1..points.len() - 1)
        .max_by(|&a, &b| points[a].1.total_cmp(&points[b].1))
        .unwrap();
    assert!(points[i].1 > points[i - 1].1 && points[i].1 > points[i + 1].1);
    let [(x0, y0), (x1, y1), (x2, y2)] = [points[i - 1], points[i], points[i + 1]];
    let d01 = (y1 - y0) / (x1 - x0);
    let d12 = (y2 - y1) / (x2 - x1);
    let a = (d12 - d01) / (x2 - x0);
    let b = d01 - a * (x0 + x1);
    let l_max = -b / (2.0 * a);
    let p_max = y1 + (l_max - x1) * (d01 + a * (l_max - x0));
    let rel_l = (l_max / analytic[0].stretch - 1.0).abs();
    let rel_p = (p_max / analytic[0].pressure - 1.0).abs();
    assert!(
        rel_l < 0.02,
        "maximum at l = {l_max} vs {}",
        analytic[0].stretch
    );
    assert!(rel_p < 0.03, "P_max = {p_max} vs {}", analytic[0].pressure);
    // M21 in closed form.
    let closed = 1.2395 * mu * h / radius;
    assert!((analytic[0].pressure / closed - 1.0).abs() < 1e-4);
    // Past the maximum the pressure falls, and the sphere stays uniform (no bifurcation: the
    // spread of the area stretches stays at the mesh's own level).
    let last = points.len() - 1;
    assert!(points[last].1 < points[last - 1].1);
    let analytic_last = sphere.pressure(&rubber, points[last].0);
    assert!((points[last].1 / analytic_last - 1.0).abs() < 0.03);
    assert!(spreads.iter().all(|s| *s < 0.05), "{spreads:?}");
}

/// The stability report (issue 30, item 6) against the analytic limit point: a neo-Hookean
/// membrane sphere held at a volume is stable on both sides of its pressure maximum
/// (`l = 7^(1/6)`, no aspherical bifurcation for this material), while the same equilibrium held
/// at its pressure instead is stable before the maximum and unstable after it (`dp/dV < 0`:
/// the smallest eigenvalue of the stiffness changes sign there). The sign is the only thing the
/// analytic sphere fixes; its mode past the maximum is the uniform inflation.
#[test]
fn the_smallest_eigenvalue_changes_sign_at_the_pressure_maximum_under_pressure_control() {
    let mesh = icosphere(0.1, 2).unwrap();
    let (mu, h) = (4.0e5, 1.0e-3);
    let mut sim = ShellBalloon::new(mesh)
        .with_membrane(MembraneNeoHookean::try_new(mu).unwrap())
        .with_thickness(h)
        .with_gas(GasKind::Constant)
        .with_gauge_pressure(0.0)
        .build()
        .unwrap();
    let v0 = sim.rest_gas_volume();
    let l_max = 7f64.powf(1.0 / 6.0);
    for l in [1.25, 1.55] {
        let held_volume = sim
            .solve_static(&StaticOptions {
                control: StaticControl::Volume {
                    target: v0 * l * l * l,
                },
                stability: true,
                ..Default::default()
            })
            .unwrap();
        let by_volume = held_volume.stability.expect("asked for");
        assert!(by_volume.residual < 1e-6, "{by_volume:?}");
        assert!(
            !by_volume.unstable() && by_volume.smallest_eigenvalue > 0.0,
            "l = {l}, volume held: {by_volume:?}"
        );
        sim.set_gauge_pressure(held_volume.gauge_pressure).unwrap();
        let held_pressure = sim
            .solve_static(&StaticOptions {
                stability: true,
                ..Default::default()
            })
            .unwrap();
        // The same shape (it was already in equilibrium at that pressure).
        assert!((held_pressure.gas_volume / held_volume.gas_volume - 1.0).abs() < 1e-6);
        let by_pressure = held_pressure.stability.expect("asked for");
        assert!(by_pressure.residual < 1e-6, "{by_pressure:?}");
        assert_eq!(
            by_pressure.unstable(),
            l > l_max,
            "l = {l}, pressure held: {by_pressure:?}"
        );
        // Holding the volume can only stabilise: it removes one direction.
        assert!(by_volume.smallest_eigenvalue >= by_pressure.smallest_eigenvalue);
    }
}
