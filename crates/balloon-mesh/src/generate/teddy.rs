//! The procedural teddy bear, the stand-in for the paper's Teddy model (Wang et al. 2015, Fig. 4: "the
//! shape of teddy's head is some of a big sphere, on which the ear is some of a small
//! hemisphere"), which comes from a benchmark whose terms forbid redistribution.
//!
//! Frame: the teddy stands along **+y** (feet at the bottom, ears on top) and faces **+z** (the
//! muzzle points to +z). Its own left is **+x** (so [`TeddyPart::LeftEar`] is the ear with
//! `x > 0`). The analytic bounding box of its primitives is centred at the origin and its height
//! equals [`TeddyParams::height`].
//!
//! Shape: the smooth union (polynomial smooth minimum) of the signed distances of an ellipsoidal
//! body, a spherical head, two small spherical ears, an optional ellipsoidal muzzle, two capsule
//! arms and two capsule legs, meshed by [`super::implicit_surface`].

use super::implicit::{ImplicitParams, implicit_surface};
use crate::geometry::Aabb;
use crate::{MeshError, TriMesh};
use nalgebra::{Point3, Vector3};

/// Parameters of [`teddy`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TeddyParams {
    /// Total height (m), feet to ear tops. Default 0.3.
    pub height: f64,
    /// Grid cells along the height (resolution of the implicit mesher). Default 34, which gives
    /// about 8k vertices; the vertex count grows like its square. Allowed 8..=400.
    pub resolution: usize,
    /// Radius of the smooth blend between body parts, as a fraction of the height. Default 0.06.
    pub blend: f64,
    /// Add the muzzle. Default `true`.
    pub muzzle: bool,
    /// Tangential relaxation iterations of the mesher. Default 8.
    pub relax_iterations: usize,
}

impl Default for TeddyParams {
    fn default() -> Self {
        Self {
            height: 0.3,
            resolution: 34,
            blend: 0.06,
            muzzle: true,
            relax_iterations: 8,
        }
    }
}

/// Body part of a teddy vertex (see [`teddy_vertex_parts`]). Left and right are the teddy's own
/// (left = +x).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum TeddyPart {
    /// The spherical head.
    Head,
    /// The ellipsoidal body.
    Body,
    /// Ear at +x.
    LeftEar,
    /// Ear at -x.
    RightEar,
    /// The muzzle (only when [`TeddyParams::muzzle`]).
    Muzzle,
    /// Arm at +x.
    LeftArm,
    /// Arm at -x.
    RightArm,
    /// Leg at +x.
    LeftLeg,
    /// Leg at -x.
    RightLeg,
}

#[derive(Clone, Copy, Debug)]
enum Shape {
    Sphere {
        c: Vector3<f64>,
        r: f64,
    },
    Ellipsoid {
        c: Vector3<f64>,
        r: Vector3<f64>,
    },
    Capsule {
        a: Vector3<f64>,
        b: Vector3<f64>,
        r: f64,
    },
}

impl Shape {
    fn sdf(&self, p: &Vector3<f64>) -> f64 {
        match *self {
            Shape::Sphere { c, r } => (p - c).norm() - r,
            Shape::Ellipsoid { c, r } => {
                // Quilez's bound: k0 (k0 - 1) / k1, exact on the surface, C1 near it.
                let q = p - c;
                let k0 = q.component_div(&r).norm();
                let k1 = q.component_div(&r.component_mul(&r)).norm();
                if k1 == 0.0 {
                    -r.min()
                } else {
                    k0 * (k0 - 1.0) / k1
                }
            }
            Shape::Capsule { a, b, r } => {
                let ab = b - a;
                let t = ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
                (p - (a + ab * t)).norm() - r
            }
        }
    }

