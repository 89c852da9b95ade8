//! The static rest shape (`ShellSimulation::solve_static`): against the analytic sphere, against
//! the rest shape of the dynamic run, under each gas control, and the thickness rule at rest.

use balloon::gas::GasKind;
use balloon::material::{Lame, StVenantKirchhoff};
use balloon::mesh::generate::icosphere;
use balloon::mesh::generate::teddy::{TeddyParams, teddy};
use balloon::mesh::{TriMesh, geometry};
use balloon::shell::analytic::sphere_stretch;
use balloon::shell::statics::{StaticControl, StaticOptions};
use balloon::shell::{ShellBalloon, ShellError, ShellSimulation};
use balloon_tests::{bbox_diagonal, max_vertex_distance};

fn material() -> StVenantKirchhoff {
    StVenantKirchhoff::new(Lame::try_from_young_poisson(1.0e6, 0.45).unwrap())
}

fn effective_radius(mesh: &TriMesh) -> f64 {
    3.0 * geometry::enclosed_volume(mesh) / geometry::surface_area(mesh)
}

fn build(mesh: TriMesh, gas: GasKind, pressure: f64) -> ShellSimulation<StVenantKirchhoff> {
    ShellBalloon::new(mesh)
        .with_material(material())
        .with_gas(gas)
        .with_gauge_pressure(pressure)
        .build()
        .unwrap()
}

/// Dynamic steps until the shape stops moving (the library form of `--until-converged`, tighter).
fn settle_dynamic(sim: &mut ShellSimulation<StVenantKirchhoff>, max_steps: usize) -> usize {
    let mut last = sim.positions().to_vec();
    let l = bbox_diagonal(&last);
    for n in 0..max_steps {
        sim.step().unwrap();
        let moved = sim
            .positions()
            .iter()
            .zip(&last)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        if moved < 1e-8 * l {
            return n + 1;
        }
        last.copy_from_slice(sim.positions());
    }
    panic!("the dynamic run did not settle in {max_steps} steps");
}

#[test]
fn static_sphere_matches_the_analytic_stretch_at_constant_pressure() {
    let mesh = icosphere(0.1, 3).unwrap();
    let r = effective_radius(&mesh);
    for p in [1000.0, 3000.0] {
        let mut sim = build(mesh.clone(), GasKind::Constant, p);
        let report = sim.solve_static(&StaticOptions::default()).unwrap();
        assert!(
            report.converged && report.relative_residual <= 1e-6,
            "{report:?}"
        );
        let lambda = (sim.gas_volume() / sim.rest_gas_volume()).cbrt();
        let expected = sphere_stretch(&material(), 3e-4, r, p).unwrap();
        assert!(
            (lambda / expected - 1.0).abs() < 2e-3,
            "p = {p}: stretch {lambda} vs analytic {expected}"
        );
        // The energy fell at every accepted iterate of the last solve.
        let e = &report.last_solve.energies;
        assert!(
            e.windows(2).all(|w| w[1] <= w[0] + 1e-12 * w[0].abs()),
            "{e:?}"
        );
        // The thickness rule at rest: the projection of the result keeps its thickness, and
        // the shell's material volume is the rest one.
        assert!(report.thickness_change <= 1e-8, "{report:?}");
        assert!((report.shell_volume_ratio - 1.0).abs() < 1e-6, "{report:?}");
        let h = sim.thickness()[0];
        assert!((h / (3e-4 / (lambda * lambda)) - 1.0).abs() < 1e-2, "h {h}");
        assert!(sim.velocities().iter().all(|v| *v == 0.0));
    }
}

#[test]
fn static_and_dynamic_rest_shapes_agree_on_the_sphere() {
    let mesh = icosphere(0.1, 3).unwrap();
    let mut dynamic = build(mesh.clone(), GasKind::Ideal, 2000.0);
    dynamic.set_dt(0.05).unwrap();
    settle_dynamic(&mut dynamic, 2000);
    let mut stat = build(mesh, GasKind::Ideal, 2000.0);
    let report = stat.solve_static(&StaticOptions::default()).unwrap();
    let l = bbox_diagonal(dynamic.positions());
    let d = max_vertex_distance(dynamic.positions(), stat.positions());
    assert!(
        d <= 1e-4 * l,
        "static vs dynamic: {d:e} m of {l} m ({report:?})"
    );
    assert!((report.gauge_pressure - dynamic.gauge_pressure()).abs() < 1e-3 * 2000.0);
}

#[test]
fn static_and_dynamic_rest_shapes_agree_on_the_coarse_teddy() {
    let mesh = teddy(&TeddyParams {
        resolution: 14,
        ..TeddyParams::default()
    })
    .unwrap();
    let mut dynamic = build(mesh.clone(), GasKind::Ideal, 2000.0);
    dynamic.set_dt(0.05).unwrap();
    settle_dynamic(&mut dynamic, 3000);
    let mut stat = build(mesh, GasKind::Ideal, 2000.0);
    let report = stat.solve_static(&StaticOptions::default()).unwrap();
    assert!(report.converged, "{report:?}");
    let l = bbox_diagonal(dynamic.positions());
    let d = max_vertex_distance(dynamic.positions(), stat.positions());
    assert!(
        d <= 1e-4 * l,
        "static vs dynamic: {d:e} m of {l} m ({report:?})"
    );
}

