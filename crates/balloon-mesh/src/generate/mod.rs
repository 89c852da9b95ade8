//! Procedural mesh generators. All return closed, outward-oriented triangle meshes.
//!
//! * spheres: [`icosphere`], [`octahedron_sphere`], [`uv_sphere`] (Song 2009, Sec. 3.4);
//! * [`torus`], the subdivided box [`box_mesh`] and the 12-triangle [`cube_soup`] (Diziol, Bender and Bayer 2011's
//!   default body);
//! * [`implicit::implicit_surface`]: any signed distance / implicit function, meshed by marching
//!   tetrahedra and relaxed onto the surface;
//! * [`teddy::teddy`]: the procedural teddy bear (Wang et al. 2015, Fig. 4), built on the implicit mesher;
//! * [`tube::tube`]: a closed cylinder with hemispherical end caps (the bulging tube);
//! * [`fin::finned_ellipsoid`]: a flattened ellipsoid with a thin fin (thin flat parts under
//!   pressure);
//! * [`wing::winged_ellipsoid`]: a small flattened ellipsoid with two thin wings, mapped from an
//!   icosphere (thin flat parts at a few hundred to a few thousand vertices).

pub mod fin;
pub mod implicit;
pub mod teddy;
pub mod tube;
pub mod wing;

pub use fin::{FinParams, finned_ellipsoid};
pub use implicit::{ImplicitParams, implicit_surface};
pub use teddy::{TeddyParams, TeddyPart, teddy, teddy_vertex_parts};
pub use tube::tube;
pub use wing::{WingParams, winged_ellipsoid};

use crate::{MeshError, TriMesh};
use nalgebra::{Point3, Vector3};
use std::collections::HashMap;

fn check_radius(radius: f64) -> Result<(), MeshError> {
    if radius.is_finite() && radius > 0.0 {
        Ok(())
    } else {
        Err(MeshError::InvalidParameter {
            name: "radius",
            value: radius.to_string(),
            reason: "must be a positive finite length in metres".into(),
        })
    }
}

