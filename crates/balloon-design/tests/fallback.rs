//! The shape-optimisation fallback: the adjoint gradient of the distance objective against
//! central differences of forward static solves, and a target with no exact design (flat
//! faces) whose distance the fallback reduces.

use balloon_design::{
    DesignParams, DesignProblem, DesignProgress, FallbackMode, FallbackParams, FallbackStop,
    InverseParams, ShapeObjective, design,
};
use balloon_integrate::statics::StaticParams;
use balloon_material::membrane::{MembraneModel, MembraneNeoHookean};
use balloon_material::{Lame, MaterialModel, NeoHookean};
use balloon_shell::ShellMaterialModel;

const H: f64 = 1.0e-3;

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

/// `dD/dX` by the adjoint (`docs/design.md`, D12) against central differences of `D` along
/// random directions, each `D` from its own forward static solve (tolerance 1e-12), on a
/// 42-vertex ellipsoid whose rest shape is not an exact design (a scaled, perturbed target):
/// the membrane and the neo-Hookean prism.
#[test]
fn adjoint_gradient_matches_central_differences() {
    let mut target = balloon_mesh::generate::icosphere(0.05, 1).unwrap();
    for v in &mut target.vertices {
        v.y *= 0.8;
        v.z *= 0.6;
    }
    for (material, p) in [(membrane(), 3.0e3), (prism(), 3.0e3)] {
        let problem =
            DesignProblem::try_new(&target, vec![H; target.num_triangles()], material, p).unwrap();
        let rest: Vec<f64> = problem
            .target()
            .iter()
            .enumerate()
            .map(|(i, x)| 0.9 * x + 1e-3 * noise(i, 1))
            .collect();
        let mut objective = ShapeObjective::new(&problem, &StaticParams::default(), 1e-12).unwrap();
        let e = objective
            .evaluate(&rest, true)
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
            eprintln!(
                "direction {seed}: adjoint {adjoint:e}, central difference {fd:e}, rel {rel:e}"
            );
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
    }
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
