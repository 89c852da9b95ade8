//! A closed tube: a circular cylinder with hemispherical end caps (a capsule), the body of the
//! bulging-tube experiment (issue 14, item 6; `docs/membranes.md`).
//!
//! Why hemispherical caps and not flat ones: a flat end cap meets the barrel at a right angle,
//! and an inflated membrane cannot carry a kink (the membrane force would have to turn through
//! 90 degrees at the rim with no bending stiffness to do it), so the rim becomes a stress
//! concentration where elements distort and the Newton solve struggles. A hemisphere joins the
//! barrel with a continuous tangent and, for a thin membrane under pressure, carries the
//! same hoop stress as the barrel's axial stress (`P R / 2 h`), so the caps perturb the barrel
//! only locally and the barrel stays the uniform tube of the analytic solution away from them.
//!
//! The barrel is a stack of rings of `segments` vertices, consecutive rings turned by half a
//! segment and spaced by `sqrt(3)/2` of the ring's chord, so its triangles are near-equilateral.
//! Each cap is a set of latitude rings whose vertex counts shrink with the cosine of the latitude
//! (so its edges stay about as long as the barrel's), closed by a pole vertex. Neighbouring rings
//! of different counts are stitched by advancing along whichever ring's next vertex comes first
//! in angle.

use super::{check_count, check_positive};
use crate::{MeshError, TriMesh};
use nalgebra::{Point3, Vector3};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// A ring of vertices at one height: `count` vertices starting at index `first`, vertex `k` at
/// angle `offset + 2 pi k / count` about the axis.
#[derive(Clone, Copy, Debug)]
struct Ring {
    first: usize,
    count: usize,
    offset: f64,
}

impl Ring {
    /// The unwrapped angle of the ring's `k`-th vertex (`k` may exceed `count`).
    fn angle(&self, k: usize) -> f64 {
        self.offset + TAU * k as f64 / self.count as f64
    }

    /// The vertex index of the ring's `k`-th vertex (periodic in `k`).
    fn index(&self, k: usize) -> usize {
        self.first + k % self.count
    }
}

/// Triangulates the band between rings `a` and `b`: `a.count + b.count` triangles, walking once
/// around the axis and advancing on the ring whose next vertex comes first in angle.
fn stitch(a: &Ring, b: &Ring, triangles: &mut Vec<[usize; 3]>) {
    // Start `b` at its last vertex at or before `a`'s first one.
    let mut j0 = ((a.angle(0) - b.offset) / (TAU / b.count as f64)).floor();
    if !j0.is_finite() {
        j0 = 0.0;
    }
    let shift = j0.rem_euclid(b.count as f64) as usize;
    let b_angle = |j: usize| b.angle(j) + TAU * (j0 - shift as f64) / b.count as f64;
    let (mut i, mut j) = (0usize, shift);
    let (end_i, end_j) = (a.count, shift + b.count);
    while i < end_i || j < end_j {
        let advance_a = if i == end_i {
            false
        } else if j == end_j {
            true
        } else {
            a.angle(i + 1) <= b_angle(j + 1)
        };
        if advance_a {
            triangles.push([a.index(i), a.index(i + 1), b.index(j)]);
            i += 1;
        } else {
            triangles.push([a.index(i), b.index(j + 1), b.index(j)]);
            j += 1;
        }
    }
}

