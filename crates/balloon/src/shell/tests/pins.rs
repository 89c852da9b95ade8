//! Hard pins of a running shell, dynamic and static, with every linear solver.

use crate::shell::{AnchorSpring, ShellBalloon, ShellMaterialModel};
use balloon_gas::GasKind;
use balloon_integrate::linear::LinearSolverKind;
use balloon_material::membrane::{MembraneModel, MembraneNeoHookean};

/// The vertices of a 0.1 m sphere below z = -0.08 (its "neck").
fn neck(x: &[f64]) -> Vec<usize> {
    (0..x.len() / 3).filter(|&v| x[3 * v + 2] < -0.08).collect()
}

#[test]
fn a_pinned_neck_stays_bit_for_bit_while_the_rest_inflates_with_every_solver() {
    for solver in [
        LinearSolverKind::Cholesky,
        LinearSolverKind::Pcg,
        LinearSolverKind::FactorizedPcg,
        LinearSolverKind::MatrixFreeCg,
    ] {
        let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
        let mut sim = ShellBalloon::new(mesh)
            .with_gas(GasKind::Constant)
            .with_gauge_pressure(3000.0)
            .with_linear_solver(solver)
            .configure_integrator(|p| {
                p.gravity = [0.0, 0.0, -9.81];
                p.stiffness_damping = 1e-4;
            })
            .build()
            .unwrap();
        let rest = sim.positions().to_vec();
        let pinned = neck(&rest);
        assert!(pinned.len() > 3, "{pinned:?}");
        sim.set_pinned_vertices(pinned.iter().rev().copied().chain([pinned[0]]).collect())
            .unwrap();
        assert_eq!(sim.pinned_vertices(), &pinned[..]);
        // External forces and a spring on a pinned vertex do not move it either.
        let f = vec![0.01; rest.len()];
        sim.set_external_forces(Some(&f)).unwrap();
        sim.set_anchor_springs(vec![AnchorSpring {
            vertex: pinned[0],
            anchor: [0.0, 0.0, -1.0],
            stiffness: 100.0,
        }])
        .unwrap();
        for _ in 0..10 {
            sim.step().unwrap_or_else(|e| panic!("{solver:?}: {e}"));
        }
        let x = sim.positions();
        for &v in &pinned {
            assert_eq!(x[3 * v..3 * v + 3], rest[3 * v..3 * v + 3], "{solver:?}");
            assert_eq!(sim.velocities()[3 * v..3 * v + 3], [0.0; 3]);
        }
        let top = (0..rest.len() / 3)
            .max_by(|&a, &b| rest[3 * a + 2].total_cmp(&rest[3 * b + 2]))
            .unwrap();
        assert!(
            x[3 * top + 2] > rest[3 * top + 2] + 1e-3,
            "{solver:?}: did not inflate"
        );
        assert!(
            sim.gas_volume() > 1.05 * sim.rest_gas_volume(),
            "{solver:?}"
        );
    }
}

#[test]
fn pins_hold_a_membrane_and_can_be_freed_and_are_checked() {
    let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
    let mut sim = ShellBalloon::new(mesh)
        .with_material(ShellMaterialModel::from(MembraneModel::from(
            MembraneNeoHookean::try_new(3e5).unwrap(),
        )))
        .with_gas(GasKind::Constant)
        .with_gauge_pressure(500.0)
        .build()
        .unwrap();
    let rest = sim.positions().to_vec();
    let pinned = neck(&rest);
    sim.set_pinned_vertices(pinned.clone()).unwrap();
    for _ in 0..5 {
        sim.step().unwrap();
    }
    for &v in &pinned {
        assert_eq!(sim.positions()[3 * v..3 * v + 3], rest[3 * v..3 * v + 3]);
    }
    sim.set_pinned_vertices(Vec::new()).unwrap();
    assert!(sim.pinned_vertices().is_empty());
    for _ in 0..5 {
        sim.step().unwrap();
    }
    assert!(
        pinned
            .iter()
            .any(|&v| sim.positions()[3 * v + 2] != rest[3 * v + 2])
    );
    let e = sim.set_pinned_vertices(vec![0, 100_000]).unwrap_err();
    assert!(e.to_string().contains("100000"), "{e}");
}

#[test]
fn the_static_solve_keeps_pinned_vertices_in_place() {
    let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
    let mut sim = ShellBalloon::new(mesh)
        .with_gas(GasKind::Constant)
        .with_gauge_pressure(3000.0)
        .build()
        .unwrap();
    let rest = sim.positions().to_vec();
    let pinned = neck(&rest);
    sim.set_pinned_vertices(pinned.clone()).unwrap();
    let f: Vec<f64> = (0..rest.len())
        .map(|i| if i % 3 == 0 { 0.01 } else { 0.0 })
        .collect();
    sim.set_external_forces(Some(&f)).unwrap();
    let report = sim.solve_static(&Default::default()).unwrap();
    assert!(report.converged, "{report:?}");
    for &v in &pinned {
        assert_eq!(sim.positions()[3 * v..3 * v + 3], rest[3 * v..3 * v + 3]);
    }
    assert!(sim.gas_volume() > 1.05 * sim.rest_gas_volume());
}
