//! Tests of the model constructors and checks, and of the simulation without the facade.

use crate::*;
use nalgebra::Point3;

fn octahedron(level: u32) -> TwoLayerModel {
    let mesh = balloon_mesh::generate::octahedron_sphere(1.0, level).unwrap();
    TwoLayerModel::from_unit_sphere(mesh, Point3::origin(), [0.7, 1.0], [0.01, 0.02])
}

/// The constructors lay out the paper's springs (Sec. 3.4.2, 3.5.2), measure the rest volumes
/// and pass their own check; the gas is `P V0` per layer.
#[test]
fn constructors_lay_out_the_springs_and_pass_the_check() {
    let m = octahedron(1).with_pressures(300.0, 100.0);
    // Octahedron level 1: V = 18, E = 48 per layer.
    assert_eq!(m.layer_size, 18);
    assert_eq!(m.spring_counts(), [96, 18, 48, 48]);
    assert!(m.rest_volume_outer > m.rest_volume_inner && m.rest_volume_inner > 0.0);
    assert_eq!(m.gas_outer, 300.0 * m.rest_volume_outer);
    assert_eq!(m.gas_inner, 100.0 * m.rest_volume_inner);
    m.check().unwrap();
    let ring = TwoLayerModel::circle(12, Point3::origin(), [0.8, 1.0], [0.01, 0.01]);
    assert_eq!(ring.spring_counts(), [24, 12, 12, 12]);
    ring.check().unwrap();
    let line = TwoLayerModel::line(Point3::origin(), 0.5, 0.1).with_pressures(1.0, 1.0);
    assert_eq!((line.num_particles(), line.gas_outer), (2, 0.0));
    line.check().unwrap();
}

/// Models whose arrays do not fit together are refused by name before anything is indexed.
#[test]
fn inconsistent_models_are_refused_by_name() {
    type Spoil = fn(&mut TwoLayerModel);
    let cases: [(&str, Spoil); 5] = [
        ("rest_positions / fixed", |m| {
            m.fixed.pop();
        }),
        ("masses", |m| m.masses[3] = 0.0),
        ("springs", |m| m.springs[0].b = 10_000),
        ("layer_size", |m| m.layer_size -= 1),
        ("surface", |m| m.surface[0][1] = m.layer_size),
    ];
    for (name, spoil) in cases {
        let mut m = octahedron(1);
        spoil(&mut m);
        let e = TwoLayerSimulation::new(m, TwoLayerParams::default(), ExplicitMethod::Rk4, 1e-3)
            .unwrap_err();
        assert!(e.to_string().contains(&format!("`{name}`")), "{e}");
    }
    let e = TwoLayerSimulation::new(
        octahedron(1),
        TwoLayerParams::default(),
        ExplicitMethod::Rk4,
        0.0,
    )
    .unwrap_err();
    assert!(e.to_string().contains("`dt`"), "{e}");
    let params = TwoLayerParams {
        restitution: 2.0,
        ..TwoLayerParams::default()
    };
    assert!(TwoLayerSimulation::new(octahedron(1), params, ExplicitMethod::Rk4, 1e-3).is_err());
}
