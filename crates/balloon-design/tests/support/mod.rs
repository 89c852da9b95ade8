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
    inflate_with_thickness(rest, material, p, vec![H; rest.num_triangles()])
}

/// [`inflate`] with the rest thickness map `thickness` (one per face, m).
pub fn inflate_with_thickness(
    rest: &TriMesh,
    material: &ShellMaterialModel,
    p: f64,
    thickness: Vec<f64>,
) -> Vec<f64> {
    inflate_with_wall(rest, material, p, thickness, 0.0)
}

/// [`inflate_with_thickness`] with the wall's bending stiffness, `bending` times the plate's
/// (`ShellSystem::set_wall_bending`; 0: none).
pub fn inflate_with_wall(
    rest: &TriMesh,
    material: &ShellMaterialModel,
    p: f64,
    thickness: Vec<f64>,
    bending: f64,
) -> Vec<f64> {
    let gas = PressureLoad::new(ConstantPressure::try_new(p).unwrap())
        .with_ambient_pressure(0.0)
        .unwrap()
        .with_follower_term(true);
    let mut x = rest.positions_flat();
    let mut shell = ShellSystem::from_rest_shape(
        &x,
        rest.triangles.clone(),
        thickness,
        1000.0,
        material.clone(),
        gas,
    )
    .unwrap();
    shell.set_wall_bending(&x, bending).unwrap();
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

/// The model `name` (`teddy`: the built-in Teddy; else a file of the shared meshes beside the
/// checkout) scaled to a largest bounding-box side of 0.1 m, centred at the origin; `None`
/// when the shared file is not there.
#[allow(dead_code)] // Used by the real-mesh tests, not by every test file.
pub fn model_at_10cm(name: &str) -> Option<TriMesh> {
    if name == "teddy" {
        return Some(fit(balloon_mesh::builtin("teddy").unwrap(), 0.1));
    }
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/meshes")
        .join(name);
    path.exists()
        .then(|| fit(balloon_mesh::io::read_mesh(&path).unwrap(), 0.1))
}

/// `mesh` scaled so that its largest bounding-box side is `size` (m), centred at the origin.
fn fit(mut mesh: TriMesh, size: f64) -> TriMesh {
    let x = mesh.positions_flat();
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in x.chunks(3) {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let side = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    let s = size / side;
    let y: Vec<f64> = x
        .chunks(3)
        .flat_map(|p| (0..3).map(move |k| (p[k] - 0.5 * (lo[k] + hi[k])) * s))
        .collect();
    mesh.set_positions_flat(&y);
    mesh
}
