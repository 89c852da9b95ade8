//! Collisions of two-layer objects (Song 2009, Sec. 4.6): particles against the walls, floor and
//! ceiling of an axis-aligned box, perfectly elastic or damped by a coefficient of restitution,
//! and the inner layer kept inside the outer layer.
//!
//! All functions work on flat arrays `positions` / `velocities` of length `3 * particles`
//! (`[x0, y0, z0, x1, ...]`, metres and metres per second) and change them in place, after the
//! integration step (Song 2009, Sec. 4.7, Step 12).
//!
//! **Response (Song 2009, Eq. 4.17-4.19).** A particle found outside a plane is put back on it and
//! the normal component of its velocity is reflected and scaled by the restitution `e` in `[0, 1]`:
//! `v_n <- -e v_n` (only when it still moves outward), the tangential component is kept (no
//! friction). `e = 1` is the paper's perfect elastic collision, `e < 1` its damped collision.
//!
//! **Inner layer.** The paper constrains the inner layer by the outer layer instead of the box.
//! Inner particle `i` is paired with outer particle `i` (both layers share connectivity); the
//! outer surface near the pair is approximated by its tangent plane at the outer particle, with
//! the area-weighted outer vertex normal `n_i`. If `(x_in - x_out) . n_i > 0` the inner particle
//! has escaped: it is projected back onto the plane and its normal velocity *relative to the
//! outer particle* is reflected with the restitution. Use [`winding_number`] for an exact
//! inside test (e.g. for statistics).

use crate::ConstraintError;
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use std::ops::Range;

mod containment;
mod winding;

pub use containment::LayerContainment;
pub use winding::{polygon_winding_number, winding_number};

/// An axis-aligned box whose six faces (walls, floor, ceiling) the particles stay inside.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AxisBox {
    /// Lower corner (m).
    pub min: Point3<f64>,
    /// Upper corner (m).
    pub max: Point3<f64>,
}

impl AxisBox {
    /// A box from its corners; errors unless they are finite with `min < max` on every axis.
    pub fn try_new(min: Point3<f64>, max: Point3<f64>) -> Result<Self, ConstraintError> {
        let ok = (0..3).all(|d| min[d].is_finite() && max[d].is_finite() && min[d] < max[d]);
        if ok {
            Ok(Self { min, max })
        } else {
            Err(ConstraintError::InvalidBox {
                min: [min.x, min.y, min.z],
                max: [max.x, max.y, max.z],
            })
        }
    }

    /// A box centred at `center` with half extents `half` (m).
    pub fn centered(center: Point3<f64>, half: Vector3<f64>) -> Result<Self, ConstraintError> {
        Self::try_new(center - half, center + half)
    }

    /// Whether `p` is inside the box or within `tol` (m) of it.
    pub fn contains(&self, p: &Point3<f64>, tol: f64) -> bool {
        (0..3).all(|d| p[d] >= self.min[d] - tol && p[d] <= self.max[d] + tol)
    }
}

/// Checks that a restitution coefficient is in `[0, 1]`.
pub fn check_restitution(restitution: f64) -> Result<f64, ConstraintError> {
    if (0.0..=1.0).contains(&restitution) {
        Ok(restitution)
    } else {
        Err(ConstraintError::InvalidRestitution(restitution))
    }
}

/// Collides particles `particles` with the six faces of `bbox` (Song 2009, Sec. 4.6): a particle
/// outside a face is moved onto it and its outward normal velocity `v_n` becomes
/// `-restitution * v_n`. Returns the number of particle-face contacts resolved.
///
/// `positions`, `velocities`: flat, length `3 * n` with `particles.end <= n`.
pub fn collide_box(
    positions: &mut [f64],
    velocities: &mut [f64],
    particles: Range<usize>,
    bbox: &AxisBox,
    restitution: f64,
) -> usize {
    let mut contacts = 0;
    for i in particles {
        for d in 0..3 {
            let k = 3 * i + d;
            if positions[k] < bbox.min[d] {
                positions[k] = bbox.min[d];
                if velocities[k] < 0.0 {
                    velocities[k] *= -restitution;
                }
                contacts += 1;
            } else if positions[k] > bbox.max[d] {
                positions[k] = bbox.max[d];
                if velocities[k] > 0.0 {
                    velocities[k] *= -restitution;
                }
                contacts += 1;
            }
        }
    }
    contacts
}