/// Splits every triangle into four, projecting new edge midpoints to the sphere of `radius`
/// about the origin. Shared midpoints are reused so the result stays watertight.
fn subdivide_on_sphere(mesh: &TriMesh, radius: f64) -> TriMesh {
    let mut vertices = mesh.vertices.clone();
    let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
    let mut midpoint = |a: usize, b: usize, vertices: &mut Vec<Point3<f64>>| -> usize {
        let key = (a.min(b), a.max(b));
        *mid.entry(key).or_insert_with(|| {
            let m = (vertices[a].coords + vertices[b].coords) * 0.5;
            vertices.push(Point3::from(m.normalize() * radius));
            vertices.len() - 1
        })
    };
    let mut triangles = Vec::with_capacity(mesh.triangles.len() * 4);
    for &[a, b, c] in &mesh.triangles {
        let ab = midpoint(a, b, &mut vertices);
        let bc = midpoint(b, c, &mut vertices);
        let ca = midpoint(c, a, &mut vertices);
        triangles.extend_from_slice(&[[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    TriMesh::new(vertices, triangles)
}

/// Icosphere of the given `radius` (m) centred at the origin: a regular icosahedron subdivided
/// `subdivisions` times (each level splits every triangle into four). Level `k` has
/// `10 * 4^k + 2` vertices (level 4: 2562).
pub fn icosphere(radius: f64, subdivisions: u32) -> Result<TriMesh, MeshError> {
    check_radius(radius)?;
    if subdivisions > 8 {
        return Err(MeshError::InvalidParameter {
            name: "subdivisions",
            value: subdivisions.to_string(),
            reason: "at most 8 (655362 vertices)".into(),
        });
    }
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let raw = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let vertices = raw
        .iter()
        .map(|p| Point3::from(Vector3::new(p[0], p[1], p[2]).normalize() * radius))
        .collect();
    let triangles = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let mut mesh = TriMesh::new(vertices, triangles);
    for _ in 0..subdivisions {
        mesh = subdivide_on_sphere(&mesh, radius);
    }
    Ok(mesh)
}

/// Sphere by octahedron subdivision (Song 2009, Sec. 3.4): a regular octahedron subdivided `level`
/// times, vertices projected to `radius` (m). Level `n` has `4^(n+1) + 2` vertices.
pub fn octahedron_sphere(radius: f64, level: u32) -> Result<TriMesh, MeshError> {
    check_radius(radius)?;
    if level > 9 {
        return Err(MeshError::InvalidParameter {
            name: "level",
            value: level.to_string(),
            reason: "at most 9".into(),
        });
    }
    let r = radius;
    let vertices = vec![
        Point3::new(r, 0.0, 0.0),
        Point3::new(-r, 0.0, 0.0),
        Point3::new(0.0, r, 0.0),
        Point3::new(0.0, -r, 0.0),
        Point3::new(0.0, 0.0, r),
        Point3::new(0.0, 0.0, -r),
    ];
    let triangles = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    let mut mesh = TriMesh::new(vertices, triangles);
    for _ in 0..level {
        mesh = subdivide_on_sphere(&mesh, radius);
    }
    Ok(mesh)
}

/// UV sphere (Song 2009, Sec. 3.4) of `radius` (m) with `slices` meridians (>= 3) and `stacks`
/// latitude bands (>= 2), two pole vertices. Vertex count `slices * (stacks - 1) + 2`.
/// Vertex 0 is the north pole (+z), the last vertex the south pole.
pub fn uv_sphere(radius: f64, slices: usize, stacks: usize) -> Result<TriMesh, MeshError> {
    check_radius(radius)?;
    if slices < 3 {
        return Err(MeshError::InvalidParameter {
            name: "slices",
            value: slices.to_string(),
            reason: "at least 3".into(),
        });
    }
    if stacks < 2 {
        return Err(MeshError::InvalidParameter {
            name: "stacks",
            value: stacks.to_string(),
            reason: "at least 2".into(),
        });
    }
    let mut vertices = vec![Point3::new(0.0, 0.0, radius)];
    for i in 1..stacks {
        let theta = std::f64::consts::PI * i as f64 / stacks as f64;
        for j in 0..slices {
            let phi = 2.0 * std::f64::consts::PI * j as f64 / slices as f64;
            vertices.push(Point3::new(
                radius * theta.sin() * phi.cos(),
                radius * theta.sin() * phi.sin(),
                radius * theta.cos(),
            ));
        }
    }
    let south = vertices.len();
    vertices.push(Point3::new(0.0, 0.0, -radius));
    let ring = |i: usize, j: usize| 1 + (i - 1) * slices + (j % slices);
    let mut triangles = Vec::new();
    for j in 0..slices {
        triangles.push([0, ring(1, j), ring(1, j + 1)]);
    }
    for i in 1..stacks - 1 {
        for j in 0..slices {
            let (a, b, c, d) = (
                ring(i, j),
                ring(i, j + 1),
                ring(i + 1, j),
                ring(i + 1, j + 1),
            );
            triangles.push([a, c, d]);
            triangles.push([a, d, b]);
        }
    }
    for j in 0..slices {
        triangles.push([south, ring(stacks - 1, j + 1), ring(stacks - 1, j)]);
    }
    Ok(TriMesh::new(vertices, triangles))
}

/// `value` as a positive finite length (m), else an error naming `name`.
fn check_positive(name: &'static str, value: f64) -> Result<(), MeshError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(MeshError::InvalidParameter {
            name,
            value: value.to_string(),
            reason: "must be a positive finite length in metres".into(),
        })
    }
}

fn check_count(name: &'static str, value: usize, min: usize, max: usize) -> Result<(), MeshError> {
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(MeshError::InvalidParameter {
            name,
            value: value.to_string(),
            reason: format!("must be between {min} and {max}"),
        })
    }
}

