//! The shape-optimisation fallback: the adjoint gradient of the distance objective against
//! central differences of forward static solves, and a target with no exact design (flat
//! faces) whose distance the fallback reduces.

use balloon_design::{
    DesignParams, DesignProblem, DesignProgress, FallbackMethod, FallbackMode, FallbackParams,
    FallbackStop, InverseParams, ShapeObjective, design,
};
use balloon_integrate::statics::StaticParams;
use balloon_material::membrane::{MembraneModel, MembraneNeoHookean};
use balloon_material::{Lame, MaterialModel, NeoHookean};
use balloon_shell::ShellMaterialModel;

mod support;
use support::{H, ellipsoid, inflate};

fn membrane() -> ShellMaterialModel {
    MembraneModel::from(MembraneNeoHookean::try_new(4.0e5).unwrap()).into()
}

fn prism() -> ShellMaterialModel {
    let lame = Lame::try_from_young_poisson(1.0e6, 0.45).unwrap();
    ShellMaterialModel::Solid(MaterialModel::NeoHookean(NeoHookean::new(lame)))
}

/// A deterministic pseudo-random number in [-1, 1).
fn noise(i: usize, seed: usize) -> f64 {
    let mut z = (i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (seed as u64 + 7).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z ^= z >> 31;
    z = z.wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 29;
    (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// The 42-vertex ellipsoid target (semi-axes 0.05, 0.04, 0.03 m) designed with the membrane
/// and with the neo-Hookean prism at 3 kPa, and with the membrane under the amount of ideal gas
/// that has 3 kPa over the atmosphere at the target (its pressure follows the volume: the
/// rank-one coupling of the forward stiffness), each with a rest shape that is not an exact
/// design (the target scaled by 0.9 and perturbed by 1 mm).
fn ellipsoid_cases() -> Vec<(DesignProblem, Vec<f64>)> {
    let target = ellipsoid(1);
    let amount = (3.0e3 + 101_325.0)
        * balloon_design::enclosed_volume(&target.positions_flat(), &target.triangles);
    [
        (membrane(), 3.0e3, false),
        (prism(), 3.0e3, false),
        (membrane(), 3.0e3, true),
    ]
    .into_iter()
    .map(|(material, p, gas)| {
        let thickness = vec![H; target.num_triangles()];
        let problem = if gas {
            DesignProblem::with_gas_amount(&target, thickness, material, amount, 101_325.0)
        } else {
            DesignProblem::try_new(&target, thickness, material, p)
        }
        .unwrap();
        let rest = problem
            .target()
            .iter()
            .enumerate()
            .map(|(i, x)| 0.9 * x + 1e-3 * noise(i, 1))
            .collect();
        (problem, rest)
    })
    .collect()
}

/// `dD/dX` by the adjoint (`docs/design.md`, D12) against central differences of `D` along
/// random directions, each `D` from its own forward static solve (tolerance 1e-12), on a
/// 42-vertex ellipsoid whose rest shape is not an exact design (a scaled, perturbed target):
/// the membrane and the neo-Hookean prism.
#[test]
fn adjoint_gradient_matches_central_differences() {
    for (problem, rest) in ellipsoid_cases() {
        check_adjoint_gradient(&problem, &rest);
    }
}

/// The adjoint gradient of [`adjoint_gradient_matches_central_differences`] with the wall's
/// bending stiffness (`docs/design.md`, D20): the forward stiffness of the adjoint solve holds
/// the hinges' Hessians and `df/dX` their rest Jacobian. The neo-Hookean prism case with a
/// factor that changes the gradient by more than 10 % (asserted).
#[test]
fn adjoint_gradient_with_the_bending_wall_matches_central_differences() {
    let (plain, rest) = ellipsoid_cases().swap_remove(1);
    let bent = plain.clone().with_wall_bending(300.0).unwrap();
    let g_bent = check_adjoint_gradient(&bent, &rest);
    let mut objective = ShapeObjective::new(&plain, &StaticParams::default(), 1e-12).unwrap();
    let g_plain = objective
        .evaluate(&rest, true)
        .unwrap()
        .unwrap()
        .gradient
        .unwrap();
    let norm = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>().sqrt();
    let diff: Vec<f64> = g_bent.iter().zip(&g_plain).map(|(a, b)| a - b).collect();
    let change = norm(&diff) / norm(&g_plain);
    eprintln!("the bending wall changes the gradient by {change:.3} of it");
    assert!(change > 0.1, "{change:e}");
}

/// Checks `dD/dX` of `problem` at `rest` against central differences of `D` along three
/// random directions and its orthogonality to the translations; returns it.
fn check_adjoint_gradient(problem: &DesignProblem, rest: &[f64]) -> Vec<f64> {
    let mut objective = ShapeObjective::new(problem, &StaticParams::default(), 1e-12).unwrap();
    let e = objective
        .evaluate(rest, true)
        .unwrap()
        .expect("an equilibrium");
    let x0 = objective.equilibrium().unwrap().to_vec();
    let g = e.gradient.unwrap();
    assert!(
        e.distance.max > 1e-3,
        "the start is not already on the target"
    );
    for seed in 0..3 {
        let v: Vec<f64> = (0..rest.len()).map(|i| noise(i, 100 + seed)).collect();
        let h = 1e-6;
        let mut at = |s: f64| {
            let y: Vec<f64> = rest.iter().zip(&v).map(|(a, b)| a + s * b).collect();
            objective.set_equilibrium(Some(x0.clone()));
            objective.evaluate(&y, false).unwrap().unwrap().objective
        };
        let fd = (at(h) - at(-h)) / (2.0 * h);
        let adjoint: f64 = g.iter().zip(&v).map(|(a, b)| a * b).sum();
        let rel = (fd - adjoint).abs() / adjoint.abs();
        eprintln!("direction {seed}: adjoint {adjoint:e}, central difference {fd:e}, rel {rel:e}");
        assert!(
            rel < 1e-5,
            "adjoint {adjoint:e} vs central difference {fd:e}"
        );
    }
    // A rigid motion of the rest shape does not change D: the gradient is orthogonal to
    // the translations.
    for k in 0..3 {
        let t: f64 = g.iter().skip(k).step_by(3).sum();
        let scale = g.iter().map(|a| a.abs()).sum::<f64>();
        assert!(t.abs() < 1e-8 * scale, "translation {k}: {t:e}");
    }
    g
}

/// Removes the least-squares rigid motion (translation and small rotation about the centroid)
/// of the displacement field `u` at the points `x`, by a dense 6x6 solve.
fn without_rigid_motion(x: &[f64], u: &[f64]) -> Vec<f64> {
    let nv = x.len() / 3;
    let c: nalgebra::Vector3<f64> = (0..nv)
        .map(|v| nalgebra::Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]))
        .sum::<nalgebra::Vector3<f64>>()
        / nv as f64;
    // Columns: the six rigid fields.
    let basis = nalgebra::DMatrix::<f64>::from_fn(3 * nv, 6, |i, k| {
        let (v, a) = (i / 3, i % 3);
        if k < 3 {
            f64::from(u8::from(a == k))
        } else {
            let q = nalgebra::Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]) - c;
            nalgebra::Vector3::ith(k - 3, 1.0).cross(&q)[a]
        }
    });
    let u = nalgebra::DVector::from_column_slice(u);
    let coef = (basis.transpose() * &basis)
        .lu()
        .solve(&(basis.transpose() * &u))
        .unwrap();
    (u - basis * coef).as_slice().to_vec()
}

