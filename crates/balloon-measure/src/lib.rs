//! Measurements that do not go through the quantity under test: the volume a surface encloses
//! and the material volume of a shell from the positions, the gauge pressure a shell's pressure
//! forces imply, lattice cell volumes, distances between states, and the peer comparison's
//! sphere. The workspace's integration tests (`tests/`), the validation and the benchmarks
//! (`cargo xtask validate`, `cargo xtask bench`) all take them from here.

use balloon::gas::GasModel;
use balloon::mesh::geometry;
use balloon::mesh::lattice::Lattice;
use balloon::shell::{ShellMaterial, ShellSimulation};
use nalgebra::Point3;

/// The volume the surface `x` (flat positions) over `triangles` encloses, by the divergence
/// theorem on the mesh (Wang et al. 2015, Eq. 13; the one kernel,
/// `balloon_mesh::geometry::enclosed_volume_flat`), measured from the positions: not the volume
/// a gas model keeps in its state.
pub fn mesh_volume(x: &[f64], triangles: &[[usize; 3]]) -> f64 {
    geometry::enclosed_volume_flat(x, triangles)
}

/// The gas pressure the simulation's pressure forces imply at its current shape, Pa (absolute
/// minus ambient: the gauge pressure): `-dE/dV` along a uniform scaling of the surface about its
/// centroid, by central differences of the gas potential `E` (whose negative gradient are the
/// pressure forces, Eq. 15) over the change of the volume the mesh encloses ([`mesh_volume`]).
/// Neither the gas state's pressure nor its volume enter.
pub fn implied_gauge_pressure<M: ShellMaterial, G: GasModel>(sim: &ShellSimulation<M, G>) -> f64 {
    let x = sim.positions();
    let tris = sim.triangles();
    let n = (x.len() / 3) as f64;
    let mut c = [0.0; 3];
    for p in x.chunks_exact(3) {
        for k in 0..3 {
            c[k] += p[k] / n;
        }
    }
    let scaled = |s: f64| -> Vec<f64> {
        x.iter()
            .enumerate()
            .map(|(i, v)| c[i % 3] + s * (v - c[i % 3]))
            .collect()
    };
    let eps = 1e-4;
    let (xp, xm) = (scaled(1.0 + eps), scaled(1.0 - eps));
    let energy = |x: &[f64]| {
        sim.system()
            .gas_energy(sim.time(), x)
            .expect("gas energy")
            .expect("this gas has a potential")
    };
    -(energy(&xp) - energy(&xm)) / (mesh_volume(&xp, tris) - mesh_volume(&xm, tris))
}

/// Each lattice cell's volume at `points`: the sum of its five tetrahedra's signed volumes,
/// computed here from the positions (not the cell-volume solver's own error measure).
pub fn cell_volumes(points: &[Point3<f64>], lattice: &Lattice) -> Vec<f64> {
    let tet = |t: &[usize; 4]| {
        let o = points[t[0]];
        (points[t[1]] - o)
            .cross(&(points[t[2]] - o))
            .dot(&(points[t[3]] - o))
            / 6.0
    };
    lattice
        .cell_tets
        .iter()
        .map(|tets| tets.iter().map(|&k| tet(&lattice.tet_mesh.tets[k])).sum())
        .collect()
}

/// The largest `|v / v0 - 1|` over matching entries.
pub fn max_relative_change(v: &[f64], v0: &[f64]) -> f64 {
    v.iter()
        .zip(v0)
        .map(|(a, b)| (a / b - 1.0).abs())
        .fold(0.0, f64::max)
}

/// The shell's material volume `sum_e h_e A_e` (Wang et al. 2015, Eq. 26) for flat positions `x`, per-face
/// thickness `thickness` (m), computed here from the triangle areas (not the projection's own
/// measure).
pub fn shell_material_volume(x: &[f64], triangles: &[[usize; 3]], thickness: &[f64]) -> f64 {
    let p = |v: usize| nalgebra::Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
    triangles
        .iter()
        .zip(thickness)
        .map(|(t, h)| {
            let a = p(t[0]);
            h * 0.5 * (p(t[1]) - a).cross(&(p(t[2]) - a)).norm()
        })
        .sum()
}

