//! The wall-thickness fit (`docs/design.md`, D18): its adjoint gradient against central
//! differences of forward static solves, and a round trip: a rest shape inflated with a
//! thickness map that is not uniform, fitted from a uniform wall with the rest shape fixed.

use balloon_design::{
    DesignParams, DesignProblem, DesignProgress, FallbackMode, FallbackStop, ShapeObjective,
    ThicknessFitParams, design, fit_thickness,
};
use balloon_integrate::statics::StaticParams;
use balloon_material::membrane::{MembraneModel, MembraneNeoHookean};
use balloon_material::{Lame, MaterialModel, NeoHookean};
use balloon_mesh::TriMesh;
use balloon_shell::ShellMaterialModel;

// `inflate` (the uniform wall) is not used here.
#[allow(dead_code)]
mod support;
use support::{H, ellipsoid, inflate_with_thickness};

fn membrane() -> ShellMaterialModel {
    MembraneModel::from(MembraneNeoHookean::try_new(4.0e5).unwrap()).into()
}

fn prism() -> ShellMaterialModel {
    let lame = Lame::try_from_young_poisson(1.0e6, 0.45).unwrap();
    ShellMaterialModel::Solid(MaterialModel::NeoHookean(NeoHookean::new(lame)))
}

/// A thickness map that grows along z: `H (1 + 0.4 z_c / 0.03)` at each face's centroid
/// `z_c` (the ellipsoid's semi-axis along z is 0.03 m): from 0.6 H at the bottom to 1.4 H at
/// the top.
fn graded(mesh: &TriMesh) -> Vec<f64> {
    mesh.triangles
        .iter()
        .map(|t| {
            let z = t.iter().map(|&v| mesh.vertices[v].z).sum::<f64>() / 3.0;
            H * (1.0 + 0.4 * z / 0.03)
        })
        .collect()
}

/// The ellipsoid rest shape inflated at 3 kPa with the graded wall, as a target mesh.
fn target(rest: &TriMesh, material: &ShellMaterialModel) -> TriMesh {
    let x = inflate_with_thickness(rest, material, 3.0e3, graded(rest));
    let mut t = rest.clone();
    for (v, p) in t.vertices.iter_mut().zip(x.chunks(3)) {
        v.x = p[0];
        v.y = p[1];
        v.z = p[2];
    }
    t
}

/// `dD/dH` of D18 (the adjoint `lambda` of D12 with `df_e/dH_e = f_e / H_e`) against central
/// differences of `D` along random thickness directions, each `D` from its own forward static
/// solve (tolerance 1e-12), for the membrane and the neo-Hookean prism, at a uniform wall that
/// does not hold the target.
#[test]
fn thickness_gradient_matches_central_differences() {
    let rest = ellipsoid(1);
    for material in [membrane(), prism()] {
        let target = target(&rest, &material);
        let problem =
            DesignProblem::try_new(&target, vec![H; target.num_triangles()], material, 3.0e3)
                .unwrap();
        check_thickness_gradient(&problem, &rest.positions_flat());
    }
}

/// [`thickness_gradient_matches_central_differences`] with the wall's bending stiffness
/// (`D ~ h^3` of the mean thickness of each hinge's two faces: `df/dH = 3 f / (2 h)` each),
/// the neo-Hookean prism, with a factor that changes the gradient by more than 10 %
/// (asserted).
#[test]
fn thickness_gradient_with_the_bending_wall_matches_central_differences() {
    let rest = ellipsoid(1);
    let material = prism();
    let target = target(&rest, &material);
    let plain =
        DesignProblem::try_new(&target, vec![H; target.num_triangles()], material, 3.0e3).unwrap();
    let bent = plain.clone().with_wall_bending(300.0).unwrap();
    let x_rest = rest.positions_flat();
    let g_bent = check_thickness_gradient(&bent, &x_rest);
    let g_plain = check_thickness_gradient(&plain, &x_rest);
    let norm = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>().sqrt();
    let diff: Vec<f64> = g_bent.iter().zip(&g_plain).map(|(a, b)| a - b).collect();
    let change = norm(&diff) / norm(&g_plain);
    eprintln!("the bending wall changes the thickness gradient by {change:.3} of it");
    assert!(change > 0.1, "{change:e}");
}

