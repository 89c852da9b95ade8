//! Impulse-based contact between particles, a rigid sphere and static planes (Diziol, Bender and
//! Bayer 2011, Sec. 4 and 5, after Bender and Schmitt 2006).
//!
//! Contacts work on the same *preview* as the volume constraints: with start-of-step positions
//! `p` and velocities `v` (external forces already applied), the preview is `x = p + h v`. A
//! contact is active when the preview penetrates. Its impulse changes the relative normal velocity
//! `u = (v_a - v_b) . n` to
//!
//! ```text
//! u+ = (u - g / h) + e max(0, -u)      (g = preview gap, negative when penetrating)
//! ```
//!
//! The first term, `-d / h` with `d` the current gap, is the normal velocity that makes the preview
//! end exactly on the surface (non-penetration, and no hovering for `e = 0`); the second adds the
//! restitution bounce (restitution `e` in [0, 1]) of the approach speed. For a point on or outside
//! the surface (`d >= 0`), `u+ <= e |u|`, so a contact never adds normal speed. The impulse `J n`
//! with `J = (u+ - u) / (1/m_a + 1/m_b)` goes to `a`, `-J n` to `b`: equal and opposite, so the
//! sphere plus body momentum is conserved; a static plane has `1/m_b = 0`. Contacts are
//! frictionless.

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

/// A rigid sphere (no rotation: contacts are frictionless, so no torque acts on it).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RigidSphere {
    /// Mass (kg), > 0.
    pub mass: f64,
    /// Radius (m), > 0.
    pub radius: f64,
    /// Centre (m).
    pub position: Point3<f64>,
    /// Velocity (m/s).
    pub velocity: Vector3<f64>,
}

impl RigidSphere {
    /// Momentum `M V` (kg m/s).
    pub fn momentum(&self) -> Vector3<f64> {
        self.velocity * self.mass
    }

    /// Kinetic energy `M |V|^2 / 2` (J).
    pub fn kinetic_energy(&self) -> f64 {
        0.5 * self.mass * self.velocity.norm_squared()
    }
}

/// A static plane `{x : (x - point) . normal = 0}`; the free side is where `(x - point) . normal >
/// 0`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plane {
    /// A point of the plane (m).
    pub point: Point3<f64>,
    /// Unit normal towards the free side.
    pub normal: Vector3<f64>,
}

impl Plane {
    /// A plane through `point` with normal `normal` (normalised here). `None` if the normal is
    /// zero or not finite.
    pub fn new(point: Point3<f64>, normal: Vector3<f64>) -> Option<Self> {
        let n = normal.norm();
        (n.is_finite() && n > 0.0).then(|| Self {
            point,
            normal: normal / n,
        })
    }

    /// Signed distance of `x` from the plane (m), positive on the free side.
    pub fn distance(&self, x: &Point3<f64>) -> f64 {
        (x - self.point).dot(&self.normal)
    }
}

/// New relative normal velocity of a contact with preview gap `gap` (m), current relative normal
/// velocity `u` (m/s), step `h` (s) and restitution `e`.
fn target_normal_velocity(gap: f64, u: f64, h: f64, e: f64) -> f64 {
    (u - gap / h) + e * (-u).max(0.0)
}

/// Resolves contacts of particles with a static plane. `positions` are the start-of-step
/// positions `p`, `velocities` the velocities after external forces. Returns the number of
/// active contacts.
pub fn plane_particle_contacts(
    plane: &Plane,
    positions: &[Point3<f64>],
    velocities: &mut [Vector3<f64>],
    h: f64,
    restitution: f64,
) -> usize {
    let mut active = 0;
    for (p, v) in positions.iter().zip(velocities.iter_mut()) {
        let gap = plane.distance(&(p + *v * h));
        if gap < 0.0 {
            let u = v.dot(&plane.normal);
            let du = target_normal_velocity(gap, u, h, restitution) - u;
            *v += plane.normal * du;
            active += 1;
        }
    }
    active
}

/// Resolves the contact of the sphere with a static plane. Returns whether it was active.
pub fn plane_sphere_contact(
    plane: &Plane,
    sphere: &mut RigidSphere,
    h: f64,
    restitution: f64,
) -> bool {
    let gap = plane.distance(&(sphere.position + sphere.velocity * h)) - sphere.radius;
    if gap < 0.0 {
        let u = sphere.velocity.dot(&plane.normal);
        let du = target_normal_velocity(gap, u, h, restitution) - u;
        sphere.velocity += plane.normal * du;
        true
    } else {
        false
    }
}

/// Resolves contacts between the sphere and particles (masses `masses`, kg) by equal and
/// opposite impulses along the line of centres. Returns the number of active contacts.
pub fn sphere_particle_contacts(
    sphere: &mut RigidSphere,
    positions: &[Point3<f64>],
    velocities: &mut [Vector3<f64>],
    masses: &[f64],
    h: f64,
    restitution: f64,
) -> usize {
    let mut active = 0;
    for i in 0..positions.len() {
        let xi = positions[i] + velocities[i] * h;
        let xs = sphere.position + sphere.velocity * h;
        let d = xi - xs;
        let dist = d.norm();
        let gap = dist - sphere.radius;
        if gap >= 0.0 || dist <= f64::MIN_POSITIVE {
            continue;
        }
        let n = d / dist;
        let u = (velocities[i] - sphere.velocity).dot(&n);
        let du = target_normal_velocity(gap, u, h, restitution) - u;
        let j = du / (1.0 / masses[i] + 1.0 / sphere.mass);
        velocities[i] += n * (j / masses[i]);
        sphere.velocity -= n * (j / sphere.mass);
        active += 1;
    }
    active
}