fn point(positions: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2])
}

/// Area-weighted unit vertex normals of a closed triangle layer whose vertex `j` is particle
/// `offset + j` (Song 2009, Sec. 4.5.2, "particle normal": the normalised sum of the adjacent face
/// normals). `normals` is resized to `count`. A vertex with no faces gets a zero normal.
pub fn layer_vertex_normals_into(
    positions: &[f64],
    offset: usize,
    count: usize,
    triangles: &[[usize; 3]],
    normals: &mut Vec<Vector3<f64>>,
) {
    normals.clear();
    normals.resize(count, Vector3::zeros());
    for t in triangles {
        let a = point(positions, offset + t[0]);
        let b = point(positions, offset + t[1]);
        let c = point(positions, offset + t[2]);
        // |(b-a) x (c-a)| = 2 * area: area weighting.
        let n = (b - a).cross(&(c - a));
        for &v in t {
            normals[v] += n;
        }
    }
    for n in normals.iter_mut() {
        let len = n.norm();
        if len > 0.0 {
            *n /= len;
        }
    }
}

/// Unit in-plane vertex normals of a closed counter-clockwise polygon in the `xy` plane whose
/// vertex `j` is particle `offset + j` (Song 2009, Sec. 4.5.2, 2D normals: each edge `(dx, dy)` has
/// outward normal `(dy, -dx)`, each vertex the normalised sum of its two edges' normals).
pub fn polygon_vertex_normals_into(
    positions: &[f64],
    offset: usize,
    count: usize,
    normals: &mut Vec<Vector3<f64>>,
) {
    normals.clear();
    normals.resize(count, Vector3::zeros());
    for j in 0..count {
        let k = (j + 1) % count;
        let a = point(positions, offset + j);
        let b = point(positions, offset + k);
        let e = b - a;
        let n = Vector3::new(e.y, -e.x, 0.0);
        normals[j] += n;
        normals[k] += n;
    }
    for n in normals.iter_mut() {
        let len = n.norm();
        if len > 0.0 {
            *n /= len;
        }
    }
}