/// Checks `dD/dH` of `problem` at the rest shape `x_rest` and the uniform wall against
/// central differences along three random thickness directions; returns it.
fn check_thickness_gradient(problem: &DesignProblem, x_rest: &[f64]) -> Vec<f64> {
    let mut objective = ShapeObjective::new(problem, &StaticParams::default(), 1e-12).unwrap();
    let e = objective
        .evaluate(x_rest, true)
        .unwrap()
        .expect("an equilibrium");
    assert!(
        e.distance.max > 1e-4,
        "the uniform wall does not hold the target"
    );
    let g = objective.thickness_gradient(x_rest).unwrap();
    let x0 = objective.equilibrium().unwrap().to_vec();
    for seed in 0..3u64 {
        let v: Vec<f64> = (0..g.len())
            .map(|i| (((i as u64 * 7919 + seed * 104_729) % 1000) as f64 / 500.0) - 1.0)
            .collect();
        let eps = 1e-8;
        let mut at = |s: f64| {
            let h: Vec<f64> = v.iter().map(|vi| H + s * vi).collect();
            objective.set_thickness(&h).unwrap();
            objective.set_equilibrium(Some(x0.clone()));
            objective
                .evaluate(x_rest, false)
                .unwrap()
                .unwrap()
                .objective
        };
        let fd = (at(eps) - at(-eps)) / (2.0 * eps);
        let adjoint: f64 = g.iter().zip(&v).map(|(a, b)| a * b).sum();
        let rel = (fd - adjoint).abs() / adjoint.abs();
        eprintln!("direction {seed}: adjoint {adjoint:e}, central difference {fd:e}, rel {rel:e}");
        assert!(
            rel < 1e-5,
            "adjoint {adjoint:e} vs central difference {fd:e}"
        );
    }
    g
}

/// Round trip: the ellipsoid inflated with the graded wall is the target; from a uniform 1 mm
/// wall on the same rest shape, the fit brings the forward equilibrium onto the target and
/// the fitted thickness near the graded one; every step decreases the objective.
#[test]
fn the_fit_recovers_a_graded_wall_on_a_fixed_rest_shape() {
    let rest = ellipsoid(2);
    let material = membrane();
    let target = target(&rest, &material);
    let problem =
        DesignProblem::try_new(&target, vec![H; target.num_triangles()], material, 3.0e3).unwrap();
    let params = ThicknessFitParams {
        max_iterations: 200,
        ..ThicknessFitParams::default()
    };
    let mut objectives = Vec::new();
    let fit = fit_thickness(
        &problem,
        &rest.positions_flat(),
        &params,
        &StaticParams::default(),
        |p| {
            objectives.push(p.objective);
            true
        },
    )
    .unwrap();
    let info = &fit.info;
    eprintln!("{info:#?}");
    let start = info.start.unwrap();
    let end = info.end.unwrap();
    assert!(
        start.max_relative > 1e-3,
        "the uniform wall is off: {start:?}"
    );
    assert!(
        end.max_relative < 1e-5,
        "the fitted wall holds the target: {end:?} ({:?})",
        info.stopped
    );
    assert!(objectives.windows(2).all(|w| w[1] <= w[0]));
    // Bounds by default: a quarter and four times the start.
    assert_eq!((info.lower, info.upper), (0.25 * H, 4.0 * H));
    let truth = graded(&rest);
    let rms = (fit
        .thickness
        .iter()
        .zip(&truth)
        .map(|(a, b)| ((a - b) / b).powi(2))
        .sum::<f64>()
        / truth.len() as f64)
        .sqrt();
    eprintln!("relative RMS thickness error {rms:e}");
    assert!(rms < 0.05, "relative RMS thickness error {rms:e}");
    assert!(
        fit.thickness
            .iter()
            .all(|h| *h > info.lower && *h < info.upper)
    );
}