    fn bounds(&self) -> (Vector3<f64>, Vector3<f64>) {
        match *self {
            Shape::Sphere { c, r } => (c.add_scalar(-r), c.add_scalar(r)),
            Shape::Ellipsoid { c, r } => (c - r, c + r),
            Shape::Capsule { a, b, r } => (a.inf(&b).add_scalar(-r), a.sup(&b).add_scalar(r)),
        }
    }

    fn transformed(&self, offset: &Vector3<f64>, s: f64) -> Shape {
        match *self {
            Shape::Sphere { c, r } => Shape::Sphere {
                c: (c - offset) * s,
                r: r * s,
            },
            Shape::Ellipsoid { c, r } => Shape::Ellipsoid {
                c: (c - offset) * s,
                r: r * s,
            },
            Shape::Capsule { a, b, r } => Shape::Capsule {
                a: (a - offset) * s,
                b: (b - offset) * s,
                r: r * s,
            },
        }
    }
}

/// Polynomial smooth minimum with blend radius `k` (Quilez): equals `min(a, b)` when
/// `|a - b| >= k`, and is C1.
fn smin(a: f64, b: f64, k: f64) -> f64 {
    let h = (k - (a - b).abs()).max(0.0) / k;
    a.min(b) - h * h * k * 0.25
}

/// The teddy's primitives, scaled and centred, with their labels; and the blend radius (m).
struct Teddy {
    parts: Vec<(TeddyPart, Shape)>,
    blend: f64,
    bounds: Aabb,
}

fn check(params: &TeddyParams) -> Result<(), MeshError> {
    let bad = |name, value: String, reason: &str| {
        Err(MeshError::InvalidParameter {
            name,
            value,
            reason: reason.into(),
        })
    };
    if !(params.height.is_finite() && params.height > 0.0) {
        return bad(
            "height",
            params.height.to_string(),
            "must be a positive finite length in metres",
        );
    }
    if !(8..=400).contains(&params.resolution) {
        return bad(
            "resolution",
            params.resolution.to_string(),
            "must be between 8 and 400",
        );
    }
    if !(params.blend.is_finite() && params.blend > 0.0 && params.blend <= 0.2) {
        return bad(
            "blend",
            params.blend.to_string(),
            "must be in (0, 0.2] (fraction of the height)",
        );
    }
    if params.relax_iterations > 100 {
        return bad(
            "relax_iterations",
            params.relax_iterations.to_string(),
            "must be at most 100",
        );
    }
    Ok(())
}

impl Teddy {
    fn new(params: &TeddyParams) -> Self {
        let v = Vector3::new;
        // Design units: metres for a teddy about 0.31 m tall.
        let mut parts = vec![
            (
                TeddyPart::Body,
                Shape::Ellipsoid {
                    c: v(0.0, -0.02, 0.0),
                    r: v(0.075, 0.085, 0.065),
                },
            ),
            (
                TeddyPart::Head,
                Shape::Sphere {
                    c: v(0.0, 0.095, 0.005),
                    r: 0.058,
                },
            ),
            (
                TeddyPart::LeftEar,
                Shape::Sphere {
                    c: v(0.046, 0.142, -0.005),
                    r: 0.022,
                },
            ),
            (
                TeddyPart::RightEar,
                Shape::Sphere {
                    c: v(-0.046, 0.142, -0.005),
                    r: 0.022,
                },
            ),
            (
                TeddyPart::LeftArm,
                Shape::Capsule {
                    a: v(0.06, 0.02, 0.01),
                    b: v(0.105, -0.035, 0.035),
                    r: 0.024,
                },
            ),
            (
                TeddyPart::RightArm,
                Shape::Capsule {
                    a: v(-0.06, 0.02, 0.01),
                    b: v(-0.105, -0.035, 0.035),
                    r: 0.024,
                },
            ),
            (
                TeddyPart::LeftLeg,
                Shape::Capsule {
                    a: v(0.04, -0.085, 0.0),
                    b: v(0.05, -0.12, 0.035),
                    r: 0.03,
                },
            ),
            (
                TeddyPart::RightLeg,
                Shape::Capsule {
                    a: v(-0.04, -0.085, 0.0),
                    b: v(-0.05, -0.12, 0.035),
                    r: 0.03,
                },
            ),
        ];
        if params.muzzle {
            parts.push((
                TeddyPart::Muzzle,
                Shape::Ellipsoid {
                    c: v(0.0, 0.08, 0.055),
                    r: v(0.026, 0.02, 0.018),
                },
            ));
        }
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for (_, s) in &parts {
            let (a, b) = s.bounds();
            lo = lo.inf(&a);
            hi = hi.sup(&b);
        }
        let offset = (lo + hi) * 0.5;
        let s = params.height / (hi.y - lo.y);
        let parts = parts
            .into_iter()
            .map(|(l, sh)| (l, sh.transformed(&offset, s)))
            .collect();
        let bounds = Aabb {
            min: Point3::from((lo - offset) * s),
            max: Point3::from((hi - offset) * s),
        };
        Self {
            parts,
            blend: params.blend * params.height,
            bounds,
        }
    }

