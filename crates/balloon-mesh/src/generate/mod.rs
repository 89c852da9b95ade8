//! Procedural mesh generators. All return closed, outward-oriented triangle meshes.

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

/// Sphere by octahedron subdivision (seed 004, Sec. 3.4): a regular octahedron subdivided `level`
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

/// UV sphere (seed 004, Sec. 3.4) of `radius` (m) with `slices` meridians (>= 3) and `stacks`
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
