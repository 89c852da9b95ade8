//! Set-up shared by the design crate's integration tests.

use balloon_gas::{ConstantPressure, PressureLoad};
use balloon_integrate::statics::{StaticParams, StaticSolver};
use balloon_mesh::TriMesh;
use balloon_shell::statics::{GasTerm, StaticShell};
use balloon_shell::{ShellMaterialModel, ShellSystem};

/// Rest wall thickness of every test design, m.
pub const H: f64 = 1.0e-3;

/// The static equilibrium of the rest shape `rest` under the gauge pressure `p` (static solve
/// to a relative residual of 1e-11, the wall at its rest thickness [`H`] as the design
/// assumes): the forward problem a round trip starts from.
pub fn inflate(rest: &TriMesh, material: &ShellMaterialModel, p: f64) -> Vec<f64> {
    let gas = PressureLoad::new(ConstantPressure::try_new(p).unwrap())
        .with_ambient_pressure(0.0)
        .unwrap()
        .with_follower_term(true);
    let mut x = rest.positions_flat();
    let mut shell = ShellSystem::from_rest_shape(
        &x,
        rest.triangles.clone(),
        vec![H; rest.num_triangles()],
        1000.0,
        material.clone(),
        gas,
    )
    .unwrap();
    let mut statics = StaticShell::new(&mut shell, GasTerm::Own, true);
    let params = StaticParams {
        tolerance: 1e-11,
        ..StaticParams::default()
    };
    let info = StaticSolver::new(params)
        .unwrap()
        .solve_with_continuation(&mut statics, 0.0, &mut x, None)
        .unwrap();
    assert!(info.converged);
    x
}

/// The icosphere of radius 0.05 m at subdivision `level`, scaled to the ellipsoid of
/// semi-axes 0.05, 0.04 and 0.03 m.
pub fn ellipsoid(level: u32) -> TriMesh {
    let mut m = balloon_mesh::generate::icosphere(0.05, level).unwrap();
    for v in &mut m.vertices {
        v.y *= 0.8;
        v.z *= 0.6;
    }
    m
}
