//! Mesh geometry: areas, normals, enclosed volume (Wang et al. 2015, Eq. 13) and its gradient,
//! bounding box, angles and centroids.
//!
//! Functions come in two flavours: on a [`TriMesh`], and slice-based (`*_flat`) on
//! `positions: &[f64]` (length `3 N`, `[x0, y0, z0, x1, ...]`, metres) plus
//! `triangles: &[[usize; 3]]`, for solvers that keep positions in one flat vector.
//!
//! All functions assume every triangle index is `< N` (true for meshes returned by the readers
//! and generators; check user-built meshes with [`crate::validate`]); they panic otherwise.

use crate::TriMesh;
use nalgebra::{Point3, Vector3};

#[inline]
fn p3(x: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
}

/// Area (m^2) of the triangle `(a, b, c)`: `|(b - a) x (c - a)| / 2`.
pub fn triangle_area(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>) -> f64 {
    0.5 * (b - a).cross(&(c - a)).norm()
}

/// Area of every triangle (m^2), indexed like `mesh.triangles`.
pub fn face_areas(mesh: &TriMesh) -> Vec<f64> {
    let v = &mesh.vertices;
    mesh.triangles
        .iter()
        .map(|&[a, b, c]| triangle_area(&v[a], &v[b], &v[c]))
        .collect()
}

/// Unit normal of every triangle, `(b - a) x (c - a)` normalised (right-hand rule: outward for an
/// outward-oriented mesh). A zero-area triangle gets the zero vector.
pub fn face_normals(mesh: &TriMesh) -> Vec<Vector3<f64>> {
    let v = &mesh.vertices;
    mesh.triangles
        .iter()
        .map(|&[a, b, c]| {
            (v[b] - v[a])
                .cross(&(v[c] - v[a]))
                .try_normalize(0.0)
                .unwrap_or_else(Vector3::zeros)
        })
        .collect()
}

/// Area-weighted vertex normals: the normalised sum of the (unnormalised, twice-area) face normals
/// of the incident triangles. A vertex without incident area gets the zero vector.
pub fn vertex_normals(mesh: &TriMesh) -> Vec<Vector3<f64>> {
    vertex_normals_flat(&mesh.positions_flat(), &mesh.triangles)
        .chunks_exact(3)
        .map(|c| Vector3::new(c[0], c[1], c[2]))
        .collect()
}

/// `sum_{t ∋ i} (x_b - x_a) x (x_c - x_a)` per vertex `i` (flat, length `3 N`, m^2): twice the
/// area-weighted normal sum `2 sum_{t ∋ i} A_t n_t` of the incident triangles.
pub fn vertex_area_normal_sums_flat(positions: &[f64], triangles: &[[usize; 3]]) -> Vec<f64> {
    let mut out = vec![0.0; positions.len() - positions.len() % 3];
    for &[a, b, c] in triangles {
        let xa = p3(positions, a);
        let an = (p3(positions, b) - xa).cross(&(p3(positions, c) - xa));
        for i in [a, b, c] {
            out[3 * i] += an.x;
            out[3 * i + 1] += an.y;
            out[3 * i + 2] += an.z;
        }
    }
    out
}

/// [`vertex_normals`] on flat positions: unit vertex normals (flat, 3 per vertex), the
/// normalised [`vertex_area_normal_sums_flat`]; a vertex whose sum vanishes gets the zero vector.
pub fn vertex_normals_flat(positions: &[f64], triangles: &[[usize; 3]]) -> Vec<f64> {
    let mut n = vertex_area_normal_sums_flat(positions, triangles);
    for v in n.chunks_exact_mut(3) {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if l > 0.0 {
            v.iter_mut().for_each(|c| *c /= l);
        }
    }
    n
}