/// A closed tube about the z axis, centred at the origin: a cylinder of `radius` (m) with
/// hemispherical end caps, `length` (m) from tip to tip (so the straight barrel is
/// `length - 2 radius` long, which must be positive), `segments` vertices around (3..=4096).
///
/// The barrel has `segments` vertices per ring, the rings turned by half a segment from one to
/// the next and spaced so that the barrel's triangles are as close to equilateral as the
/// barrel length allows; the caps are latitude rings of decreasing vertex count and a pole
/// vertex at `z = +- length / 2`. Every vertex lies on the capsule exactly (barrel vertices at
/// distance `radius` from the axis, cap vertices at distance `radius` from their cap's centre).
/// The mesh is a closed, outward-oriented genus-0 manifold. See the module docs for why the
/// caps are hemispherical.
///
/// ```
/// use balloon_mesh::generate::tube;
/// use balloon_mesh::validate::validate_closed_manifold;
///
/// let mesh = tube(0.05, 0.6, 24)?;
/// validate_closed_manifold(&mesh)?;
/// let v = balloon_mesh::geometry::enclosed_volume(&mesh);
/// let exact = std::f64::consts::PI * 0.05f64.powi(2) * (0.6 - 0.1) + 4.0 / 3.0 * std::f64::consts::PI * 0.05f64.powi(3);
/// assert!(v < exact && v > 0.97 * exact);
/// # Ok::<(), balloon_mesh::MeshError>(())
/// ```
///
/// # Errors
/// [`MeshError::InvalidParameter`] for a non-positive or non-finite `radius` or `length`, a
/// `length` not larger than `2 radius`, or `segments` outside `3..=4096`.
pub fn tube(radius: f64, length: f64, segments: usize) -> Result<TriMesh, MeshError> {
    check_positive("radius", radius)?;
    check_positive("length", length)?;
    check_count("segments", segments, 3, 4096)?;
    let barrel = length - 2.0 * radius;
    if barrel.is_nan() || barrel <= 0.0 {
        return Err(MeshError::InvalidParameter {
            name: "length",
            value: length.to_string(),
            reason: format!(
                "must exceed twice the radius ({}) to leave a straight barrel between the caps",
                2.0 * radius
            ),
        });
    }
    let n = segments;
    // Edge length around a ring and the height of an equilateral triangle on it.
    let edge = 2.0 * radius * (PI / n as f64).sin();
    let band = edge * 3f64.sqrt() / 2.0;
    let barrel_bands = ((barrel / band).round() as usize).max(1);
    let cap_bands = ((FRAC_PI_2 * radius / band).round() as usize).max(1);

    let mut vertices: Vec<Point3<f64>> = Vec::new();
    let mut rings: Vec<Ring> = Vec::new();
    let mut push_ring = |count: usize, offset: f64, rho: f64, z: f64, vertices: &mut Vec<_>| {
        let first = vertices.len();
        for k in 0..count {
            let phi = offset + TAU * k as f64 / count as f64;
            vertices.push(Point3::new(rho * phi.cos(), rho * phi.sin(), z));
        }
        rings.push(Ring {
            first,
            count,
            offset,
        });
    };
    let half = barrel / 2.0;
    let half_turn = PI / n as f64;
    // South cap rings (latitude from the pole towards the rim, pole excluded), then the barrel
    // (rim to rim), then the north cap rings.
    let cap_count =
        |theta: f64| -> usize { ((n as f64 * theta.cos()).round() as usize).clamp(3, n) };
    for k in (1..cap_bands).rev() {
        let theta = FRAC_PI_2 * k as f64 / cap_bands as f64;
        let count = cap_count(theta);
        let offset = if k % 2 == 1 { half_turn } else { 0.0 };
        push_ring(
            count,
            offset,
            radius * theta.cos(),
            -half - radius * theta.sin(),
            &mut vertices,
        );
    }
    for r in 0..=barrel_bands {
        let z = -half + barrel * r as f64 / barrel_bands as f64;
        let offset = if r % 2 == 1 { half_turn } else { 0.0 };
        push_ring(n, offset, radius, z, &mut vertices);
    }
    let last_barrel = barrel_bands % 2;
    for k in 1..cap_bands {
        let theta = FRAC_PI_2 * k as f64 / cap_bands as f64;
        let count = cap_count(theta);
        let offset = if (k + last_barrel) % 2 == 1 {
            half_turn
        } else {
            0.0
        };
        push_ring(
            count,
            offset,
            radius * theta.cos(),
            half + radius * theta.sin(),
            &mut vertices,
        );
    }
    let south = vertices.len();
    vertices.push(Point3::new(0.0, 0.0, -half - radius));
    let north = vertices.len();
    vertices.push(Point3::new(0.0, 0.0, half + radius));

    let mut triangles: Vec<[usize; 3]> = Vec::with_capacity(2 * vertices.len());
    for pair in rings.windows(2) {
        stitch(&pair[0], &pair[1], &mut triangles);
    }
    let (first, last) = (rings[0], rings[rings.len() - 1]);
    for k in 0..first.count {
        triangles.push([south, first.index(k + 1), first.index(k)]);
    }
    for k in 0..last.count {
        triangles.push([north, last.index(k), last.index(k + 1)]);
    }
    // Orient every triangle outward: away from the nearest point of the axis segment between
    // the two cap centres (exact for a capsule).
    for t in &mut triangles {
        let [a, b, c] = t.map(|i| vertices[i]);
        let centroid = (a.coords + b.coords + c.coords) / 3.0;
        let axis = Vector3::new(0.0, 0.0, centroid.z.clamp(-half, half));
        let normal = (b - a).cross(&(c - a));
        if normal.dot(&(centroid - axis)) < 0.0 {
            t.swap(1, 2);
        }
    }
    Ok(TriMesh::new(vertices, triangles))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::validate::validate_closed_manifold;

    fn edge_ratio(m: &TriMesh, t: [usize; 3]) -> f64 {
        let l = [(0, 1), (1, 2), (2, 0)].map(|(i, j)| (m.vertices[t[i]] - m.vertices[t[j]]).norm());
        l.iter().cloned().fold(0.0, f64::max) / l.iter().cloned().fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn tubes_are_closed_outward_capsules_with_good_triangles() {
        for (r, len, n) in [
            (0.05, 0.5, 16),
            (0.05, 0.6, 32),
            (1.0, 2.5, 7),
            (0.1, 0.21, 3),
        ] {
            let m = tube(r, len, n).unwrap();
            validate_closed_manifold(&m).unwrap_or_else(|e| panic!("{r} {len} {n}: {e}"));
            let topo = crate::topology::Topology::new(&m);
            assert_eq!(topo.genus(&m.triangles), Some(0));
            // On the capsule exactly.
            let half = (len - 2.0 * r) / 2.0;
            for p in &m.vertices {
                let c = Vector3::new(0.0, 0.0, p.z.clamp(-half, half));
                assert!(((p.coords - c).norm() - r).abs() < 1e-12 * r.max(1.0));
            }
            // Volume below the exact capsule (inscribed polyhedron), and close to it.
            let exact = PI * r * r * (len - 2.0 * r) + 4.0 / 3.0 * PI * r * r * r;
            let v = crate::geometry::enclosed_volume(&m);
            let floor = if n >= 16 { 0.97 } else { 0.2 };
            assert!(v < exact && v > floor * exact, "{v} vs {exact}");
            let (lo, hi) = m
                .vertices
                .iter()
                .fold((0.0f64, 0.0f64), |(lo, hi), p| (lo.min(p.z), hi.max(p.z)));
            assert!((hi - lo - len).abs() < 1e-12 * len);
        }
        // Near-equilateral barrel triangles (edge ratio close to 1), reasonable caps.
        let m = tube(0.05, 0.6, 32).unwrap();
        let mut barrel_worst: f64 = 1.0;
        let mut worst: f64 = 1.0;
        for &t in &m.triangles {
            let q = edge_ratio(&m, t);
            worst = worst.max(q);
            if t.iter().all(|&i| m.vertices[i].z.abs() <= 0.25 + 1e-12) {
                barrel_worst = barrel_worst.max(q);
            }
        }
        assert!(barrel_worst < 1.1, "barrel edge ratio {barrel_worst}");
        assert!(worst < 2.0, "worst edge ratio {worst}");
    }

    #[test]
    fn invalid_tubes_are_refused() {
        assert!(tube(0.0, 1.0, 8).is_err());
        assert!(tube(0.1, f64::NAN, 8).is_err());
        assert!(tube(0.1, 0.2, 8).is_err());
        assert!(tube(0.1, 1.0, 2).is_err());
        assert!(tube(0.1, 1.0, 5000).is_err());
    }
}
