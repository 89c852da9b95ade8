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
use balloon::shell::statics::StaticOptions;

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
    sim.configure_integrator(|p| p.mass_damping = 5.0).unwrap();
    let target = sim.rest_gas_volume() * l * l * l;
    sim.inflate_to_volume(target, &StaticOptions::default())
        .unwrap();
    sim
}

#[test]
fn two_balloons_on_opposite_sides_of_the_maximum_end_at_one_pressure() {
    let mesh = icosphere(0.1, 2).unwrap();
    let radius = 3.0 * geometry::enclosed_volume(&mesh) / geometry::surface_area(&mesh);
    let sphere = ThinSphere::try_new(radius, H).unwrap();
    let rubber = MembraneNeoHookean::try_new(MU).unwrap();
    // Below and above the maximum at l = 7^(1/6) = 1.383; the smaller balloon has the higher
    // pressure (4.95 kPa against 4.70 kPa on the analytic curve).
    let (la, lb) = (1.35, 1.6);
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
        // The analytic end state (ThinSphere::joined_pair, checked against the closed form).
        let (ea, eb, ep) = sphere
            .joined_pair(&rubber, ambient, v0, total, 10.0)
            .unwrap()
            .expect("an end state on opposite branches");
        // Until the volumes settle (relative change per step below 1e-8, 20 steps in a row).
        let mut last: Option<balloon::shell::connected::ConnectedStepStats> = None;
        let mut calm = 0;
        while calm < 20 {
            let s = pair.step().unwrap();
            assert!(s.step < 3000, "not settled after 3000 steps");
            let moved = last.as_ref().map_or(f64::INFINITY, |l| {
                (0..2)
                    .map(|i| (s.volumes[i] / l.volumes[i] - 1.0).abs())
                    .fold(0.0, f64::max)
            });
            calm = if moved < 1e-8 { calm + 1 } else { 0 };
            last = Some(s);
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
        // ...at the analytic end state.
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

#[test]
fn inflating_to_a_volume_needs_the_ideal_gas_and_a_positive_target() {
    let mut constant = ShellBalloon::new(icosphere(0.1, 1).unwrap())
        .with_membrane(MembraneNeoHookean::try_new(MU).unwrap())
        .with_thickness(H)
        .with_gas(GasKind::Constant)
        .build()
        .unwrap();
    let v0 = constant.rest_gas_volume();
    let err = constant
        .inflate_to_volume(1.2 * v0, &StaticOptions::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("`gas`") && err.contains("ideal gas"), "{err}");
    let mut ideal = balloon_at(1.0 + 1e-9, 0.0, 1);
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let err = ideal
            .inflate_to_volume(bad, &StaticOptions::default())
            .unwrap_err()
            .to_string();
        assert!(err.contains("target volume"), "{bad}: {err}");
    }
    // At the target, the balloon holds exactly the gas that keeps it there: a dynamic step
    // from rest barely moves it.
    let target = 1.25 * ideal.rest_gas_volume();
    let report = ideal
        .inflate_to_volume(target, &StaticOptions::default())
        .unwrap();
    assert!((ideal.gas_volume() / target - 1.0).abs() < 1e-7);
    assert_eq!(
        ideal.gas_amount(),
        Some((ideal.ambient_pressure() + report.gauge_pressure) * report.gas_volume)
    );
    ideal.step().unwrap();
    assert!((ideal.gas_volume() / target - 1.0).abs() < 1e-6);
}

#[test]
fn connected_balloons_step_through_the_simulation_trait_as_one_surface() {
    use balloon::Simulation;
    let (a, b) = (balloon_at(1.2, 0.0, 1), balloon_at(1.4, 0.5, 1));
    let (na, nb) = (a.positions().len(), b.positions().len());
    let (ta, tb) = (a.triangles().len(), b.triangles().len());
    let tube = Tube {
        a: 0,
        b: 1,
        conductance: Conductance::Finite(1.0),
    };
    let mut pair = ConnectedBalloons::new(vec![a, b], vec![tube]).unwrap();
    assert_eq!(pair.vertex_offsets(), vec![0, na / 3, (na + nb) / 3]);
    let s = Simulation::step(&mut pair).unwrap();
    assert_eq!((s.steps, Simulation::steps(&pair)), (1, 1));
    assert_eq!(s.detail.stretches, pair.stretches());
    assert!((s.detail.total_amount / pair.total_amount() - 1.0).abs() < 1e-15);
    // The merged surface is the balloons' own positions, one after the other.
    let surface = pair.surface();
    assert_eq!(surface.positions.len(), na + nb);
    assert_eq!(surface.triangles.len(), ta + tb);
    assert_eq!(&surface.positions[na..], pair.balloons()[1].positions());
    assert!(
        surface.triangles[ta..]
            .iter()
            .flatten()
            .all(|&i| i >= na / 3)
    );
    assert_eq!(Simulation::velocities(&pair).len(), na + nb);
    let ke: f64 = pair.balloons().iter().map(Simulation::kinetic_energy).sum();
    assert_eq!(Simulation::kinetic_energy(&pair), ke);
    // One dt for all, refused as the shell refuses it.
    Simulation::set_dt(&mut pair, 0.005).unwrap();
    assert!(pair.balloons().iter().all(|b| b.dt() == 0.005));
    assert!(Simulation::set_dt(&mut pair, -1.0).is_err());
    assert!(pair.balloons().iter().all(|b| b.dt() == 0.005));
}