/// Torus about the z axis, centred at the origin: tube centre circle of radius `major_radius`
/// (m) in the xy plane, tube radius `minor_radius` (m, `< major_radius`), `major_segments`
/// (>= 3) around z and `minor_segments` (>= 3) around the tube. Vertex `(i, j)` sits at angle
/// `2 pi i / major_segments` around z and `2 pi j / minor_segments` around the tube; genus 1,
/// `major_segments * minor_segments` vertices, twice as many triangles.
pub fn torus(
    major_radius: f64,
    minor_radius: f64,
    major_segments: usize,
    minor_segments: usize,
) -> Result<TriMesh, MeshError> {
    check_positive("major_radius", major_radius)?;
    check_positive("minor_radius", minor_radius)?;
    if minor_radius >= major_radius {
        return Err(MeshError::InvalidParameter {
            name: "minor_radius",
            value: minor_radius.to_string(),
            reason: format!("must be smaller than major_radius = {major_radius}"),
        });
    }
    check_count("major_segments", major_segments, 3, 100_000)?;
    check_count("minor_segments", minor_segments, 3, 100_000)?;
    let (m, n) = (major_segments, minor_segments);
    let tau = 2.0 * std::f64::consts::PI;
    let mut vertices = Vec::with_capacity(m * n);
    for i in 0..m {
        let u = tau * i as f64 / m as f64;
        for j in 0..n {
            let v = tau * j as f64 / n as f64;
            let rho = major_radius + minor_radius * v.cos();
            vertices.push(Point3::new(
                rho * u.cos(),
                rho * u.sin(),
                minor_radius * v.sin(),
            ));
        }
    }
    let id = |i: usize, j: usize| (i % m) * n + (j % n);
    let mut triangles = Vec::with_capacity(2 * m * n);
    for i in 0..m {
        for j in 0..n {
            // (d/du x d/dv) points out of the tube.
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    Ok(TriMesh::new(vertices, triangles))
}

/// Axis-aligned box of edge lengths `size` (m) centred at the origin, every face split into a
/// `subdivisions x subdivisions` grid of quads (two triangles each) so that it can deform and
/// inflate. `6 n^2 + 2` vertices and `12 n^2` triangles for `n = subdivisions` (1..=1000).
pub fn box_mesh(size: Vector3<f64>, subdivisions: usize) -> Result<TriMesh, MeshError> {
    check_positive("size.x", size.x)?;
    check_positive("size.y", size.y)?;
    check_positive("size.z", size.z)?;
    check_count("subdivisions", subdivisions, 1, 1000)?;
    let n = subdivisions;
    // Coordinate of grid line `i` along axis `k`: exactly +-size/2 at the ends, so that the
    // faces' shared rim vertices coincide bit for bit and weld exactly.
    let coord = |k: usize, i: usize| size[k] * (i as f64 / n as f64 - 0.5);
    let mut vertices: Vec<Point3<f64>> = Vec::new();
    let mut index: HashMap<[usize; 3], usize> = HashMap::new();
    let mut triangles = Vec::with_capacity(12 * n * n);
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [0, n] {
            let mut vid = |i: usize, j: usize| {
                let mut g = [0usize; 3];
                g[axis] = side;
                g[u] = i;
                g[v] = j;
                *index.entry(g).or_insert_with(|| {
                    vertices.push(Point3::new(coord(0, g[0]), coord(1, g[1]), coord(2, g[2])));
                    vertices.len() - 1
                })
            };
            for i in 0..n {
                for j in 0..n {
                    let (a, b, c, d) = (vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1));
                    // e_u x e_v = e_axis: counter-clockwise seen from +axis.
                    if side == n {
                        triangles.push([a, b, c]);
                        triangles.push([a, c, d]);
                    } else {
                        triangles.push([a, c, b]);
                        triangles.push([a, d, c]);
                    }
                }
            }
        }
    }
    Ok(TriMesh::new(vertices, triangles))
}

