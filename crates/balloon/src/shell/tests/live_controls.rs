//! The live controls of a running shell (the viewer's): external forces, `dt`, the gas
//! setters, anchor springs, the default pump.

use crate::gas::{Gas, GasKind, STANDARD_ATMOSPHERE};
use crate::integrate::linear::LinearSolverKind;
use crate::shell::{AnchorSpring, DEFAULT_PUMP_VOLUMES_PER_SECOND, ShellBalloon, ShellSimulation};
use nalgebra::Vector3;

fn small() -> ShellSimulation {
    let mesh = balloon_mesh::generate::icosphere(0.1, 1).unwrap();
    ShellBalloon::new(mesh)
        .with_gas(GasKind::Constant)
        .with_gauge_pressure(0.0)
        .with_projection(None)
        .build()
        .unwrap()
}

#[test]
fn constant_external_force_accelerates_a_free_shell_by_f_over_m() {
    let mut sim = small();
    sim.configure_integrator(|p| p.mass_damping = 0.0).unwrap();
    let n = sim.positions().len();
    let total_mass: f64 = sim.masses().iter().step_by(3).sum();
    // 1 N in total along +x, shared by mass so every vertex gets the same acceleration.
    let f: Vec<f64> = sim
        .masses()
        .iter()
        .enumerate()
        .map(|(i, m)| if i % 3 == 0 { m / total_mass } else { 0.0 })
        .collect();
    sim.set_external_forces(Some(&f)).unwrap();
    assert_eq!(sim.external_forces().len(), n);
    let steps = 5;
    for _ in 0..steps {
        sim.step().unwrap();
    }
    let mean_vx = sim.velocities().iter().step_by(3).sum::<f64>() / (n / 3) as f64;
    let expected = sim.time() / total_mass;
    assert!(
        (mean_vx - expected).abs() < 1e-3 * expected,
        "mean vx {mean_vx} vs F t / m = {expected}"
    );
    sim.set_external_forces(None).unwrap();
    assert!(sim.external_forces().is_empty());
}

#[test]
fn bad_external_forces_are_rejected() {
    let mut sim = small();
    assert!(sim.set_external_forces(Some(&[1.0])).is_err());
    let mut f = vec![0.0; sim.positions().len()];
    f[4] = f64::NAN;
    let e = sim.set_external_forces(Some(&f)).unwrap_err().to_string();
    assert!(e.contains("component 4"), "{e}");
    assert!(sim.set_dt(0.0).is_err());
    sim.set_dt(0.005).unwrap();
    assert_eq!(sim.dt(), 0.005);
}

/// The default pump delivers DEFAULT_PUMP_VOLUMES_PER_SECOND rest volumes of ambient air
/// per second whatever the body's size: read back from the ideal gas law on the state
/// (p V = p_amb V0 (1 + k t)), at 5 cm and 1 m.
#[test]
fn the_default_pump_follows_the_body_size() {
    for radius in [0.05, 1.0] {
        let mesh = balloon_mesh::generate::icosphere(radius, 1).unwrap();
        let mut sim = ShellBalloon::new(mesh).build().unwrap();
        let v0 = sim.rest_gas_volume();
        for _ in 0..3 {
            sim.step().unwrap();
        }
        let s = sim.gas_state();
        let pumped = s.absolute_pressure * s.volume / (STANDARD_ATMOSPHERE * v0) - 1.0;
        let expected = DEFAULT_PUMP_VOLUMES_PER_SECOND * sim.time();
        assert!(
            (pumped - expected).abs() < 1e-9 * expected.max(1.0),
            "radius {radius}: pumped {pumped} rest volumes, expected {expected}"
        );
        assert!(s.volume > v0, "radius {radius}: the body did not grow");
    }
    // An absolute rate stays absolute.
    let mesh = balloon_mesh::generate::icosphere(0.05, 1).unwrap();
    let mut sim = ShellBalloon::new(mesh)
        .with_pump_rate(1e-4)
        .build()
        .unwrap();
    sim.step().unwrap();
    let s = sim.gas_state();
    let pumped = s.absolute_pressure * s.volume - STANDARD_ATMOSPHERE * sim.rest_gas_volume();
    assert!((pumped - STANDARD_ATMOSPHERE * 1e-4 * sim.time()).abs() < 1e-9);
}