#[test]
fn volume_control_reports_the_pressure_that_holds_that_volume() {
    let mesh = icosphere(0.1, 3).unwrap();
    // Pressure control first: the volume it reaches.
    let mut by_pressure = build(mesh.clone(), GasKind::Constant, 2500.0);
    by_pressure.solve_static(&StaticOptions::default()).unwrap();
    let v = by_pressure.gas_volume();
    // Volume control at that volume (the simulation's own gas is ignored): the multiplier is
    // the pressure.
    let mut by_volume = build(mesh, GasKind::Ideal, 0.0);
    let report = by_volume
        .solve_static(&StaticOptions {
            control: StaticControl::Volume { target: v },
            ..Default::default()
        })
        .unwrap();
    assert!(report.volume_error <= 1e-8, "{report:?}");
    assert!(
        (report.gauge_pressure - 2500.0).abs() < 1e-4 * 2500.0,
        "{report:?}"
    );
    let d = max_vertex_distance(by_pressure.positions(), by_volume.positions());
    assert!(d < 1e-6 * bbox_diagonal(by_volume.positions()), "{d:e}");
}

#[test]
fn the_papers_gas_without_ambient_converges_with_continuation_or_directly() {
    // The paper's own gas (ideal, no ambient) at a high initial pressure, from the rest shape.
    let mesh = icosphere(0.1, 2).unwrap();
    let mut sim = ShellBalloon::new(mesh)
        .with_material(material())
        .with_gas(GasKind::Ideal)
        .with_ambient_pressure(0.0)
        .with_gauge_pressure(28_000.0)
        .build()
        .unwrap();
    let report = sim.solve_static(&StaticOptions::default()).unwrap();
    assert!(report.relative_residual <= 1e-6, "{report:?}");
    // The gas volume grew (no collapse), and the gas law holds: p V = p0 V0.
    assert!(sim.gas_volume() > sim.rest_gas_volume());
    let pv = report.gauge_pressure * report.gas_volume;
    assert!((pv / (28_000.0 * sim.rest_gas_volume()) - 1.0).abs() < 1e-9);
    // The same from measurements that do not go through the gas state: the volume the mesh
    // encloses and the pressure its forces imply.
    let v = balloon_tests::mesh_volume(sim.positions(), sim.triangles());
    let v0 = balloon_tests::mesh_volume(sim.rest_positions(), sim.triangles());
    let p = balloon_tests::implied_gauge_pressure(&sim);
    assert!(
        (p * v / (28_000.0 * v0) - 1.0).abs() < 1e-6,
        "pV = {} against p0 V0 = {}",
        p * v,
        28_000.0 * v0
    );
}

#[test]
fn static_solve_refuses_anchor_springs_and_bad_targets() {
    let mesh = icosphere(0.1, 1).unwrap();
    let mut sim = build(mesh, GasKind::Constant, 1000.0);
    let e = sim
        .solve_static(&StaticOptions {
            control: StaticControl::Volume { target: -1.0 },
            ..Default::default()
        })
        .unwrap_err();
    assert!(matches!(e, ShellError::InvalidParameter { .. }), "{e}");
    sim.set_anchor_springs(vec![balloon::shell::AnchorSpring {
        vertex: 0,
        anchor: [0.0; 3],
        stiffness: 1.0,
    }])
    .unwrap();
    assert!(sim.solve_static(&StaticOptions::default()).is_err());
}

/// Any pair of solver and thickness tolerances converges, to a shape as close to the tight
/// solution as the looser of the two asks: a thickness tolerance above ten times the solver's
/// once kept the outer loop from ever asking for the solver's tolerance (60 outer iterations,
/// then `StaticNotConverged` with both tests met), and one above 1e-2 panicked in `clamp`.
#[test]
fn static_solve_converges_for_any_pair_of_tolerances() {
    let mesh = icosphere(0.1, 2).unwrap();
    let solve = |solver_tolerance: f64, thickness_tolerance: f64| {
        let mut sim = build(mesh.clone(), GasKind::Ideal, 3000.0);
        let mut options = StaticOptions {
            thickness_tolerance,
            ..Default::default()
        };
        options.solver.tolerance = solver_tolerance;
        let report = sim.solve_static(&options).unwrap_or_else(|e| {
            panic!("tolerances {solver_tolerance:e}/{thickness_tolerance:e}: {e}")
        });
        (report, sim.positions().to_vec())
    };
    let (tight, x_tight) = solve(1e-10, 1e-11);
    let l = bbox_diagonal(&x_tight);
    for (solver_tolerance, thickness_tolerance, shape) in [
        (1e-6, 1e-5, 1e-5),
        (1e-6, 1e-4, 1e-4),
        (1e-3, 1e-2, 1e-2),
        (1e-2, 0.5, 0.1),
    ] {
        let (report, x) = solve(solver_tolerance, thickness_tolerance);
        let d = max_vertex_distance(&x, &x_tight) / l;
        eprintln!(
            "tolerances {solver_tolerance:e}/{thickness_tolerance:e}: outer {}, Newton {}, shape {d:.2e}",
            report.outer_iterations, report.newton_iterations
        );
        assert!(report.converged);
        assert!(
            report.outer_iterations <= tight.outer_iterations,
            "looser tolerances took {} outer iterations, the tight ones {}",
            report.outer_iterations,
            tight.outer_iterations
        );
        assert!(
            d < shape,
            "shape {d:e} of the diagonal from the tight solution"
        );
    }
}

