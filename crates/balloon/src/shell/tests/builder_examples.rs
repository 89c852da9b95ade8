//! The examples of the running shell's methods built with [`ShellBalloon`] (their docs in
//! `balloon-shell` build the simulation from the stage crates).

use crate::gas::GasKind;
use crate::shell::statics::StaticOptions;
use crate::shell::{ShellBalloon, ShellError};

#[test]
fn pinned_vertices_stay_where_they_are() -> Result<(), Box<dyn std::error::Error>> {
    let mesh = crate::mesh::generate::icosphere(0.1, 2)?;
    let mut sim = ShellBalloon::new(mesh).build()?;
    let bottom: Vec<usize> = (0..sim.positions().len() / 3)
        .filter(|&v| sim.positions()[3 * v + 2] < -0.09)
        .collect();
    sim.set_pinned_vertices(bottom.clone())?;
    let before = sim.positions().to_vec();
    for _ in 0..5 {
        sim.step()?;
    }
    for &v in &bottom {
        assert_eq!(sim.positions()[3 * v..3 * v + 3], before[3 * v..3 * v + 3]);
    }
    Ok(())
}

#[test]
fn the_static_solve_of_an_ideal_gas_balloon_converges() -> Result<(), ShellError> {
    let mesh = crate::mesh::generate::icosphere(0.1, 2).unwrap();
    let mut sim = ShellBalloon::new(mesh)
        .with_gas(GasKind::Ideal)
        .with_gauge_pressure(3000.0)
        .build()
        .unwrap();
    let report = sim.solve_static(&StaticOptions::default())?;
    assert!(report.converged && report.relative_residual <= 1e-6);
    assert!(sim.gas_volume() > sim.rest_gas_volume());
    Ok(())
}

#[test]
fn inflating_to_a_volume_holds_the_gas_there() -> Result<(), ShellError> {
    let mut sim = ShellBalloon::new(crate::mesh::generate::icosphere(0.1, 1).unwrap())
        .with_gas(GasKind::Ideal)
        .build()
        .unwrap();
    let target = 1.2 * sim.rest_gas_volume();
    let report = sim.inflate_to_volume(target, &StaticOptions::default())?;
    assert!((sim.gas_volume() / target - 1.0).abs() < 1e-6);
    let amount = (sim.ambient_pressure() + report.gauge_pressure) * report.gas_volume;
    assert_eq!(sim.gas_amount(), Some(amount));
    Ok(())
}

#[test]
fn connected_balloons_keep_their_total_amount() {
    use crate::mesh::generate::icosphere;
    use crate::shell::connected::{Conductance, ConnectedBalloons, Tube};
    let balloon = |gauge: f64| {
        ShellBalloon::new(icosphere(0.1, 1).unwrap())
            .with_gas(GasKind::Ideal)
            .with_gauge_pressure(gauge)
            .build()
            .unwrap()
    };
    let tube = Tube {
        a: 0,
        b: 1,
        conductance: Conductance::Finite(1e-3),
    };
    let mut pair =
        ConnectedBalloons::new(vec![balloon(800.0), balloon(200.0)], vec![tube]).unwrap();
    let total = pair.total_amount();
    pair.step().unwrap();
    assert!((pair.total_amount() / total - 1.0).abs() < 1e-12);
}
