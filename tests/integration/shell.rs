//! Shell balloons end to end (Wang et al. 2015): analytic sphere, gas law, volume projection over a
//! long run, thickness effects, bad input and divergence.

use balloon::gas::GasKind;
use balloon::integrate::linear::LinearSolverKind;
use balloon::material::{Lame, Material, NeoHookean, StVenantKirchhoff};
use balloon::mesh::generate::teddy::{TeddyParams, TeddyPart, teddy, teddy_vertex_parts};
use balloon::mesh::generate::{icosphere, uv_sphere};
use balloon::mesh::{TriMesh, geometry};
use balloon::shell::analytic::{sphere_pressure, sphere_stretch};
use balloon::shell::{ShellBalloon, ShellError, ShellSimulation};

fn lame() -> Lame {
    Lame::try_from_young_poisson(1.0e6, 0.45).unwrap()
}

/// `R = 3 V0 / A0` of a mesh: the radius for which the analytic sphere is exact on the mesh.
fn effective_radius(mesh: &TriMesh) -> f64 {
    3.0 * geometry::enclosed_volume(mesh) / geometry::surface_area(mesh)
}

/// Quasi-static constant-pressure inflation: large implicit steps with the direct solver until
/// the stretch stops changing. Returns the simulation.
fn settle<M: Material>(sim: &mut ShellSimulation<M>, max_steps: usize) {
    let mut last = 0.0;
    for _ in 0..max_steps {
        let s = sim.step().unwrap();
        if (s.gas_volume - last).abs() < 1e-9 * s.gas_volume {
            return;
        }
        last = s.gas_volume;
    }
    panic!(
        "did not settle in {max_steps} steps (last volume change {:e})",
        sim.gas_volume() - last
    );
}

fn check_sphere_against_analytic<M: Material>(material: M, pressures: &[f64], max_steps: usize) {
    // 2562-vertex icosphere (level 4), as the issue asks.
    let mesh = icosphere(0.1, 4).unwrap();
    assert_eq!(mesh.num_vertices(), 2562);
    let r = effective_radius(&mesh);
    let h0 = 3.0e-4;
    for &p in pressures {
        let mut sim = ShellBalloon::new(mesh.clone())
            .with_material(material.clone())
            .with_thickness(h0)
            .with_gas(GasKind::Constant)
            .with_gauge_pressure(p)
            .with_linear_solver(LinearSolverKind::Cholesky)
            .with_dt(1.0)
            .build()
            .unwrap();
        settle(&mut sim, max_steps);
        let lambda = (sim.gas_volume() / sim.rest_gas_volume()).cbrt();
        let expected = sphere_stretch(&material, h0, r, p).expect("pressure below the limit point");
        let rel = (lambda - 1.0 - (expected - 1.0)).abs() / (expected - 1.0);
        // Compare the stretch itself within 0.5% (and the strain within 3%).
        assert!(
            (lambda / expected - 1.0).abs() < 5e-3,
            "p = {p}: simulated stretch {lambda}, analytic {expected}"
        );
        assert!(
            rel < 3e-2,
            "p = {p}: strain {} vs analytic {}",
            lambda - 1.0,
            expected - 1.0
        );
        // The projection keeps the material volume, so the thickness is H / lambda^2.
        let h_mean = sim.thickness().iter().sum::<f64>() / sim.thickness().len() as f64;
        assert!(
            (h_mean / (h0 / (lambda * lambda)) - 1.0).abs() < 1e-3,
            "thickness {h_mean}"
        );
    }
}

#[test]
fn stvk_sphere_matches_the_analytic_stretch_at_three_pressures() {
    check_sphere_against_analytic(StVenantKirchhoff::new(lame()), &[500.0, 1500.0, 3000.0], 60);
}

#[test]
fn neo_hookean_sphere_matches_the_analytic_stretch_below_the_limit_point() {
    // p_max = 4 mu H / (3 sqrt 3 R) ~ 800 Pa for these parameters; near it the curve is flat
    // and the quasi-static iteration converges slowly, so stay at half of it and below.
    check_sphere_against_analytic(NeoHookean::new(lame()), &[150.0, 400.0], 200);
}