/// Barycentric (lumped) vertex areas (m^2): each triangle gives a third of its area to each of its
/// corners, so the sum equals the surface area. The usual lumped-mass weights of a shell.
pub fn vertex_areas(mesh: &TriMesh) -> Vec<f64> {
    let mut a = vec![0.0; mesh.num_vertices()];
    for (t, area) in mesh.triangles.iter().zip(face_areas(mesh)) {
        for &i in t {
            a[i] += area / 3.0;
        }
    }
    a
}

/// Total surface area (m^2).
pub fn surface_area(mesh: &TriMesh) -> f64 {
    face_areas(mesh).iter().sum()
}

/// Total surface area (m^2) of flat positions (see the module doc for the layout).
pub fn surface_area_flat(positions: &[f64], triangles: &[[usize; 3]]) -> f64 {
    triangles
        .iter()
        .map(|&[a, b, c]| {
            let (xa, xb, xc) = (p3(positions, a), p3(positions, b), p3(positions, c));
            0.5 * (xb - xa).cross(&(xc - xa)).norm()
        })
        .sum()
}

/// Enclosed volume (m^3) by the divergence theorem (Wang et al. 2015, Eq. 13):
/// `V = (1/6) sum_t x_a . (x_b x x_c)` over triangles `t = (a, b, c)`.
///
/// Positive for a closed outward-oriented surface; independent of the origin only when the
/// surface is closed.
pub fn enclosed_volume(mesh: &TriMesh) -> f64 {
    let v = &mesh.vertices;
    enclosed_volume_of(mesh.triangles.iter().copied(), |i| v[i].coords)
}

/// [`enclosed_volume`] on flat positions (Wang et al. 2015, Eq. 13).
pub fn enclosed_volume_flat(positions: &[f64], triangles: &[[usize; 3]]) -> f64 {
    enclosed_volume_of(triangles.iter().copied(), |i| p3(positions, i))
}

/// The enclosed-volume kernel behind [`enclosed_volume`], [`enclosed_volume_flat`] and the gas
/// crate's volume: `V = (1/6) sum_t x_a . (x_b x x_c)` over `triangles` with the vertex
/// positions (m) given by `vertex`, summed in triangle order. For callers that keep positions
/// or indices in their own layout (e.g. `[f64; 3]` chunks and `u32` indices).
///
/// ```
/// use balloon_mesh::geometry::{enclosed_volume_flat, enclosed_volume_of};
/// let mesh = balloon_mesh::generate::icosphere(1.0, 1).unwrap();
/// let x = mesh.positions_flat();
/// let compact: Vec<[u32; 3]> = mesh.triangles.iter().map(|t| t.map(|i| i as u32)).collect();
/// let v = enclosed_volume_of(compact.iter().map(|t| t.map(|i| i as usize)), |i| {
///     mesh.vertices[i].coords
/// });
/// assert_eq!(v, enclosed_volume_flat(&x, &mesh.triangles));
/// ```
#[inline]
pub fn enclosed_volume_of(
    triangles: impl IntoIterator<Item = [usize; 3]>,
    vertex: impl Fn(usize) -> Vector3<f64>,
) -> f64 {
    triangles
        .into_iter()
        .map(|[a, b, c]| vertex(a).dot(&vertex(b).cross(&vertex(c))))
        .sum::<f64>()
        / 6.0
}

/// Exact gradient of [`enclosed_volume_flat`] with respect to every coordinate, written into
/// `out` (length `3 N`, m^2; overwritten): `dV/dx_i = (1/6) sum_{t ∋ i} x_j x x_k` where
/// `(i, j, k)` is the triangle's cyclic order starting at `i`. For a closed surface this equals
/// the area-weighted vertex normal `(1/3) sum A_t n_t`.
///
/// # Panics
/// If `out.len() != positions.len()`.
pub fn enclosed_volume_gradient_flat_into(
    positions: &[f64],
    triangles: &[[usize; 3]],
    out: &mut [f64],
) {
    enclosed_volume_and_gradient_flat_into(positions, triangles, out);
}

