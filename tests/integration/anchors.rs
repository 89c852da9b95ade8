//! Anchors and thickness maps across crates: a shell balloon hard-pinned by its neck with a
//! per-face wall, spring anchors, and a two-layer body hung from fixed particles.

use balloon::gas::GasKind;
use balloon::shell::ShellBalloon;
use balloon::two_layer::{ExplicitMethod, TwoLayerBody};

/// Per-face thickness of a sphere: `thick` for faces whose centroid is above z = 0.
fn wall(mesh: &balloon_mesh::TriMesh, thin: f64, thick: f64) -> Vec<f64> {
    mesh.triangles
        .iter()
        .map(|t| {
            let z: f64 = t.iter().map(|&v| mesh.vertices[v].z).sum();
            if z > 0.0 { thick } else { thin }
        })
        .collect()
}

#[test]
fn a_pinned_neck_stays_put_while_a_wall_thick_on_top_inflates_lopsided() {
    let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
    let neck: Vec<usize> = (0..mesh.num_vertices())
        .filter(|&v| mesh.vertices[v].z < -0.085)
        .collect();
    let build = |pinned: bool| {
        let mut sim = ShellBalloon::new(mesh.clone())
            .with_thickness_per_face(wall(&mesh, 3e-4, 6e-4))
            .with_gas(GasKind::Constant)
            .with_gauge_pressure(1500.0)
            .build()
            .unwrap();
        if pinned {
            sim.set_pinned_vertices(neck.clone()).unwrap();
        }
        for _ in 0..30 {
            sim.step().unwrap();
        }
        sim
    };
    // Free: the thin lower half bulges further than the thick upper one, so the centroid of
    // the vertices moves down.
    let free = build(false);
    let x = free.positions();
    let n = x.len() / 3;
    let cz: f64 = (0..n).map(|v| x[3 * v + 2]).sum::<f64>() / n as f64;
    let rest_cz: f64 = mesh.vertices.iter().map(|p| p.z).sum::<f64>() / n as f64;
    assert!(cz < rest_cz - 1e-4, "centroid z {cz} vs rest {rest_cz}");
    // Pinned: the neck keeps its rest position bit for bit; the balloon still inflates.
    let held = build(true);
    let x = held.positions();
    for &v in &neck {
        let p = mesh.vertices[v];
        assert_eq!(x[3 * v..3 * v + 3], [p.x, p.y, p.z], "vertex {v}");
    }
    assert!(held.gas_volume() > 1.05 * held.rest_gas_volume());
}

#[test]
fn a_two_layer_body_hangs_from_its_fixed_top_particles() {
    let body = TwoLayerBody::uv_sphere(10, 8).with_gravity(9.81);
    let mut sim = body.simulate(ExplicitMethod::Rk4, 2e-4).unwrap();
    let rest = sim.positions().to_vec();
    let n = rest.len() / 3;
    let top_z = (0..n)
        .map(|i| rest[3 * i + 2])
        .fold(f64::NEG_INFINITY, f64::max);
    let top: Vec<usize> = (0..n).filter(|&i| rest[3 * i + 2] > top_z - 1e-9).collect();
    sim.fix_particles(&top).unwrap();
    sim.run(500).unwrap();
    let x = sim.positions();
    for &i in &top {
        assert_eq!(x[3 * i..3 * i + 3], rest[3 * i..3 * i + 3], "particle {i}");
    }
    let cz: f64 = (0..n).map(|i| x[3 * i + 2] - rest[3 * i + 2]).sum::<f64>() / n as f64;
    assert!(cz < -1e-5, "the body sags under gravity: mean dz {cz}");
    assert!(sim.fix_particles(&[n]).is_err());
}