/// The per-element projection scope keeps every element's material volume, so each thickness
/// is `H A0_e / A_e` and a uniformly stretched sphere stays uniformly thin; with the paper's
/// global constraint the same run leaves the thicknesses spread (measured, not asserted: it
/// depends on the path).
#[test]
fn per_element_projection_gives_every_element_its_own_incompressible_thickness() {
    use balloon::constraint::shell_volume::{ProjectionScope, ShellVolumeParams};
    let mesh = icosphere(0.1, 3).unwrap();
    let r = effective_radius(&mesh);
    let (h0, p) = (3.0e-4, 3000.0);
    let material = StVenantKirchhoff::new(lame());
    let mut sim = ShellBalloon::new(mesh.clone())
        .with_material(material)
        .with_thickness(h0)
        .with_gas(GasKind::Constant)
        .with_gauge_pressure(p)
        .with_linear_solver(LinearSolverKind::Cholesky)
        .with_projection(Some(ShellVolumeParams {
            scope: ProjectionScope::PerElement,
            ..Default::default()
        }))
        .with_dt(1.0)
        .build()
        .unwrap();
    settle(&mut sim, 2000);
    let x = sim.positions();
    let x0 = sim.rest_positions();
    let area = |x: &[f64], t: &[usize; 3]| {
        let v = |i: usize| nalgebra::Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
        0.5 * (v(t[1]) - v(t[0])).cross(&(v(t[2]) - v(t[0]))).norm()
    };
    for (e, t) in sim.triangles().iter().enumerate() {
        let want = h0 * area(x0, t) / area(x, t);
        assert!(
            (sim.thickness()[e] / want - 1.0).abs() < 1e-12,
            "element {e}: {} vs {want}",
            sim.thickness()[e]
        );
    }
    assert!((sim.shell_volume() / sim.rest_shell_volume() - 1.0).abs() < 1e-12);
    let lambda = (sim.gas_volume() / sim.rest_gas_volume()).cbrt();
    let expected = sphere_stretch(&material, h0, r, p).unwrap();
    assert!(
        (lambda / expected - 1.0).abs() < 5e-3,
        "{lambda} vs {expected}"
    );
    let h_ref = h0 / (lambda * lambda);
    let spread = sim
        .thickness()
        .iter()
        .fold(0.0f64, |m, h| m.max((h / h_ref - 1.0).abs()));
    // What is left is the geometric non-uniformity of the icosphere's stretch (~1e-3).
    assert!(spread < 1e-2, "thickness spread {spread}");
}

#[test]
fn analytic_pressure_is_zero_at_rest() {
    assert!(sphere_pressure(&StVenantKirchhoff::new(lame()), 3e-4, 0.1, 1.0).abs() < 1e-9);
}

#[test]
fn isothermal_gas_keeps_pv_constant_during_inflation() {
    // Fixed amount of gas at 2 kPa over a zero ambient (the paper's model, Eq. 14).
    let mesh = icosphere(0.1, 3).unwrap();
    let mut sim = ShellBalloon::new(mesh)
        .with_gas(GasKind::Ideal)
        .with_ambient_pressure(0.0)
        .with_gauge_pressure(2000.0)
        .build()
        .unwrap();
    // Measured independently of the gas state: the volume the mesh encloses and the pressure
    // its forces imply (the derivative of the gas potential along a scaling of the surface).
    let tris = sim.triangles().to_vec();
    let v0 = balloon_tests::mesh_volume(sim.rest_positions(), &tris);
    let p0 = balloon_tests::implied_gauge_pressure(&sim);
    assert!((p0 / 2000.0 - 1.0).abs() < 1e-6, "implied p0 = {p0}");
    for _ in 0..20 {
        sim.step().unwrap();
        let v = balloon_tests::mesh_volume(sim.positions(), &tris);
        let p = balloon_tests::implied_gauge_pressure(&sim);
        assert!(
            (p * v / (p0 * v0) - 1.0).abs() < 1e-6,
            "pV = {} against p0 V0 = {}",
            p * v,
            p0 * v0
        );
        // The pressure fell as the volume grew: the check is not at a fixed state.
        assert!(p < p0 && v > v0);
    }
    // It did inflate, so the check above is not at a fixed volume.
    assert!(sim.gas_volume() > 1.02 * sim.rest_gas_volume());
}

/// The built-in teddy at a coarse resolution (about 1.4k vertices) so that long runs stay fast in
/// the default test profile; `cargo xtask validate` repeats them at full resolution.
fn coarse_teddy() -> (TriMesh, TeddyParams) {
    let params = TeddyParams {
        resolution: 14,
        ..Default::default()
    };
    (teddy(&params).unwrap(), params)
}

