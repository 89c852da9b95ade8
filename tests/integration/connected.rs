//! The two-balloon experiment (issue 14, item 4): two equal neo-Hookean membrane balloons,
//! inflated on opposite sides of their pressure maximum and then connected, end where the
//! analytic thin-sphere curve puts them: the smaller one has emptied into the larger until both
//! have one pressure, with the total amount of gas unchanged.

use balloon::gas::GasKind;
use balloon::material::membrane::{MembraneNeoHookean, ThinSphere};
use balloon::mesh::generate::icosphere;
use balloon::mesh::geometry;
use balloon::shell::ShellBalloon;
use balloon::shell::connected::{Conductance, ConnectedBalloons, Tube};
use balloon::shell::statics::{StaticControl, StaticOptions};

const MU: f64 = 4.0e5;
const H: f64 = 1.0e-3;

/// A balloon at rest at stretch `l` (volume control), then holding that gas as an ideal gas.
fn balloon_at(
    l: f64,
    offset: f64,
    level: u32,
) -> balloon::shell::ShellSimulation<balloon::shell::Membrane<MembraneNeoHookean>> {
    let mut mesh = icosphere(0.1, level).unwrap();
    for v in &mut mesh.vertices {
        v.x += offset;
    }
    let mut sim = ShellBalloon::new(mesh)
        .with_membrane(MembraneNeoHookean::try_new(MU).unwrap())
        .with_thickness(H)
        .with_gas(GasKind::Ideal)
        .build()
        .unwrap();
    sim.integrator_params_mut().mass_damping = 20.0;
    let v0 = sim.rest_gas_volume();
    let report = sim
        .solve_static(&StaticOptions {
            control: StaticControl::Volume {
                target: v0 * l * l * l,
            },
            ..Default::default()
        })
        .unwrap();
    assert!(report.converged, "{report:?}");
    let amount = (sim.ambient_pressure() + report.gauge_pressure) * report.gas_volume;
    sim.set_gas_amount(amount).unwrap();
    sim
}

/// The analytic end state: stretches `(l_a, l_b)` on the rising and the falling branch of the
/// thin sphere's curve `P(l)` at one pressure, with the total amount `sum (p_amb + P) V0 l^3`
/// equal to `amount`. By bisection on `l_a` below the maximum, `l_b` above it.
fn analytic_end(
    sphere: &ThinSphere,
    rubber: &MembraneNeoHookean,
    ambient: f64,
    v0: f64,
    amount: f64,
) -> (f64, f64, f64) {
    let l_max = 7f64.powf(1.0 / 6.0);
    let p = |l: f64| sphere.pressure(rubber, l);
    // The falling branch at pressure `target`: P decreases from P_max to 0 beyond l_max.
    let falling = |target: f64| {
        let (mut lo, mut hi) = (l_max, 50.0);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if p(mid) > target { lo = mid } else { hi = mid }
        }
        0.5 * (lo + hi)
    };
    let residual = |la: f64| {
        let pa = p(la);
        let lb = falling(pa);
        (ambient + pa) * v0 * (la.powi(3) + lb.powi(3)) - amount
    };
    let (mut lo, mut hi) = (1.0 + 1e-9, l_max - 1e-9);
    assert!(
        residual(lo) * residual(hi) < 0.0,
        "no end state on opposite branches"
    );
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if residual(mid) * residual(lo) > 0.0 {
            lo = mid
        } else {
            hi = mid
        }
    }
    let la = 0.5 * (lo + hi);
    (la, falling(p(la)), p(la))
}

#[test]
fn two_balloons_on_opposite_sides_of_the_maximum_end_at_one_pressure() {
    let mesh = icosphere(0.1, 2).unwrap();
    let radius = 3.0 * geometry::enclosed_volume(&mesh) / geometry::surface_area(&mesh);
    let sphere = ThinSphere::try_new(radius, H).unwrap();
    let rubber = MembraneNeoHookean::try_new(MU).unwrap();
    // Below and above the maximum at l = 7^(1/6) = 1.383; the smaller balloon has the higher
    // pressure (4.72 kPa against 4.51 kPa on the analytic curve).
    let (la, lb) = (1.25, 1.7);
    assert!(sphere.pressure(&rubber, la) > sphere.pressure(&rubber, lb));
    for conductance in [Conductance::Finite(5.0), Conductance::Instant] {
        let a = balloon_at(la, 0.0, 2);
        let b = balloon_at(lb, 0.5, 2);
        let v0 = a.rest_gas_volume();
        let ambient = a.ambient_pressure();
        let tube = Tube {
            a: 0,
            b: 1,
            conductance,
        };
        let mut pair = ConnectedBalloons::new(vec![a, b], vec![tube]).unwrap();
        let total = pair.total_amount();
        let (ea, eb, ep) = analytic_end(&sphere, &rubber, ambient, v0, total);
        let mut last = None;
        for _ in 0..400 {
            last = Some(pair.step().unwrap());
        }
        let s = last.unwrap();
        let (fa, fb) = ((s.volumes[0] / v0).cbrt(), (s.volumes[1] / v0).cbrt());
        let what = format!(
            "{conductance:?}: end l = {fa:.5}, {fb:.5} at {:.1} / {:.1} Pa; analytic {ea:.5}, {eb:.5} at {ep:.1} Pa",
            s.gauge_pressures[0], s.gauge_pressures[1]
        );
        // The smaller balloon emptied into the larger one...
        assert!(fa < la - 0.03 && fb > lb + 0.015, "{what}");
        // ...until the pressures are equal, with the amount of gas conserved...
        assert!((pair.total_amount() / total - 1.0).abs() < 1e-12, "{what}");
        assert!(
            (s.gauge_pressures[0] / s.gauge_pressures[1] - 1.0).abs() < 1e-3,
            "{what}"
        );
        // ...at the analytic end state (l = 1.2039, 1.7245 at 4.53 kPa).
        assert!((fa / ea - 1.0).abs() < 1e-3, "{what}");
        assert!((fb / eb - 1.0).abs() < 1e-3, "{what}");
        assert!((s.gauge_pressures[1] / ep - 1.0).abs() < 3e-3, "{what}");
    }
}

#[test]
fn invalid_connections_are_refused_with_the_tube_or_balloon_named() {
    let a = balloon_at(1.1, 0.0, 1);
    let b = balloon_at(1.1, 0.5, 1);
    let tube = |a, b, conductance| Tube { a, b, conductance };
    let err = ConnectedBalloons::new(vec![a, b], vec![tube(0, 2, Conductance::Instant)])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("tube 0") && err.contains("there are 2"),
        "{err}"
    );
    let (a, b) = (balloon_at(1.1, 0.0, 1), balloon_at(1.1, 0.5, 1));
    let err = ConnectedBalloons::new(vec![a, b], vec![tube(0, 1, Conductance::Finite(-1.0))])
        .unwrap_err()
        .to_string();
    assert!(err.contains("conductance -1"), "{err}");
    let constant = ShellBalloon::new(icosphere(0.1, 1).unwrap())
        .with_membrane(MembraneNeoHookean::try_new(MU).unwrap())
        .with_thickness(H)
        .with_gas(GasKind::Constant)
        .build()
        .unwrap();
    let err = ConnectedBalloons::new(vec![balloon_at(1.1, 0.0, 1), constant], vec![])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("balloon 1") && err.contains("ideal gas"),
        "{err}"
    );
}