#[test]
fn gas_setters_act_live() {
    let mut sim = small();
    sim.set_gauge_pressure(1500.0).unwrap();
    match sim.gas() {
        Gas::Constant(c) => assert!((c.pressure - (STANDARD_ATMOSPHERE + 1500.0)).abs() < 1e-9),
        g => panic!("{g:?}"),
    }
    sim.step().unwrap();
    assert!((sim.gauge_pressure() - 1500.0).abs() < 1e-6);
    assert!(sim.set_gauge_pressure(-2.0 * STANDARD_ATMOSPHERE).is_err());
    assert!(sim.set_pump_rate(1e-3).is_err());

    let mesh = balloon_mesh::generate::icosphere(0.1, 1).unwrap();
    let mut ideal = ShellBalloon::new(mesh.clone())
        .with_gas(GasKind::Ideal)
        .build()
        .unwrap();
    ideal.set_gauge_pressure(500.0).unwrap();
    match ideal.gas() {
        Gas::Ideal(g) => {
            let want = (STANDARD_ATMOSPHERE + 500.0) * ideal.rest_gas_volume();
            assert!((g.amount() - want).abs() < 1e-9 * want);
        }
        g => panic!("{g:?}"),
    }

    let mut pump = ShellBalloon::new(mesh).with_pump_rate(0.0).build().unwrap();
    pump.step().unwrap();
    let v0 = pump.gas_volume();
    pump.set_pump_rate(2e-3).unwrap();
    let amount_then = match pump.gas() {
        Gas::Pump(p) => p.amount(pump.time()),
        g => panic!("{g:?}"),
    };
    for _ in 0..3 {
        pump.step().unwrap();
    }
    match pump.gas() {
        Gas::Pump(p) => {
            let added = p.amount(pump.time()) - amount_then;
            let want = 2e-3 * STANDARD_ATMOSPHERE * 3.0 * pump.dt();
            assert!((added - want).abs() < 1e-9 * want, "{added} vs {want}");
        }
        g => panic!("{g:?}"),
    }
    assert!(pump.gas_volume() > v0);
    assert!(pump.set_pump_rate(-1.0).is_err());
    assert!(pump.set_gauge_pressure(100.0).is_err());
}

#[test]
fn stiff_anchor_springs_pull_a_vertex_out_stably_with_every_solver() {
    for solver in [
        LinearSolverKind::Pcg,
        LinearSolverKind::Cholesky,
        LinearSolverKind::MatrixFreeCg,
    ] {
        let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
        let mut sim = ShellBalloon::new(mesh)
            .with_gas(GasKind::Constant)
            .with_gauge_pressure(1000.0)
            .with_linear_solver(solver)
            .build()
            .unwrap();
        let start = Vector3::new(sim.positions()[0], sim.positions()[1], sim.positions()[2]);
        let target = start * 1.3;
        // 1000 N/m on a vertex of ~0.2 g at dt = 10 ms: k dt^2 / m ~ 500, far beyond what an
        // explicit spring survives.
        sim.set_anchor_springs(vec![AnchorSpring {
            vertex: 0,
            anchor: target.into(),
            stiffness: 1000.0,
        }])
        .unwrap();
        for _ in 0..30 {
            sim.step().unwrap();
        }
        let x = sim.positions();
        let now = Vector3::new(x[0], x[1], x[2]);
        // A free balloon follows the vertex: it reaches the target without blowing up.
        assert!(
            (now - target).norm() < 0.5 * (start - target).norm(),
            "{solver:?}: {start:?} -> {now:?}, target {target:?}"
        );
        sim.set_anchor_springs(Vec::new()).unwrap();
        assert!(sim.anchor_springs().is_empty());
    }
    // The same spring as an explicit external force does not survive.
    let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
    let mut sim = ShellBalloon::new(mesh)
        .with_gas(GasKind::Constant)
        .with_gauge_pressure(1000.0)
        .build()
        .unwrap();
    let target: Vec<f64> = sim.positions()[..3].iter().map(|c| 1.3 * c).collect();
    let explicit = (0..30).try_for_each(|_| {
        let mut f = vec![0.0; sim.positions().len()];
        for d in 0..3 {
            f[d] = 1000.0 * (target[d] - sim.positions()[d]);
        }
        sim.set_external_forces(Some(&f))?;
        sim.step().map(|_| ())
    });
    assert!(
        explicit.is_err(),
        "the explicit spring survived: {explicit:?}"
    );
    let mesh = balloon_mesh::generate::icosphere(0.1, 1).unwrap();
    let mut sim = ShellBalloon::new(mesh).build().unwrap();
    let bad = |vertex, stiffness: f64| AnchorSpring {
        vertex,
        anchor: [0.0; 3],
        stiffness,
    };
    assert!(sim.set_anchor_springs(vec![bad(1000, 1.0)]).is_err());
    assert!(sim.set_anchor_springs(vec![bad(0, -1.0)]).is_err());
    assert!(sim.set_anchor_springs(vec![bad(0, f64::NAN)]).is_err());
}
