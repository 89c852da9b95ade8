//! Set-up shared by the unit tests of the rest-mesh terms.

use balloon_material::{Lame, MaterialModel, NeoHookean};
use balloon_shell::ShellMaterialModel;

use crate::problem::DesignProblem;

/// The 42-vertex icosphere of radius 0.05 m stretched to semi-axes 0.06, 0.05 and 0.04 m as the
/// target, a 1 mm neo-Hookean prism wall (E = 1 MPa, nu = 0.45), 1 kPa.
pub(crate) fn ellipsoid_problem() -> DesignProblem {
    let mut mesh = balloon_mesh::generate::icosphere(0.05, 1).unwrap();
    let x: Vec<f64> = mesh
        .positions_flat()
        .chunks(3)
        .flat_map(|p| [p[0] * 1.2, p[1], p[2] * 0.8])
        .collect();
    mesh.set_positions_flat(&x);
    let lame = Lame::try_from_young_poisson(1.0e6, 0.45).unwrap();
    let material = ShellMaterialModel::Solid(MaterialModel::NeoHookean(NeoHookean::new(lame)));
    DesignProblem::try_new(&mesh, vec![1e-3; mesh.num_triangles()], material, 1e3).unwrap()
}

/// Checks `value_gradient`'s gradient at `rest` against central differences of its value
/// (step `h`) along four deterministic directions, to `tolerance` relative (with `floor` as the
/// smallest magnitude compared against).
pub(crate) fn check_gradient(
    value_gradient: impl Fn(&[f64]) -> (f64, Vec<f64>),
    rest: &[f64],
    h: f64,
    tolerance: f64,
    floor: f64,
) {
    let (_, g) = value_gradient(rest);
    for seed in 0..4 {
        let dir: Vec<f64> = (0..rest.len())
            .map(|i| ((i * 7 + seed * 13) as f64 * 0.61).sin())
            .collect();
        let shifted =
            |s: f64| -> Vec<f64> { rest.iter().zip(&dir).map(|(x, d)| x + s * h * d).collect() };
        let fd = (value_gradient(&shifted(1.0)).0 - value_gradient(&shifted(-1.0)).0) / (2.0 * h);
        let exact: f64 = g.iter().zip(&dir).map(|(a, b)| a * b).sum();
        assert!(
            (fd - exact).abs() <= tolerance * exact.abs().max(floor),
            "seed {seed}: {fd:e} vs {exact:e}"
        );
    }
}

/// Checks a Gauss-Newton product `product(at, dir)` at a zero-residual point `at` (where it is
/// the Hessian's) against central differences (step `h`) of `value_gradient`'s gradient along
/// three deterministic directions, each entry to `1e-6` of the product's largest.
pub(crate) fn check_gauss_newton_product(
    value_gradient: impl Fn(&[f64]) -> (f64, Vec<f64>),
    product: impl Fn(&[f64], &[f64]) -> Vec<f64>,
    at: &[f64],
    h: f64,
) {
    for seed in 0..3 {
        let dir: Vec<f64> = (0..at.len())
            .map(|i| ((i * 5 + seed * 11) as f64 * 0.83).cos())
            .collect();
        let shifted =
            |s: f64| -> Vec<f64> { at.iter().zip(&dir).map(|(x, d)| x + s * h * d).collect() };
        let (gp, gm) = (
            value_gradient(&shifted(1.0)).1,
            value_gradient(&shifted(-1.0)).1,
        );
        let product = product(at, &dir);
        let scale = product.iter().map(|v| v.abs()).fold(0.0, f64::max);
        assert!(scale > 0.0);
        for i in 0..at.len() {
            let fd = (gp[i] - gm[i]) / (2.0 * h);
            assert!(
                (fd - product[i]).abs() <= 1e-6 * scale,
                "seed {seed}, {i}: {fd:e} vs {:e}",
                product[i]
            );
        }
    }
}