/// The Gauss-Newton step's sensitivity `dx/dX v = K^-1 (df/dX) v` (`docs/design.md`, D15)
/// against central differences of the forward equilibrium `x(X)` along random directions
/// (each `x` its own static solve at a relative residual of 1e-12, warm-started from the same
/// equilibrium), both modulo rigid motions (the equilibrium of a free balloon is defined up to
/// one), on the 42-vertex ellipsoid of the adjoint test; its transpose by the identity
/// `<S v, y> = <v, S^T y>`; and the Gauss-Newton product's symmetry and positivity.
#[test]
fn equilibrium_sensitivity_matches_central_differences() {
    for (problem, rest) in ellipsoid_cases() {
        let mut objective = ShapeObjective::new(&problem, &StaticParams::default(), 1e-12).unwrap();
        assert!(
            objective.sensitivity(&rest).is_err(),
            "nothing linearised yet"
        );
        objective.evaluate(&rest, true).unwrap().unwrap();
        let x0 = objective.equilibrium().unwrap().to_vec();
        let norm = |a: &[f64]| a.iter().map(|v| v * v).sum::<f64>().sqrt();
        for seed in 0..3 {
            let v: Vec<f64> = (0..rest.len()).map(|i| noise(i, 200 + seed)).collect();
            let s = objective.sensitivity(&v).unwrap();
            let h = 1e-6;
            let mut at = |t: f64| {
                let y: Vec<f64> = rest.iter().zip(&v).map(|(a, b)| a + t * b).collect();
                objective.set_equilibrium(Some(x0.clone()));
                objective.evaluate(&y, false).unwrap().unwrap();
                objective.equilibrium().unwrap().to_vec()
            };
            let (plus, minus) = (at(h), at(-h));
            let fd: Vec<f64> = plus
                .iter()
                .zip(&minus)
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect();
            let (fd, s) = (
                without_rigid_motion(&x0, &fd),
                without_rigid_motion(&x0, &s),
            );
            let diff: Vec<f64> = fd.iter().zip(&s).map(|(a, b)| a - b).collect();
            let rel = norm(&diff) / norm(&fd);
            eprintln!(
                "direction {seed}: |S v| {:e}, relative difference {rel:e}",
                norm(&s)
            );
            assert!(norm(&s) > 1e-2 * norm(&v), "a non-trivial sensitivity");
            assert!(rel < 1e-5, "S v against central differences: {rel:e}");
        }
        // The linearisation is that of the last evaluation with the gradient: re-linearise.
        objective.set_equilibrium(Some(x0.clone()));
        objective.evaluate(&rest, true).unwrap().unwrap();
        let v: Vec<f64> = (0..rest.len()).map(|i| noise(i, 300)).collect();
        let u: Vec<f64> = (0..rest.len()).map(|i| noise(i, 301)).collect();
        let y = without_rigid_motion(&x0, &u);
        let lhs: f64 = objective
            .sensitivity(&v)
            .unwrap()
            .iter()
            .zip(&y)
            .map(|(a, b)| a * b)
            .sum();
        let rhs: f64 = objective
            .sensitivity_transpose(&y)
            .unwrap()
            .iter()
            .zip(&v)
            .map(|(a, b)| a * b)
            .sum();
        assert!(
            (lhs - rhs).abs() < 1e-8 * lhs.abs(),
            "<S v, y> {lhs:e} vs <v, S^T y> {rhs:e}"
        );
        let (av, au) = (
            objective.gauss_newton_product(&v).unwrap(),
            objective.gauss_newton_product(&u).unwrap(),
        );
        let uav: f64 = u.iter().zip(&av).map(|(a, b)| a * b).sum();
        let vau: f64 = v.iter().zip(&au).map(|(a, b)| a * b).sum();
        let vav: f64 = v.iter().zip(&av).map(|(a, b)| a * b).sum();
        assert!(
            (uav - vau).abs() < 1e-8 * vav,
            "symmetric: {uav:e} vs {vau:e}"
        );
        assert!(vav > 0.0);
    }
}