    fn sdf(&self, p: &Point3<f64>) -> f64 {
        let mut d = f64::INFINITY;
        for (label, s) in &self.parts {
            let di = s.sdf(&p.coords);
            // Ears get a tighter blend so that they stay distinct small hemispheres.
            let k = match label {
                TeddyPart::LeftEar | TeddyPart::RightEar => 0.4 * self.blend,
                _ => self.blend,
            };
            d = if d.is_infinite() { di } else { smin(d, di, k) };
        }
        d
    }

    fn nearest(&self, p: &Point3<f64>) -> TeddyPart {
        let mut best = (f64::INFINITY, TeddyPart::Body);
        for (label, s) in &self.parts {
            let d = s.sdf(&p.coords);
            if d < best.0 {
                best = (d, *label);
            }
        }
        best.1
    }
}

/// The procedural teddy bear (see the module doc for its frame and shape): closed, 2-manifold,
/// outward-oriented, about 8k vertices with the default parameters.
///
/// # Errors
/// [`MeshError::InvalidParameter`] when a parameter is out of range (see [`TeddyParams`]).
pub fn teddy(params: &TeddyParams) -> Result<TriMesh, MeshError> {
    check(params)?;
    let t = Teddy::new(params);
    let h = params.height / params.resolution as f64;
    implicit_surface(
        |p| t.sdf(p),
        t.bounds,
        &ImplicitParams {
            cell_size: h,
            relax_iterations: params.relax_iterations,
            ..Default::default()
        },
    )
}