/// The static Newton's linear solves are inexact (`StaticParams::inexact_forcing`): on the
/// peer sphere (level 4) the kept factor's CG takes about one iteration per Newton step (11 for
/// 10; 20 with `inexact_forcing = 0`, every solve to `1e-8`), and the rest shape is the one of
/// exact direct solves.
#[test]
fn inexact_static_newton_keeps_the_rest_shape_of_exact_solves() {
    use balloon::integrate::linear::LinearSolverKind;
    let solve = |kind: LinearSolverKind, forcing: f64| {
        let mut sim = balloon_tests::peer_sphere(4).unwrap().build().unwrap();
        let mut options = StaticOptions::default();
        options.solver.solver.linear.kind = kind;
        options.solver.inexact_forcing = forcing;
        let report = sim.solve_static(&options).unwrap();
        (report, sim.positions().to_vec())
    };
    let (direct, x_direct) = solve(LinearSolverKind::Cholesky, 0.1);
    let (tight, _) = solve(LinearSolverKind::FactorizedPcg, 0.0);
    let (inexact, x) = solve(LinearSolverKind::FactorizedPcg, 0.1);
    let d = max_vertex_distance(&x, &x_direct) / bbox_diagonal(&x_direct);
    eprintln!(
        "direct: Newton {}; forcing 0: Newton {}, CG {}; forcing 0.1: Newton {}, CG {}; shape {d:.2e}",
        direct.newton_iterations,
        tight.newton_iterations,
        tight.linear_iterations,
        inexact.newton_iterations,
        inexact.linear_iterations
    );
    assert!(d < 1e-7, "rest shapes differ by {d:e} of the diagonal");
    assert!(
        inexact.newton_iterations <= direct.newton_iterations + 1,
        "inexact solves cost Newton iterations: {} against {}",
        inexact.newton_iterations,
        direct.newton_iterations
    );
    assert!(
        2 * inexact.linear_iterations <= 3 * inexact.newton_iterations
            && inexact.linear_iterations < tight.linear_iterations,
        "{} CG iterations for {} Newton iterations ({} with forcing 0)",
        inexact.linear_iterations,
        inexact.newton_iterations,
        tight.linear_iterations
    );
}

/// A free body's static solve keeps its rigid motions out of the Newton directions
/// (`StaticParams::remove_rigid_motions`, set by the shell when nothing is pinned): its mass
/// centre stays where it was to round-off, though the default preconditioner is rounded to
/// single precision (which, unremoved, moves the peer sphere by about 1e-7 of its diagonal),
/// and the shape is the direct solve's.
#[test]
fn a_free_body_static_solve_keeps_its_mass_centre() {
    use balloon::integrate::linear::LinearSolverKind;
    let centre = |sim: &ShellSimulation<StVenantKirchhoff>| {
        let (x, m) = (sim.positions(), sim.masses());
        let total: f64 = m.iter().step_by(3).sum();
        let mut c = [0.0; 3];
        for (p, w) in x.chunks_exact(3).zip(m.chunks_exact(3)) {
            for d in 0..3 {
                c[d] += w[d] * p[d] / total;
            }
        }
        c
    };
    let mut sim = build(icosphere(0.1, 3).unwrap(), GasKind::Ideal, 2000.0);
    let before = centre(&sim);
    let report = sim.solve_static(&StaticOptions::default()).unwrap();
    assert!(report.converged, "{report:?}");
    let l = bbox_diagonal(sim.positions());
    let after = centre(&sim);
    let moved = (0..3)
        .map(|d| (after[d] - before[d]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(
        moved <= 1e-13 * l,
        "the mass centre moved by {moved:e} m of {l} m"
    );
    let mut direct = build(icosphere(0.1, 3).unwrap(), GasKind::Ideal, 2000.0);
    let mut options = StaticOptions::default();
    options.solver.solver.linear.kind = LinearSolverKind::Cholesky;
    direct.solve_static(&options).unwrap();
    let d = max_vertex_distance(sim.positions(), direct.positions());
    assert!(d <= 1e-7 * l, "{d:e} m from the direct solve's shape");
}