/// A target with an exact design: a 162-vertex ellipsoid (semi-axes 0.05, 0.04, 0.03 m)
/// inflated statically at 8 kPa from itself as the rest shape, membrane wall. Returns that
/// rest shape `X0` and the design problem of the inflated target.
fn exact_round_trip() -> (Vec<f64>, DesignProblem) {
    let mesh = ellipsoid(2);
    let x_star = inflate(&mesh, &membrane(), 8.0e3);
    let x0 = mesh.positions_flat();
    let mut target = mesh;
    target.set_positions_flat(&x_star);
    let problem =
        DesignProblem::try_new(&target, vec![H; target.num_triangles()], membrane(), 8.0e3)
            .unwrap();
    (x0, problem)
}

/// On a target with an exact design (a 162-vertex ellipsoid inflated statically from a known
/// rest shape, membrane at 8 kPa), the Gauss-Newton outer loop started from the target itself
/// as the rest shape brings the forward equilibrium within 1e-7 of the bounding-box diagonal
/// in a handful of steps, where L-BFGS with the same budget stays far from it.
#[test]
fn gauss_newton_converges_where_lbfgs_crawls() {
    let (_, problem) = exact_round_trip();
    let run = |method| {
        let mut rest = problem.target().to_vec();
        let params = FallbackParams {
            method,
            max_iterations: 12,
            distance_tolerance: 1e-7,
            ..FallbackParams::default()
        };
        let info = balloon_design::optimise_rest_shape(
            &problem,
            &params,
            &StaticParams::default(),
            &mut rest,
            |p| {
                eprintln!("{method:?} {p:?}");
                true
            },
        )
        .unwrap();
        eprintln!("{method:?}: {info:?}");
        info
    };
    let gn = run(FallbackMethod::GaussNewton);
    assert_eq!(gn.stopped, FallbackStop::Distance, "{gn:?}");
    assert!(gn.end.unwrap().max_relative <= 1e-7);
    assert!(gn.gauss_newton_steps > 0 && gn.cg_iterations > 0);
    let lbfgs = run(FallbackMethod::Lbfgs);
    assert_eq!(lbfgs.gauss_newton_steps, 0);
    assert!(lbfgs.end.unwrap().max_relative > 10.0 * gn.end.unwrap().max_relative);
}