/// Bounds that exclude the graded wall: the fit stays within them, reduces the distance as far
/// as they allow, and says that faces sit at a bound; through [`design`] (inverse off), the check
/// uses the fitted thickness and the progress reports the fit's steps.
#[test]
fn bounds_hold_and_design_checks_with_the_fitted_wall() {
    let rest = ellipsoid(1);
    let material = membrane();
    let target = target(&rest, &material);
    let problem =
        DesignProblem::try_new(&target, vec![H; target.num_triangles()], material, 3.0e3).unwrap();
    let params = ThicknessFitParams {
        lower: Some(0.9 * H),
        upper: Some(1.1 * H),
        max_iterations: 60,
        ..ThicknessFitParams::default()
    };
    let fit = fit_thickness(
        &problem,
        &rest.positions_flat(),
        &params,
        &StaticParams::default(),
        |_| true,
    )
    .unwrap();
    assert!(fit.thickness.iter().all(|h| *h >= 0.9 * H && *h <= 1.1 * H));
    assert!(fit.info.at_bounds > 0, "{:?}", fit.info);
    let (start, end) = (fit.info.start.unwrap(), fit.info.end.unwrap());
    assert!(end.rms < start.rms, "{start:?} -> {end:?}");

    // Bad bounds are named.
    let bad = ThicknessFitParams {
        lower: Some(2.0 * H),
        upper: Some(H),
        ..params
    };
    let err = fit_thickness(
        &problem,
        &rest.positions_flat(),
        &bad,
        &StaticParams::default(),
        |_| true,
    )
    .unwrap_err();
    assert!(err.to_string().contains("thickness_max"), "{err}");

    // In `design`: the ellipsoid with its poles cut flat (|z| <= 0.02 m), which no rest shape
    // holds under pressure, the shape optimisation off; the fit then runs on the inverse's best
    // rest shape.
    let mut flat = ellipsoid(1);
    for v in &mut flat.vertices {
        v.z = v.z.clamp(-0.02, 0.02);
    }
    let problem =
        DesignProblem::try_new(&flat, vec![H; flat.num_triangles()], membrane(), 3.0e3).unwrap();
    let mut design_params = DesignParams::default();
    design_params.fallback.mode = FallbackMode::Off;
    design_params.thickness = ThicknessFitParams {
        enabled: true,
        max_iterations: 5,
        ..ThicknessFitParams::default()
    };
    let mut steps = 0;
    let result = design(&problem, &design_params, |p| {
        if matches!(p, DesignProgress::Thickness(_)) {
            steps += 1;
        }
        true
    })
    .unwrap();
    let fitted = result.thickness.expect("the fit ran");
    assert!(!result.inverse.converged);
    assert_eq!(steps, fitted.info.iterations);
    assert!(steps >= 1, "{:?}", fitted.info);
    assert_ne!(fitted.info.stopped, FallbackStop::NoEquilibrium);
    assert!(fitted.info.end.unwrap().rms < fitted.info.start.unwrap().rms);
    // The check is the forward solve with the fitted wall: its distance is the fit's end.
    let end = fitted.info.end.unwrap();
    assert!(
        (result.check.distance.max - end.max).abs() <= 1e-6 * end.max.max(1e-9) + 1e-12,
        "check {:?} vs fit {end:?}",
        result.check.distance
    );
}