/// Labels every vertex of `mesh` (a teddy made by [`teddy`] with the same `params`) with the body
/// part whose primitive is nearest (smallest signed distance). Used to measure, for instance, how
/// the ears inflate relative to the head (Wang et al. 2015, Sec. 5, Fig. 7). Works on deformed copies too
/// (labels then follow the rest-shape primitives, so label the rest mesh and keep the labels).
///
/// Infallible: with out-of-range `params` (which [`teddy`] would have rejected) the labels are
/// meaningless but nothing panics.
pub fn teddy_vertex_parts(mesh: &TriMesh, params: &TeddyParams) -> Vec<TeddyPart> {
    let t = Teddy::new(params);
    mesh.vertices.iter().map(|p| t.nearest(p)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{bounding_box, enclosed_volume, min_angle_degrees};
    use crate::validate::validate_closed_manifold;

    #[test]
    fn default_teddy_is_a_valid_closed_manifold_of_the_right_size() {
        let p = TeddyParams::default();
        let start = std::time::Instant::now();
        let m = teddy(&p).unwrap();
        eprintln!(
            "teddy: {} vertices, {} triangles in {:?}, min angle {:?}",
            m.num_vertices(),
            m.num_triangles(),
            start.elapsed(),
            min_angle_degrees(&m)
        );
        validate_closed_manifold(&m).unwrap();
        assert!(
            (5_000..=15_000).contains(&m.num_vertices()),
            "{}",
            m.num_vertices()
        );
        let bb = bounding_box(&m).unwrap();
        let e = bb.extent();
        assert!((e.y - 0.3).abs() < 0.01, "height {}", e.y);
        assert!(e.y > e.x && e.y > e.z, "stands along +y: {e:?}");
        assert!(
            bb.center().coords.norm() < 0.01,
            "centred: {:?}",
            bb.center()
        );
        assert!(enclosed_volume(&m) > 0.0);
        let topo = crate::topology::Topology::new(&m);
        assert_eq!(topo.genus(&m.triangles), Some(0));
        assert_eq!(topo.triangle_components().1, 1);
        assert!(min_angle_degrees(&m).unwrap() > 10.0);
        // No fold-over: every face normal agrees with the outward SDF gradient at its centroid,
        // and every vertex lies on the zero level set.
        let t = Teddy::new(&p);
        let eps = 1e-6;
        for &[a, b, c] in &m.triangles {
            let (x, y, z) = (m.vertices[a], m.vertices[b], m.vertices[c]);
            let n = (y - x).cross(&(z - x));
            let g = super::super::implicit::tests_support::gradient(
                &|q| t.sdf(q),
                &nalgebra::center(&x, &nalgebra::center(&y, &z)),
                eps,
            );
            assert!(n.dot(&g) > 0.0, "folded triangle [{a}, {b}, {c}]");
        }
        for v in &m.vertices {
            assert!(
                t.sdf(v).abs() < 1e-6,
                "vertex off the surface by {}",
                t.sdf(v)
            );
        }
    }

    #[test]
    fn parts_label_ears_on_top_left_at_plus_x() {
        let p = TeddyParams::default();
        let m = teddy(&p).unwrap();
        let parts = teddy_vertex_parts(&m, &p);
        let count = |part| parts.iter().filter(|q| **q == part).count();
        // The ears are resolved well enough to measure their inflation (about 200 vertices
        // each by default), and the mirror-symmetric shape gives mirror-like counts.
        let (l, r) = (count(TeddyPart::LeftEar), count(TeddyPart::RightEar));
        assert!(l >= 100 && r >= 100, "ears {l} / {r}");
        assert!((l as f64 / r as f64 - 1.0).abs() < 0.1, "ears {l} / {r}");
        assert!(count(TeddyPart::Head) > 4 * l);
        for part in [
            TeddyPart::Head,
            TeddyPart::Body,
            TeddyPart::LeftEar,
            TeddyPart::RightEar,
            TeddyPart::LeftArm,
            TeddyPart::RightArm,
            TeddyPart::LeftLeg,
            TeddyPart::RightLeg,
            TeddyPart::Muzzle,
        ] {
            assert!(parts.contains(&part), "{part:?} has no vertex");
        }
        let mean_of = |part| {
            let v: Vec<_> = m
                .vertices
                .iter()
                .zip(&parts)
                .filter(|(_, q)| **q == part)
                .map(|(x, _)| x.coords)
                .collect();
            v.iter().sum::<Vector3<f64>>() / v.len() as f64
        };
        assert!(mean_of(TeddyPart::LeftEar).x > 0.0 && mean_of(TeddyPart::RightEar).x < 0.0);
        assert!(mean_of(TeddyPart::LeftEar).y > mean_of(TeddyPart::Head).y);
        assert!(mean_of(TeddyPart::Muzzle).z > mean_of(TeddyPart::Head).z);
        assert!(
            teddy(&TeddyParams {
                height: -1.0,
                ..Default::default()
            })
            .is_err()
        );
        assert!(
            teddy(&TeddyParams {
                resolution: 2,
                ..Default::default()
            })
            .is_err()
        );
    }
}