/// Keeps the inner layer inside the outer one (Song 2009, Sec. 4.6.2): for each pair `j` in
/// `0..count`, inner particle `inner_offset + j` is tested against the tangent plane of the outer
/// layer at outer particle `outer_offset + j` with unit outward normal `outer_normals[j]`. An
/// escaped inner particle is projected onto the plane. If the pair still separates along `n`
/// (relative normal velocity `v_r = (v_in - v_out) . n > 0`), an impulse
/// `J = (1 + e) v_r / (1/m_in + 1/m_out)` along `n` is exchanged between the two particles
/// (masses from `masses`, global indices): the relative normal velocity becomes `-e v_r`,
/// momentum is conserved and kinetic energy never grows for `e <= 1` (a wall that moves must
/// not pump energy into the inner layer). Returns how many inner particles were corrected.
///
/// This is the paper's per-pair test, kept for comparison: it only looks at one tangent plane
/// per inner particle, so on a deforming body some inner particles end up outside the outer
/// surface (4 to 44 of 258 on the level-3 sphere, by winding number). `TwoLayerSimulation`
/// uses the closest-point test over the whole outer layer instead ([`LayerContainment`]),
/// which keeps every inner particle inside.
pub fn contain_inner_layer(
    positions: &mut [f64],
    velocities: &mut [f64],
    masses: &[f64],
    inner_offset: usize,
    outer_offset: usize,
    count: usize,
    outer_normals: &[Vector3<f64>],
    restitution: f64,
) -> usize {
    let mut corrected = 0;
    for j in 0..count {
        let n = outer_normals[j];
        if n == Vector3::zeros() {
            continue;
        }
        let (ii, oo) = (inner_offset + j, outer_offset + j);
        let s = (point(positions, ii) - point(positions, oo)).dot(&n);
        if s <= 0.0 {
            continue;
        }
        corrected += 1;
        let vr = (point(velocities, ii) - point(velocities, oo)).dot(&n);
        let (wi, wo) = (1.0 / masses[ii], 1.0 / masses[oo]);
        let impulse = if vr > 0.0 {
            (1.0 + restitution) * vr / (wi + wo)
        } else {
            0.0
        };
        for d in 0..3 {
            positions[3 * ii + d] -= s * n[d];
            velocities[3 * ii + d] -= impulse * wi * n[d];
            velocities[3 * oo + d] += impulse * wo * n[d];
        }
    }
    corrected
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use balloon_mesh::generate::octahedron_sphere;

    #[test]
    fn box_collision_reflects_normal_velocity_with_restitution() {
        let b = AxisBox::try_new(Point3::new(-1.0, -1.0, 0.0), Point3::new(1.0, 1.0, 2.0)).unwrap();
        // Particle 0 below the floor moving down and sideways; particle 1 inside; particle 2
        // beyond the +x wall but already moving back in (its velocity must not flip).
        let mut x = vec![0.5, 0.0, -0.1, 0.0, 0.0, 1.0, 1.2, 0.0, 1.0];
        let mut v = vec![0.3, 0.0, -2.0, 1.0, 1.0, 1.0, -0.5, 0.0, 0.0];
        let n = collide_box(&mut x, &mut v, 0..3, &b, 0.5);
        assert_eq!(n, 2);
        assert_eq!(&x[0..3], &[0.5, 0.0, 0.0]);
        // Normal speed halves and reverses; tangential speed is kept (no friction).
        assert_eq!(&v[0..3], &[0.3, 0.0, 1.0]);
        assert_eq!(&v[3..6], &[1.0, 1.0, 1.0]);
        assert_eq!(x[6], 1.0);
        assert_eq!(v[6], -0.5);
        // A perfectly elastic collision keeps the speed: kinetic energy is conserved.
        let mut x = vec![0.0, 0.0, 2.5];
        let mut v = vec![0.1, 0.2, 3.0];
        collide_box(&mut x, &mut v, 0..1, &b, 1.0);
        assert_relative_eq!(
            v.iter().map(|c| c * c).sum::<f64>(),
            0.01 + 0.04 + 9.0,
            epsilon = 1e-15
        );
        assert!(b.contains(&Point3::new(x[0], x[1], x[2]), 0.0));
    }

    #[test]
    fn invalid_box_and_restitution_are_errors() {
        assert!(AxisBox::try_new(Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 1.0)).is_err());
        assert!(
            AxisBox::try_new(Point3::new(f64::NAN, 0.0, 0.0), Point3::new(1.0, 1.0, 1.0)).is_err()
        );
        let msg = AxisBox::try_new(Point3::new(2.0, 0.0, 0.0), Point3::new(1.0, 1.0, 1.0))
            .unwrap_err()
            .to_string();
        assert!(msg.contains("min < max"), "{msg}");
        assert!(check_restitution(1.5).is_err());
        assert!(check_restitution(-0.1).is_err());
        assert_eq!(check_restitution(0.3), Ok(0.3));
    }

    #[test]
    fn sphere_normals_are_radial_and_winding_numbers_classify() {
        let m = octahedron_sphere(1.0, 2).unwrap();
        let x = m.positions_flat();
        let mut normals = Vec::new();
        layer_vertex_normals_into(&x, 0, m.num_vertices(), &m.triangles, &mut normals);
        // On a sphere the vertex normals point along the radius.
        for (j, n) in normals.iter().enumerate() {
            assert!(n.dot(&point(&x, j)) > 0.99, "normal {j} not radial");
        }
        assert_relative_eq!(
            winding_number(&Point3::origin(), &x, 0, &m.triangles),
            1.0,
            epsilon = 1e-9
        );
        assert!(winding_number(&Point3::new(0.0, 0.0, 1.5), &x, 0, &m.triangles).abs() < 1e-9);
        // Polygon in the xy plane (counter-clockwise unit circle, 12 vertices).
        let poly: Vec<f64> = (0..12)
            .flat_map(|j| {
                let a = j as f64 * std::f64::consts::TAU / 12.0;
                [a.cos(), a.sin(), 0.0]
            })
            .collect();
        assert_relative_eq!(
            polygon_winding_number(&Point3::new(0.2, 0.1, 0.0), &poly, 0, 12),
            1.0,
            epsilon = 1e-12
        );
        assert!(polygon_winding_number(&Point3::new(2.0, 0.0, 0.0), &poly, 0, 12).abs() < 1e-12);
        polygon_vertex_normals_into(&poly, 0, 12, &mut normals);
        for (j, n) in normals.iter().enumerate() {
            assert_relative_eq!(n.dot(&point(&poly, j)), 1.0, epsilon = 1e-12);
        }
    }

    #[test]
    fn escaped_inner_particle_is_projected_and_reflected() {
        // Two layers of an octahedron sphere (inner radius 0.5, outer 1); push inner particle 0
        // outside the outer surface, moving outward faster than its partner.
        let inner = octahedron_sphere(0.5, 1).unwrap();
        let outer = octahedron_sphere(1.0, 1).unwrap();
        let n = inner.num_vertices();
        let mut x = inner.positions_flat();
        x.extend(outer.positions_flat());
        let mut v = vec![0.0; 6 * n];
        let dir = point(&x, n); // outer partner of inner particle 0, radial
        for d in 0..3 {
            x[d] = 1.2 * dir[d];
            v[d] = 2.0 * dir[d];
            v[3 * n + d] = 0.5 * dir[d];
        }
        let mut normals = Vec::new();
        layer_vertex_normals_into(&x, n, n, &outer.triangles, &mut normals);
        let before_inside = (0..n)
            .filter(|&j| {
                let p = Point3::from(point(&x, j));
                winding_number(&p, &x, n, &outer.triangles) > 0.5
            })
            .count();
        assert_eq!(before_inside, n - 1);
        // Inner particles weigh 1 kg, outer ones 3 kg.
        let masses: Vec<f64> = (0..2 * n).map(|i| if i < n { 1.0 } else { 3.0 }).collect();
        let momentum =
            |v: &[f64]| -> Vector3<f64> { (0..2 * n).map(|i| point(v, i) * masses[i]).sum() };
        let kinetic = |v: &[f64]| -> f64 {
            (0..2 * n)
                .map(|i| 0.5 * masses[i] * point(v, i).norm_squared())
                .sum()
        };
        let (p0, k0) = (momentum(&v), kinetic(&v));
        let fixed = contain_inner_layer(&mut x, &mut v, &masses, 0, n, n, &normals, 0.5);
        assert_eq!(fixed, 1);
        // Now on the tangent plane of its partner: at radius 1 along the radial direction.
        assert_relative_eq!(point(&x, 0).norm(), 1.0, epsilon = 1e-12);
        // Relative normal velocity 1.5 outward becomes 0.75 inward; the impulse
        // J = 1.5 * 1.5 / (1 + 1/3) = 1.6875 N s changes v_in by -J and v_out by +J/3.
        assert_relative_eq!(point(&v, 0).dot(&dir), 2.0 - 1.6875, epsilon = 1e-12);
        assert_relative_eq!(point(&v, n).dot(&dir), 0.5 + 1.6875 / 3.0, epsilon = 1e-12);
        assert_relative_eq!(
            (point(&v, 0) - point(&v, n)).dot(&dir),
            -0.75,
            epsilon = 1e-12
        );
        // A collision between the layers conserves momentum and does not create energy.
        assert!((momentum(&v) - p0).norm() < 1e-12);
        assert!(kinetic(&v) < k0);
        // The other inner particles were inside and are untouched.
        assert_eq!(
            contain_inner_layer(&mut x, &mut v, &masses, 0, n, n, &normals, 0.5),
            0
        );
    }
}