#[test]
fn shell_volume_ratio_stays_within_1e_9_over_300_steps_of_teddy_inflation() {
    let (mesh, _) = coarse_teddy();
    let mut sim = ShellBalloon::new(mesh)
        .with_linear_solver(LinearSolverKind::Cholesky)
        .build()
        .unwrap();
    // The shell's material volume sum A_e h_e measured here from the positions and thickness
    // (not the projection's own ratio, which is its stopping rule), every 10 steps.
    let tris = sim.triangles().to_vec();
    let area = |x: &[f64], t: &[usize; 3]| {
        let p = |i: usize| nalgebra::Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
        0.5 * (p(t[1]) - p(t[0])).cross(&(p(t[2]) - p(t[0]))).norm()
    };
    let material_volume =
        |x: &[f64], h: &[f64]| -> f64 { tris.iter().zip(h).map(|(t, h)| area(x, t) * h).sum() };
    let h0 = sim.thickness().to_vec();
    let v0 = material_volume(sim.rest_positions(), &h0);
    let mut worst: f64 = 0.0;
    for k in 1..=300 {
        sim.step().unwrap();
        if k % 10 == 0 {
            let v = material_volume(sim.positions(), sim.thickness());
            worst = worst.max((v / v0 - 1.0).abs());
        }
    }
    assert!(worst <= 1e-9, "max |V_b / V_b0 - 1| = {worst:e}");
    // The measure is sensitive: the rest thickness on the inflated surface (no projection)
    // would be off by the area growth.
    let unprojected = material_volume(sim.positions(), &h0);
    assert!(
        unprojected / v0 - 1.0 > 0.1,
        "area growth {}",
        unprojected / v0
    );
    // The run inflated the teddy (the pump added gas), so the projection had work to do.
    assert!(
        sim.gas_volume() > 1.2 * sim.rest_gas_volume(),
        "volume ratio {}",
        sim.gas_volume() / sim.rest_gas_volume()
    );
    let h = sim.thickness();
    assert!(
        h.iter().copied().fold(f64::INFINITY, f64::min) < 0.95 * 3e-4,
        "the shell got thinner"
    );
}

#[test]
fn thinner_shell_inflates_more_at_the_same_gas_state() {
    // Same shape, same amount of gas (paper's ideal gas, zero ambient), three thicknesses as in
    // the paper's Fig. 7: the thinner the shell, the larger the equilibrium volume.
    let mesh = uv_sphere(0.1, 24, 12).unwrap();
    let mut volumes = Vec::new();
    for h in [3e-4, 2e-4, 1e-4] {
        let mut sim = ShellBalloon::new(mesh.clone())
            .with_thickness(h)
            .with_gas(GasKind::Ideal)
            .with_ambient_pressure(0.0)
            .with_gauge_pressure(3000.0)
            .with_linear_solver(LinearSolverKind::Cholesky)
            .with_dt(0.5)
            .build()
            .unwrap();
        settle(&mut sim, 60);
        volumes.push(sim.gas_volume() / sim.rest_gas_volume());
    }
    assert!(
        volumes[0] < volumes[1] && volumes[1] < volumes[2],
        "volume ratios for 0.3/0.2/0.1 mm: {volumes:?}"
    );
    assert!(
        volumes[2] > 1.1 * volumes[0],
        "the effect is substantial: {volumes:?}"
    );
}

/// RMS distance of a part's vertices from their centroid: a size measure of a body part.
fn part_size(x: &[f64], parts: &[TeddyPart], which: &[TeddyPart]) -> f64 {
    let idx: Vec<usize> = (0..parts.len())
        .filter(|&i| which.contains(&parts[i]))
        .collect();
    let n = idx.len() as f64;
    let mut c = [0.0; 3];
    for &i in &idx {
        for k in 0..3 {
            c[k] += x[3 * i + k] / n;
        }
    }
    (idx.iter()
        .map(|&i| (0..3).map(|k| (x[3 * i + k] - c[k]).powi(2)).sum::<f64>())
        .sum::<f64>()
        / n)
        .sqrt()
}