/// The rest-mesh shape term's continuation (D16) on the exact round trip of
/// `gauss_newton_converges_where_lbfgs_crawls`: three stages with the term (its weight divided
/// by 10 per stage), then one without, and the inverse's Newton solve from the result: the
/// forward equilibrium ends within 1e-7 of the diagonal, the Newton solve converges, and the
/// known rest shape is recovered to 1e-6 of its diagonal.
#[test]
fn the_shape_term_continuation_ends_on_the_exact_design() {
    let (x0, problem) = exact_round_trip();
    let mut rest = problem.target().to_vec();
    let params = FallbackParams {
        max_iterations: 12,
        distance_tolerance: 1e-7,
        shape_weight: 1.0,
        newton_polish: true,
        ..FallbackParams::default()
    };
    let info = balloon_design::optimise_rest_shape(
        &problem,
        &params,
        &StaticParams::default(),
        &mut rest,
        |p| {
            eprintln!("{p:?}");
            true
        },
    )
    .unwrap();
    eprintln!("{info:?}");
    assert_eq!(info.shape_stages, 3, "{info:?}");
    assert!(info.polished, "{info:?}");
    assert!(info.end.unwrap().max_relative <= 1e-7, "{info:?}");
    let recovered = balloon_design::distance(&balloon_design::rigidly_aligned(&rest, &x0), &x0);
    assert!(recovered.max_relative < 1e-6, "{recovered:?}");
    let check = balloon_design::forward_check(&problem, &rest, &StaticParams::default()).unwrap();
    assert!(check.distance.max_relative <= 1e-7, "{:?}", check.distance);
}

/// The same continuation with the bending term of D17 instead of the shape term (`kappa_0 =
/// 1`): it too ends on the exact design, so the bending term biases only the stages that
/// carry it.
#[test]
fn the_bending_term_continuation_ends_on_the_exact_design() {
    let (x0, problem) = exact_round_trip();
    let mut rest = problem.target().to_vec();
    let params = FallbackParams {
        max_iterations: 12,
        distance_tolerance: 1e-7,
        bending_weight: 1.0,
        newton_polish: true,
        ..FallbackParams::default()
    };
    let info = balloon_design::optimise_rest_shape(
        &problem,
        &params,
        &StaticParams::default(),
        &mut rest,
        |_| true,
    )
    .unwrap();
    eprintln!("{info:?}");
    assert_eq!(info.shape_stages, 3, "{info:?}");
    assert!(info.end.unwrap().max_relative <= 1e-7, "{info:?}");
    let recovered = balloon_design::distance(&balloon_design::rigidly_aligned(&rest, &x0), &x0);
    eprintln!("rest vs X0: {recovered:?}");
    assert!(recovered.max_relative < 1e-6, "{recovered:?}");
}