/// Length of the bounding-box diagonal of the points `x` (`[x0, y0, z0, x1, ...]`).
pub fn bbox_diagonal(x: &[f64]) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in x.chunks_exact(3) {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    (0..3).map(|c| (hi[c] - lo[c]).powi(2)).sum::<f64>().sqrt()
}

/// Largest distance between corresponding points of `a` and `b`.
pub fn max_vertex_distance(a: &[f64], b: &[f64]) -> f64 {
    a.chunks_exact(3)
        .zip(b.chunks_exact(3))
        .map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max)
}

/// The sphere of the peer comparison (issue 12; `cargo xtask bench --converged sphere`, the
/// `static_profile` example): an icosphere of `level` (5: 10242 vertices) with radius 1 m,
/// StVK with E t = 1155 N/m at t = 1 mm and nu = 1/3, 1 kg of wall in all, the ideal gas at
/// 377 Pa gauge with no ambient pressure, mass damping 20 1/s. A builder, so callers can change
/// the solver settings before `build`.
pub fn peer_sphere(
    level: u32,
) -> Result<balloon::shell::ShellBalloon, Box<dyn std::error::Error + Send + Sync>> {
    use balloon::gas::GasKind;
    use balloon::material::{Lame, MaterialKind, MaterialModel};
    let mesh = balloon::mesh::generate::icosphere(1.0, level)?;
    let thickness = 1e-3;
    let area = geometry::surface_area(&mesh);
    let lame = Lame::try_from_young_poisson(1155.0 / thickness, 1.0 / 3.0)?;
    Ok(balloon::shell::ShellBalloon::new(mesh)
        .with_material(MaterialModel::from_lame(
            MaterialKind::StVenantKirchhoff,
            lame,
        ))
        .with_thickness(thickness)
        .with_density(1.0 / (area * thickness))
        .with_gas(GasKind::Ideal)
        .with_ambient_pressure(0.0)
        .with_gauge_pressure(377.0)
        .configure_integrator(|p| p.mass_damping = 20.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit cube `[0, 1]^3`, outward triangles.
    fn cube() -> (Vec<f64>, Vec<[usize; 3]>) {
        let mut x = Vec::new();
        for i in 0..8 {
            x.extend([(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64]);
        }
        let quads = [
            [0, 2, 3, 1], // z = 0, normal -z
            [4, 5, 7, 6], // z = 1
            [0, 1, 5, 4], // y = 0
            [2, 6, 7, 3], // y = 1
            [0, 4, 6, 2], // x = 0
            [1, 3, 7, 5], // x = 1
        ];
        let tris = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        (x, tris)
    }

    #[test]
    fn the_unit_cube_measures_as_it_should() {
        let (x, tris) = cube();
        assert!((mesh_volume(&x, &tris) - 1.0).abs() < 1e-14);
        // Scaled by 2 and moved: eight times the volume, twice the diagonal.
        let moved: Vec<f64> = x.iter().map(|c| 2.0 * c + 0.3).collect();
        assert!((mesh_volume(&moved, &tris) - 8.0).abs() < 1e-12);
        assert!((bbox_diagonal(&x) - 3f64.sqrt()).abs() < 1e-15);
        assert!((bbox_diagonal(&moved) - 2.0 * 3f64.sqrt()).abs() < 1e-14);
        // Inward triangles enclose a negative volume.
        let inward: Vec<[usize; 3]> = tris.iter().map(|t| [t[0], t[2], t[1]]).collect();
        assert!((mesh_volume(&x, &inward) + 1.0).abs() < 1e-14);
        // A wall of 2 mm on the six unit faces.
        let h = vec![2e-3; tris.len()];
        assert!((shell_material_volume(&x, &tris, &h) - 6.0 * 2e-3).abs() < 1e-15);
        // The largest vertex displacement: vertex 7 moved by (0, 0.3, 0.4).
        let mut y = x.clone();
        y[22] += 0.3;
        y[23] += 0.4;
        y[0] += 0.1;
        assert!((max_vertex_distance(&x, &y) - 0.5).abs() < 1e-15);
    }
}
