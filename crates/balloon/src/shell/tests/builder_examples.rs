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

    // A snapshot put back repeats the run from there: the same positions, gas amounts and
    // step count at once, and three steps later the positions of the first continuation (to
    // what the kept factor of the linear solver changes: the Newton tolerance).
    let saved = pair.snapshot();
    let run = |pair: &mut ConnectedBalloons<_>| {
        for _ in 0..3 {
            pair.step().unwrap();
        }
        (
            pair.merged_positions().to_vec(),
            pair.amounts(),
            pair.steps(),
        )
    };
    let at_save = (pair.merged_positions().to_vec(), pair.amounts());
    let first = run(&mut pair);
    pair.restore(&saved).unwrap();
    assert_eq!((pair.merged_positions().to_vec(), pair.amounts()), at_save);
    assert_eq!((saved.steps_taken(), pair.steps()), (1, 1));
    let again = run(&mut pair);
    assert_eq!(first.2, again.2);
    let moved = first
        .0
        .iter()
        .zip(&at_save.0)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let differ = first
        .0
        .iter()
        .zip(&again.0)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(moved > 1e-6, "the balloons did not move ({moved} m)");
    assert!(
        differ < 1e-4 * moved,
        "{differ} m apart after {moved} m of motion"
    );
    for (a, b) in first.1.iter().zip(&again.1) {
        assert!((a / b - 1.0).abs() < 1e-9, "gas amounts {a} and {b}");
    }
    // Another number of balloons is refused, and nothing changes.
    let mut single = ConnectedBalloons::new(vec![balloon(500.0)], vec![]).unwrap();
    let e = single.restore(&saved).unwrap_err().to_string();
    assert!(e.contains("snapshot of 2 balloons"), "{e}");
    assert_eq!(single.steps(), 0);
}