#[test]
fn teddy_ears_grow_relatively_slower_than_the_head() {
    // Sec. 8: big parts with gentle curvature inflate faster than small, strongly curved ones.
    let (mesh, params) = coarse_teddy();
    let parts = teddy_vertex_parts(&mesh, &params);
    let ears = [TeddyPart::LeftEar, TeddyPart::RightEar];
    let head = [TeddyPart::Head];
    let mut sim = ShellBalloon::new(mesh)
        .with_linear_solver(LinearSolverKind::Cholesky)
        .build()
        .unwrap();
    let x0 = sim.positions().to_vec();
    for _ in 0..120 {
        sim.step().unwrap();
    }
    let x = sim.positions();
    let ear_growth = part_size(x, &parts, &ears[..1]) / part_size(&x0, &parts, &ears[..1]);
    let head_growth = part_size(x, &parts, &head) / part_size(&x0, &parts, &head);
    assert!(head_growth > 1.05, "the head inflated: {head_growth}");
    assert!(
        ear_growth < head_growth,
        "ear growth {ear_growth} vs head growth {head_growth}"
    );
}

#[test]
fn bad_input_is_rejected_before_any_work() {
    let sphere = icosphere(0.1, 1).unwrap();
    // Open mesh: drop a triangle.
    let mut open = sphere.clone();
    open.triangles.pop();
    let err = ShellBalloon::new(open).build().unwrap_err();
    assert!(matches!(err, ShellError::Mesh(_)), "{err}");
    assert!(
        err.to_string().contains("boundary") || err.to_string().contains("open"),
        "{err}"
    );
    for (builder, name) in [
        (
            ShellBalloon::new(sphere.clone()).with_thickness(0.0),
            "thickness",
        ),
        (
            ShellBalloon::new(sphere.clone()).with_thickness(-1e-4),
            "thickness",
        ),
        (
            ShellBalloon::new(sphere.clone()).with_density(0.0),
            "density",
        ),
        (ShellBalloon::new(sphere.clone()).with_dt(0.0), "dt"),
        (ShellBalloon::new(sphere.clone()).with_dt(f64::NAN), "dt"),
    ] {
        let err = builder.build().unwrap_err();
        assert!(err.to_string().contains(name), "{err} should name {name}");
    }
    assert!(Lame::try_from_young_poisson(1e6, 0.5).is_err());
    assert!(Lame::try_from_young_poisson(1e6, -1.0).is_err());
}

#[test]
fn runaway_is_reported_with_the_step_and_the_state_is_rolled_back() {
    // A neo-Hookean balloon under a constant pressure above its limit point has no equilibrium.
    let mesh = icosphere(0.1, 2).unwrap();
    let l = lame();
    let p_max = 4.0 * l.mu() * 3e-4 / (3.0 * 3f64.sqrt() * 0.1);
    let mut sim = ShellBalloon::new(mesh)
        .with_material(NeoHookean::new(l))
        .with_gas(GasKind::Constant)
        .with_gauge_pressure(3.0 * p_max)
        .with_linear_solver(LinearSolverKind::Cholesky)
        .with_dt(0.05)
        .build()
        .unwrap();
    let mut failed = None;
    for _ in 0..400 {
        let before = sim.positions().to_vec();
        match sim.step() {
            Ok(_) => {}
            Err(e) => {
                assert_eq!(
                    sim.positions(),
                    &before[..],
                    "state rolled back to the start of the failed step"
                );
                failed = Some(e);
                break;
            }
        }
    }
    let e = failed.expect("the run must diverge");
    let msg = e.to_string();
    assert!(msg.contains("step "), "{msg}");
    assert!(sim.positions().iter().all(|v| v.is_finite()));
}

#[test]
fn linear_solvers_agree() {
    let mesh = icosphere(0.1, 2).unwrap();
    let mut finals = Vec::new();
    for kind in [
        LinearSolverKind::MatrixFreeCg,
        LinearSolverKind::Pcg,
        LinearSolverKind::Cholesky,
    ] {
        let mut b = ShellBalloon::new(mesh.clone()).with_linear_solver(kind);
        // The same Newton path for every solver: no chord steps (matrix-free CG has no
        // matrix to reuse; the chord steps change the path within the Newton tolerance).
        let mut p = balloon::integrate::implicit::BackwardEulerParams {
            mass_damping: 10.0,
            tangent_reuse_steps: 0,
            ..Default::default()
        };
        p.linear.kind = kind;
        p.linear.relative_tolerance = 1e-12;
        p.linear.max_iterations = 5000;
        b = b.with_integrator(p);
        let mut sim = b.build().unwrap();
        for _ in 0..5 {
            sim.step().unwrap();
        }
        finals.push(sim.positions().to_vec());
    }
    for other in &finals[1..] {
        let diff = finals[0]
            .iter()
            .zip(other)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(diff < 1e-9, "solvers disagree by {diff:e} m");
    }
}