/// D18's `df_e/dH_e = f_e / H_e`: the elastic forces of a three-prism (current thickness = rest
/// thickness, as in the static solve) and of a membrane element, at a stretched and sheared
/// state, against central differences in the rest thickness.
#[test]
fn element_forces_are_linear_in_the_rest_thickness() {
    use balloon_element::{HyperMembrane, ThreePrism};
    use nalgebra::Vector3;
    let rest = [
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(0.01, 0.0, 0.0),
        Vector3::new(0.002, 0.009, 0.0),
    ];
    let x = [
        Vector3::new(0.001, -0.0005, 0.0003),
        Vector3::new(0.0132, 0.0004, 0.001),
        Vector3::new(0.0031, 0.0121, -0.0008),
    ];
    let (prism_material, membrane_material) = match (prism(), membrane()) {
        (ShellMaterialModel::Solid(p), ShellMaterialModel::Membrane(m)) => (p, m),
        _ => unreachable!(),
    };
    let prism_forces = |h: f64| {
        ThreePrism::try_new(rest, h)
            .unwrap()
            .forces(&prism_material, &x, h)
    };
    let membrane_forces = |h: f64| {
        HyperMembrane::try_new(rest, h)
            .unwrap()
            .forces(&membrane_material, &x)
    };
    for forces in [
        &prism_forces as &dyn Fn(f64) -> [Vector3<f64>; 3],
        &membrane_forces,
    ] {
        let f = forces(H);
        let eps = 1e-6 * H;
        let (fp, fm) = (forces(H + eps), forces(H - eps));
        let scale = f.iter().map(|v| v.norm()).fold(0.0, f64::max);
        assert!(scale > 0.0);
        for a in 0..3 {
            let fd = (fp[a] - fm[a]) / (2.0 * eps);
            let err = (fd - f[a] / H).norm() / (scale / H);
            assert!(err < 1e-8, "corner {a}: {fd:?} vs {:?} ({err:e})", f[a] / H);
        }
    }
}

/// `design_for_rest`: a given rest shape is kept. With the wall that inflates it onto the target
/// its equilibrium residual is zero to round-off and it is reported as holding the target;
/// with a uniform wall it is not, and the fit then brings the check onto the target with the
/// rest shape unchanged.
#[test]
fn a_given_rest_shape_is_checked_and_its_wall_fitted() {
    let rest = ellipsoid(1);
    let material = membrane();
    let target = target(&rest, &material);
    let uniform =
        DesignProblem::try_new(&target, vec![H; target.num_triangles()], material, 3.0e3).unwrap();
    let exact = uniform.with_thickness(graded(&rest)).unwrap();
    let x_rest = rest.positions_flat();
    let params = DesignParams::default();
    let held = balloon_design::design_for_rest(&exact, x_rest.clone(), &params, |_| true).unwrap();
    assert!(held.inverse.converged, "{:?}", held.inverse);
    assert!(held.inverse.relative_residual < 1e-9, "{:?}", held.inverse);
    assert_eq!(held.inverse.iterations, 0);
    // The forward check solves to the static solver's default tolerance.
    assert!(
        held.check.distance.max_relative < 1e-7,
        "{:?}",
        held.check.distance
    );
    assert!(held.thickness.is_none());

    let off = balloon_design::design_for_rest(&uniform, x_rest.clone(), &params, |_| true).unwrap();
    assert!(!off.inverse.converged);
    assert!(off.inverse.relative_residual > 1e-3, "{:?}", off.inverse);
    let fit_params = DesignParams {
        thickness: ThicknessFitParams {
            enabled: true,
            max_iterations: 200,
            ..ThicknessFitParams::default()
        },
        ..DesignParams::default()
    };
    let fitted =
        balloon_design::design_for_rest(&uniform, x_rest.clone(), &fit_params, |_| true).unwrap();
    assert_eq!(fitted.rest, x_rest);
    assert!(
        fitted.check.distance.max_relative < 1e-6,
        "{:?}",
        fitted.check.distance
    );
    assert!(fitted.check.distance.max < 1e-3 * off.check.distance.max);
    // The wrong number of coordinates is named.
    let err = balloon_design::design_for_rest(&uniform, x_rest[3..].to_vec(), &params, |_| true)
        .unwrap_err();
    assert!(err.to_string().contains("rest"), "{err}");
}