/// [`enclosed_volume_flat`] and its gradient (written into `out`, length `3 N`, m^2,
/// overwritten; see [`enclosed_volume_gradient_flat_into`]) in one pass over the triangles.
/// The volume is accumulated as `6 V = 0 + sum_t x_a . (x_b x x_c)` in triangle order.
///
/// # Panics
/// If `out.len() != positions.len()`.
pub fn enclosed_volume_and_gradient_flat_into(
    positions: &[f64],
    triangles: &[[usize; 3]],
    out: &mut [f64],
) -> f64 {
    assert_eq!(out.len(), positions.len(), "gradient buffer length");
    out.fill(0.0);
    let mut six_v = 0.0;
    for &[a, b, c] in triangles {
        let (xa, xb, xc) = (p3(positions, a), p3(positions, b), p3(positions, c));
        let bc = xb.cross(&xc);
        six_v += xa.dot(&bc);
        for (i, g) in [(a, bc), (b, xc.cross(&xa)), (c, xa.cross(&xb))] {
            out[3 * i] += g.x / 6.0;
            out[3 * i + 1] += g.y / 6.0;
            out[3 * i + 2] += g.z / 6.0;
        }
    }
    six_v / 6.0
}

/// Gradient of [`enclosed_volume`] as a flat vector of length `3 N` (see
/// [`enclosed_volume_gradient_flat_into`]).
pub fn enclosed_volume_gradient(mesh: &TriMesh) -> Vec<f64> {
    let x = mesh.positions_flat();
    let mut g = vec![0.0; x.len()];
    enclosed_volume_gradient_flat_into(&x, &mesh.triangles, &mut g);
    g
}

/// An axis-aligned bounding box (metres).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Aabb {
    /// Smallest coordinates.
    pub min: Point3<f64>,
    /// Largest coordinates.
    pub max: Point3<f64>,
}

impl Aabb {
    /// `max - min`.
    pub fn extent(&self) -> Vector3<f64> {
        self.max - self.min
    }

    /// Midpoint of the box.
    pub fn center(&self) -> Point3<f64> {
        nalgebra::center(&self.min, &self.max)
    }
}

/// Bounding box of the vertices, `None` for a mesh without vertices.
pub fn bounding_box(mesh: &TriMesh) -> Option<Aabb> {
    let first = *mesh.vertices.first()?;
    let mut bb = Aabb {
        min: first,
        max: first,
    };
    for p in &mesh.vertices {
        bb.min = bb.min.inf(p);
        bb.max = bb.max.sup(p);
    }
    Some(bb)
}

/// The three interior angles (radians) of triangle `(a, b, c)`, at `a`, `b`, `c`. A zero-length
/// edge gives angles of 0.
pub fn triangle_angles(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>) -> [f64; 3] {
    let ang = |u: Vector3<f64>, v: Vector3<f64>| {
        let cr = u.cross(&v).norm();
        let d = u.dot(&v);
        if cr == 0.0 && d == 0.0 {
            0.0
        } else {
            cr.atan2(d)
        }
    };
    [ang(b - a, c - a), ang(c - b, a - b), ang(a - c, b - c)]
}

/// Smallest interior angle over all triangles, in degrees; `None` for a mesh without triangles.
pub fn min_angle_degrees(mesh: &TriMesh) -> Option<f64> {
    let v = &mesh.vertices;
    mesh.triangles
        .iter()
        .flat_map(|&[a, b, c]| triangle_angles(&v[a], &v[b], &v[c]))
        .map(f64::to_degrees)
        .min_by(f64::total_cmp)
}

/// Mean of the vertex positions; `None` for a mesh without vertices.
pub fn vertex_centroid(mesh: &TriMesh) -> Option<Point3<f64>> {
    if mesh.vertices.is_empty() {
        return None;
    }
    let s: Vector3<f64> = mesh.vertices.iter().map(|p| p.coords).sum();
    Some(Point3::from(s / mesh.vertices.len() as f64))
}