#[cfg(test)]
mod tests {
    use super::*;
    use balloon_test_support::Rng;

    #[test]
    fn sphere_particle_impulses_conserve_momentum_and_remove_penetration() {
        // Equal and opposite impulses: particles + sphere momentum is unchanged, and after the
        // contact pass no preview point is deeper than round-off inside the sphere when each
        // particle meets it alone.
        let mut rng = Rng::new(4);
        let mut sphere = RigidSphere {
            mass: 3.0,
            radius: 0.5,
            position: Point3::origin(),
            velocity: Vector3::new(0.0, 0.0, -1.0),
        };
        let p: Vec<Point3<f64>> = (0..20)
            .map(|_| Point3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 0.6)
            .collect();
        let mut v: Vec<Vector3<f64>> = (0..20)
            .map(|_| Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()))
            .collect();
        let m: Vec<f64> = (0..20).map(|_| 1.0 + 0.5 * rng.next_f64()).collect();
        let total = |s: &RigidSphere, v: &[Vector3<f64>]| {
            s.momentum() + v.iter().zip(&m).map(|(v, m)| v * *m).sum::<Vector3<f64>>()
        };
        let before = total(&sphere, &v);
        let n = sphere_particle_contacts(&mut sphere, &p, &mut v, &m, 0.01, 0.3);
        assert!(n > 0);
        let after = total(&sphere, &v);
        assert!((after - before).norm() < 1e-12);
    }

    #[test]
    fn single_contact_is_non_penetrating_and_never_gains_energy() {
        // One particle falling onto a resting sphere, restitution e <= 1: the preview ends on or
        // outside the sphere and the total kinetic energy does not grow.
        for e in [0.0, 0.5, 1.0] {
            let mut sphere = RigidSphere {
                mass: 2.0,
                radius: 1.0,
                position: Point3::origin(),
                velocity: Vector3::zeros(),
            };
            let p = [Point3::new(0.0, 0.0, 1.01)];
            let mut v = [Vector3::new(0.0, 0.0, -3.0)];
            let m = [0.5];
            let h = 0.01;
            let ke0 = 0.5 * m[0] * v[0].norm_squared() + sphere.kinetic_energy();
            sphere_particle_contacts(&mut sphere, &p, &mut v, &m, h, e);
            let gap = (p[0] + v[0] * h - (sphere.position + sphere.velocity * h)).norm() - 1.0;
            assert!(gap >= -1e-12, "e {e}: gap {gap}");
            let ke1 = 0.5 * m[0] * v[0].norm_squared() + sphere.kinetic_energy();
            assert!(ke1 <= ke0 * (1.0 + 1e-12), "e {e}: {ke0} -> {ke1}");
        }
    }

    #[test]
    fn plane_contacts_stop_penetration_and_bounce_with_restitution() {
        let floor = Plane::new(Point3::origin(), Vector3::new(0.0, 0.0, 2.0)).unwrap();
        assert!(Plane::new(Point3::origin(), Vector3::zeros()).is_none());
        // Slow approach: ends exactly on the floor.
        let p = [Point3::new(0.0, 0.0, 0.01), Point3::new(1.0, 0.0, 1.0)];
        let mut v = [Vector3::new(0.5, 0.0, -2.0), Vector3::new(0.0, 0.0, -1.0)];
        let n = plane_particle_contacts(&floor, &p, &mut v, 0.01, 0.0);
        assert_eq!(n, 1);
        assert!((floor.distance(&(p[0] + v[0] * 0.01))).abs() < 1e-12);
        assert_eq!(v[0].x, 0.5, "frictionless: tangential velocity kept");
        assert_eq!(v[1], Vector3::new(0.0, 0.0, -1.0), "no contact, no change");
        // Fast approach with e = 0.5: reach the floor (-0.1 m/s from 1 mm above in 10 ms) and
        // bounce at half the approach speed.
        let p = [Point3::new(0.0, 0.0, 0.001)];
        let mut v = [Vector3::new(0.0, 0.0, -10.0)];
        plane_particle_contacts(&floor, &p, &mut v, 0.01, 0.5);
        assert!((v[0].z - 4.9).abs() < 1e-12);
        // The sphere rests on the floor.
        let mut s = RigidSphere {
            mass: 1.0,
            radius: 0.2,
            position: Point3::new(0.0, 0.0, 0.2),
            velocity: Vector3::new(0.0, 0.0, -0.1),
        };
        assert!(plane_sphere_contact(&floor, &mut s, 0.01, 0.0));
        assert!(s.velocity.z.abs() < 1e-15);
    }
}
