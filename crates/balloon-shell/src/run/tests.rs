//! Tests of the running shell built from its parts (the `balloon` facade's tests run it
//! through the builder).

use balloon_gas::{Gas, IdealGas, PressureLoad, STANDARD_ATMOSPHERE};
use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
use balloon_material::{Lame, StVenantKirchhoff};

use crate::{ShellError, ShellSimulation, ShellSystem};

pub(super) fn parts() -> (ShellSystem<StVenantKirchhoff, Gas>, Vec<f64>, BackwardEuler) {
    parts_of(1)
}

/// [`parts`] on the icosphere of `subdivisions`.
fn parts_of(subdivisions: u32) -> (ShellSystem<StVenantKirchhoff, Gas>, Vec<f64>, BackwardEuler) {
    let mesh = balloon_mesh::generate::icosphere(0.1, subdivisions).unwrap();
    let x = mesh.positions_flat();
    let v0 = balloon_gas::enclosed_volume(&x, &mesh.triangles).unwrap();
    let gas = Gas::Ideal(IdealGas::try_new(STANDARD_ATMOSPHERE + 1000.0, v0).unwrap());
    let load = PressureLoad::new(gas)
        .with_ambient_pressure(STANDARD_ATMOSPHERE)
        .unwrap();
    let material = StVenantKirchhoff::new(Lame::try_from_young_poisson(1e6, 0.45).unwrap());
    let h = vec![3e-4; mesh.num_triangles()];
    let system =
        ShellSystem::from_rest_shape(&x, mesh.triangles.clone(), h, 950.0, material, load).unwrap();
    let integrator = BackwardEuler::new(BackwardEulerParams::default()).unwrap();
    (system, x, integrator)
}

fn refused_parameter(e: ShellError) -> &'static str {
    match e {
        ShellError::InvalidParameter { name, .. } => name,
        e => panic!("not an invalid parameter: {e}"),
    }
}

/// The constructor refuses parts that do not fit, naming the parameter; a good set starts at
/// rest at the rest shape.
#[test]
fn the_constructor_checks_its_parts() {
    let (system, mut x, integrator) = parts();
    x.pop();
    let e = ShellSimulation::new(system, x, 950.0, integrator, None, 0.01, 10).unwrap_err();
    assert_eq!(refused_parameter(e), "rest_positions");
    let (system, x, integrator) = parts();
    let e = ShellSimulation::new(system, x, 0.0, integrator, None, 0.01, 10).unwrap_err();
    assert_eq!(refused_parameter(e), "density");
    let (system, x, integrator) = parts();
    let e = ShellSimulation::new(system, x, 950.0, integrator, None, f64::NAN, 10).unwrap_err();
    assert_eq!(refused_parameter(e), "dt");
    let (system, x, integrator) = parts();
    let sim = ShellSimulation::new(system, x.clone(), 950.0, integrator, None, 0.01, 10).unwrap();
    assert_eq!(sim.positions(), &x[..]);
    assert_eq!(sim.rest_positions(), &x[..]);
    assert!(sim.velocities().iter().all(|&v| v == 0.0));
    assert_eq!((sim.time(), sim.steps_taken(), sim.dt()), (0.0, 0, 0.01));
    assert_eq!(sim.gas_volume(), sim.rest_gas_volume());
    assert!((sim.shell_volume() / sim.rest_shell_volume() - 1.0).abs() < 1e-15);
}

/// Settings refused by the decorators and the integrator name the setting by its Rust name.
#[test]
fn refused_settings_are_named() {
    let (system, x, integrator) = parts();
    let mut sim = ShellSimulation::new(system, x, 950.0, integrator, None, 0.01, 10).unwrap();
    let e = sim.set_pinned_vertices(vec![0, 10_000]).unwrap_err();
    assert!(e.to_string().contains("`pinned_vertices` = 10000"), "{e}");
    let spring = balloon_integrate::decorators::AnchorSpring {
        vertex: 0,
        anchor: [0.0; 3],
        stiffness: -1.0,
    };
    let e = sim.set_anchor_springs(vec![spring]).unwrap_err();
    assert_eq!(refused_parameter(e), "anchor_springs");
    let e = sim
        .configure_integrator(|p| p.newton_iterations = 0)
        .unwrap_err();
    assert_eq!(refused_parameter(e), "newton_iterations");
    let e = sim.set_gas_amount(-1.0).unwrap_err();
    assert_eq!(refused_parameter(e), "gas_amount");
    let e = sim.set_pump_rate(1.0).unwrap_err();
    assert!(e.to_string().contains("`pump_rate`"), "{e}");
    sim.step().unwrap();
}

/// A snapshot put back repeats the run from there bit for bit (the matrix-free solver keeps
/// nothing between steps): positions, thickness, gas, time and step count after three more
/// steps are the ones of the first continuation. A snapshot of another mesh is refused.
#[test]
fn a_restored_snapshot_repeats_the_run_from_there() {
    let (system, x, integrator) = parts();
    let mut sim = ShellSimulation::new(system, x, 950.0, integrator, None, 0.01, 10).unwrap();
    for _ in 0..3 {
        sim.step().unwrap();
    }
    let saved = sim.snapshot();
    assert_eq!((saved.steps_taken(), saved.time()), (3, sim.time()));
    let run = |sim: &mut ShellSimulation<StVenantKirchhoff, Gas>| {
        for _ in 0..3 {
            sim.step().unwrap();
        }
        (
            sim.positions().to_vec(),
            sim.velocities().to_vec(),
            sim.thickness().to_vec(),
            sim.gas_volume(),
            sim.gauge_pressure(),
            sim.time(),
            sim.steps_taken(),
        )
    };
    let first = run(&mut sim);
    assert_ne!(first.0, saved.positions(), "the run did not move");
    sim.restore(&saved).unwrap();
    assert_eq!(sim.positions(), saved.positions());
    assert_eq!(sim.steps_taken(), 3);
    let again = run(&mut sim);
    assert_eq!(first, again);

    let (other, x, integrator) = parts_of(2);
    let mut other = ShellSimulation::new(other, x, 950.0, integrator, None, 0.01, 10).unwrap();
    let before = other.positions().to_vec();
    let e = other.restore(&saved).unwrap_err();
    assert_eq!(refused_parameter(e), "snapshot");
    assert_eq!(other.positions(), &before[..]);
}