/// Centroid of the enclosed solid (uniform density), by summing the signed tetrahedra
/// `(0, a, b, c)` of the divergence-theorem decomposition: `c = sum V_t (x_a + x_b + x_c) / 4 / V`.
/// `None` when the enclosed volume is zero (open or flat meshes).
pub fn volume_centroid(mesh: &TriMesh) -> Option<Point3<f64>> {
    let v = &mesh.vertices;
    let mut vol = 0.0;
    let mut m = Vector3::zeros();
    for &[a, b, c] in &mesh.triangles {
        let vt = v[a].coords.dot(&v[b].coords.cross(&v[c].coords)) / 6.0;
        vol += vt;
        m += (v[a].coords + v[b].coords + v[c].coords) * (vt / 4.0);
    }
    (vol != 0.0).then(|| Point3::from(m / vol))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::icosphere;
    use balloon_test_support::{Rng, assert_second_order, check_gradient, taylor_remainder_orders};

    #[test]
    fn unit_cube_tetra_volume_area_and_angles() {
        // The corner tetrahedron of the unit cube: volume 1/6, outward faces.
        let m = TriMesh::new(
            vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
                Point3::new(0.0, 0.0, 1.0),
            ],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        );
        assert!((enclosed_volume(&m) - 1.0 / 6.0).abs() < 1e-15);
        let area = 1.5 + 3f64.sqrt() / 2.0;
        assert!((surface_area(&m) - area).abs() < 1e-14);
        assert!((min_angle_degrees(&m).unwrap() - 45.0).abs() < 1e-12);
        let c = volume_centroid(&m).unwrap();
        assert!((c - Point3::new(0.25, 0.25, 0.25)).norm() < 1e-14);
        let bb = bounding_box(&m).unwrap();
        assert_eq!(bb.max, Point3::new(1.0, 1.0, 1.0));
        // Translation does not change the enclosed volume of a closed surface.
        let mut t = m.clone();
        for p in &mut t.vertices {
            p.coords += Vector3::new(3.0, -2.0, 7.0);
        }
        assert!((enclosed_volume(&t) - 1.0 / 6.0).abs() < 1e-13);
    }

    #[test]
    fn volume_gradient_matches_finite_differences() {
        let mut m = icosphere(0.1, 1).unwrap();
        let mut rng = Rng::new(7);
        for p in &mut m.vertices {
            p.coords += Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 0.01;
        }
        let x = m.positions_flat();
        let tris = m.triangles.clone();
        let e = |x: &[f64]| enclosed_volume_flat(x, &tris);
        let g = |x: &[f64]| {
            let mut out = vec![0.0; x.len()];
            enclosed_volume_gradient_flat_into(x, &tris, &mut out);
            out
        };
        check_gradient(e, g, &x, 1e-6, 1e-7);
        let dx = rng.vector(x.len());
        assert_second_order(&taylor_remainder_orders(e, g, &x, &dx, 1e-2));
        // On a closed surface the volume gradient sums to zero (translation invariance).
        let gv = g(&x);
        for k in 0..3 {
            let s: f64 = gv.iter().skip(k).step_by(3).sum();
            assert!(s.abs() < 1e-15, "component {k} sums to {s}");
        }
    }

    #[test]
    fn sphere_volume_and_normals_converge() {
        // A fine icosphere approaches the ball: V -> 4/3 pi r^3, A -> 4 pi r^2, normals radial.
        let m = icosphere(2.0, 4).unwrap();
        let v = enclosed_volume(&m);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 8.0;
        assert!((v / exact - 1.0).abs() < 5e-3, "{v} vs {exact}");
        assert!((surface_area(&m) / (16.0 * std::f64::consts::PI) - 1.0).abs() < 5e-3);
        let va: f64 = vertex_areas(&m).iter().sum();
        assert!((va - surface_area(&m)).abs() < 1e-12 * va);
        for (p, n) in m.vertices.iter().zip(vertex_normals(&m)) {
            assert!((p.coords.normalize() - n).norm() < 1e-2);
        }
    }
}