/// A flat-faced target (a box, 56 vertices): no rest shape holds a flat face under pressure,
/// so the inverse solve does not converge; the shape optimisation that follows reduces the
/// distance of the forward equilibrium to the target strictly, the independent forward check
/// from the designed rest shape lands on the same equilibrium, and the design still reports
/// `converged = false`. The membrane and the neo-Hookean prism.
#[test]
fn the_fallback_reduces_the_distance_on_a_flat_faced_box() {
    let target =
        balloon_mesh::generate::box_mesh(nalgebra::Vector3::new(0.1, 0.08, 0.06), 3).unwrap();
    for material in [membrane(), prism()] {
        let problem =
            DesignProblem::try_new(&target, vec![H; target.num_triangles()], material, 2.0e3)
                .unwrap();
        let params = |mode| DesignParams {
            inverse: InverseParams {
                max_halvings: 4,
                ..InverseParams::default()
            },
            fallback: FallbackParams {
                mode,
                max_iterations: 40,
                ..FallbackParams::default()
            },
            ..DesignParams::default()
        };
        let plain = design(&problem, &params(FallbackMode::Off), |_| true).unwrap();
        assert!(!plain.inverse.converged);
        assert!(plain.inverse.fallback.is_none());
        let mut steps = 0;
        let result = design(&problem, &params(FallbackMode::Unconverged), |p| {
            if let DesignProgress::Fallback(_) = p {
                steps += 1;
            }
            true
        })
        .unwrap();
        eprintln!(
            "inverse alone: {:?}; with the fallback: {:?}, {:?}",
            plain.check.distance, result.check.distance, result.inverse.fallback
        );
        assert!(
            !result.inverse.converged,
            "the fallback does not claim an exact design"
        );
        let fallback = result.inverse.fallback.clone().expect("the fallback ran");
        assert_eq!(fallback.iterations, steps);
        assert!(fallback.iterations > 0);
        assert_ne!(fallback.stopped, FallbackStop::NoEquilibrium);
        let (start, end) = (fallback.start.unwrap(), fallback.end.unwrap());
        assert!(fallback.objective_end < fallback.objective_start);
        assert_eq!(start, plain.check.distance);
        assert!(end.rms < 0.85 * start.rms, "{start:?} -> {end:?}");
        assert!(end.max < start.max, "{start:?} -> {end:?}");
        // The forward check from the designed rest shape finds the optimised equilibrium.
        assert!(
            (result.check.distance.rms - end.rms).abs() < 1e-6 * end.rms,
            "{:?} vs {end:?}",
            result.check.distance
        );
        assert!(result.check.converged);
    }
}

/// Stopping from the progress callback (Ctrl-C) keeps the best rest shape so far: the
/// optimisation stops after the first accepted step, which already reduced the distance.
#[test]
fn an_interrupted_fallback_keeps_its_best_step() {
    let target =
        balloon_mesh::generate::box_mesh(nalgebra::Vector3::new(0.1, 0.08, 0.06), 2).unwrap();
    let problem =
        DesignProblem::try_new(&target, vec![H; target.num_triangles()], membrane(), 2.0e3)
            .unwrap();
    let mut rest = problem.target().to_vec();
    let inverse = InverseParams {
        max_halvings: 4,
        ..InverseParams::default()
    };
    let info = balloon_design::design_rest_shape(&problem, &inverse, &mut rest, |_| true).unwrap();
    assert!(!info.converged);
    let start = rest.clone();
    let fallback = balloon_design::optimise_rest_shape(
        &problem,
        &FallbackParams::default(),
        &StaticParams::default(),
        &mut rest,
        |_| false,
    )
    .unwrap();
    assert_eq!(fallback.stopped, FallbackStop::Interrupted);
    assert_eq!(fallback.iterations, 1);
    assert_ne!(rest, start);
    assert!(fallback.end.unwrap().rms < fallback.start.unwrap().rms);
    let check = balloon_design::forward_check(&problem, &rest, &StaticParams::default()).unwrap();
    assert!((check.distance.rms - fallback.end.unwrap().rms).abs() < 1e-6 * check.distance.rms);
}