/// A closed, outward-oriented axis-aligned cube of side `side` (m) with its minimum corner at
/// `min`: the 8 corners in the lattice's cell-corner order ([`crate::lattice::CORNERS`]) and 12
/// triangles, the default body of Diziol, Bender and Bayer 2011's Fig. 4 scene. A negative `side` turns it inside
/// out.
pub fn cube_soup(min: Point3<f64>, side: f64) -> TriMesh {
    let v: Vec<Point3<f64>> = crate::lattice::CORNERS
        .iter()
        .map(|c| min + Vector3::new(c[0] as f64, c[1] as f64, c[2] as f64) * side)
        .collect();
    let quads = [
        [0, 3, 2, 1],
        [4, 5, 6, 7],
        [0, 1, 5, 4],
        [1, 2, 6, 5],
        [2, 3, 7, 6],
        [3, 0, 4, 7],
    ];
    let mut tris = Vec::new();
    for q in quads {
        tris.push([q[0], q[1], q[2]]);
        tris.push([q[0], q[2], q[3]]);
    }
    TriMesh::new(v, tris)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::validate::validate_closed_manifold;

    #[test]
    fn torus_and_box_are_closed_outward_with_exact_counts() {
        // Torus volume 2 pi^2 R r^2 and genus 1; box volume is the product of its sides.
        let t = torus(1.0, 0.25, 64, 24).unwrap();
        validate_closed_manifold(&t).unwrap();
        assert_eq!(t.num_vertices(), 64 * 24);
        let exact = 2.0 * std::f64::consts::PI.powi(2) * 0.25 * 0.25;
        let v = crate::geometry::enclosed_volume(&t);
        assert!((v / exact - 1.0).abs() < 0.02, "{v} vs {exact}");
        let topo = crate::topology::Topology::new(&t);
        assert_eq!(topo.genus(&t.triangles), Some(1));
        let b = box_mesh(Vector3::new(1.0, 2.0, 3.0), 5).unwrap();
        validate_closed_manifold(&b).unwrap();
        assert_eq!(b.num_vertices(), 6 * 25 + 2);
        assert_eq!(b.num_triangles(), 12 * 25);
        assert!((crate::geometry::enclosed_volume(&b) - 6.0).abs() < 1e-12);
        assert!(torus(1.0, 1.5, 8, 8).is_err());
        assert!(box_mesh(Vector3::new(1.0, 0.0, 1.0), 2).is_err());
        assert!(box_mesh(Vector3::new(1.0, 1.0, 1.0), 0).is_err());
    }

    #[test]
    fn spheres_are_valid_closed_manifolds() {
        for m in [
            icosphere(0.1, 2).unwrap(),
            octahedron_sphere(0.1, 3).unwrap(),
            uv_sphere(0.1, 12, 6).unwrap(),
        ] {
            validate_closed_manifold(&m).unwrap();
        }
    }

    fn volume(m: &TriMesh) -> f64 {
        m.triangles
            .iter()
            .map(|&[a, b, c]| {
                m.vertices[a]
                    .coords
                    .dot(&m.vertices[b].coords.cross(&m.vertices[c].coords))
                    / 6.0
            })
            .sum()
    }

    #[test]
    fn spheres_have_expected_counts_and_positive_volume() {
        let ico = icosphere(1.0, 4).unwrap();
        assert_eq!(ico.num_vertices(), 2562);
        assert_eq!(ico.num_triangles(), 5120);
        let oct = octahedron_sphere(2.0, 3).unwrap();
        assert_eq!(oct.num_vertices(), 4usize.pow(4) + 2);
        let uv = uv_sphere(0.5, 16, 8).unwrap();
        assert_eq!(uv.num_vertices(), 16 * 7 + 2);
        for (m, r) in [(&ico, 1.0), (&oct, 2.0), (&uv, 0.5)] {
            let v = volume(m);
            let exact = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
            assert!(
                v > 0.0 && v < exact && v > 0.6 * exact,
                "volume {v} vs {exact}"
            );
        }
        assert!(icosphere(-1.0, 1).is_err());
        assert!(uv_sphere(1.0, 2, 5).is_err());
    }

    #[test]
    fn cube_soup_is_a_closed_outward_cube() {
        let cube = cube_soup(Point3::new(1.0, -2.0, 0.5), 2.0);
        assert_eq!((cube.num_vertices(), cube.num_triangles()), (8, 12));
        validate_closed_manifold(&cube).unwrap();
        let v = crate::geometry::enclosed_volume(&cube);
        assert!((v - 8.0).abs() < 1e-12, "{v}");
        assert_eq!(cube.vertices[6], Point3::new(3.0, 0.0, 2.5));
    }
}
