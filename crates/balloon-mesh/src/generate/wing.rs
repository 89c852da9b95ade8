//! A flattened ellipsoid with two thin wings: a small test shape for thin flat parts under
//! pressure, a few hundred to a few thousand vertices.
//!
//! [`finned_ellipsoid`](super::finned_ellipsoid) resolves its thin fin with the implicit
//! mesher's uniform grid, so a thinner fin costs vertices everywhere (a 4 mm fin: 14614
//! vertices). This shape maps an icosphere instead: the body is the ellipsoid of semi-axes
//! `semi_axes`, and the vertices with `|y| > wing_root` on the unit sphere move outward along
//! `y` by up to `span` while their `z` is squeezed to a wall `wing_thickness` thick and their
//! `x` tapers, with a smooth step in between. Each wing is then two nearly parallel walls joined
//! by a rim, as the wings and ears of real models are, at the icosphere's vertex count
//! (642 vertices at level 3, 2562 at 4).
//!
//! The map `(x, y, z) -> (x c(y), Y(y), z g(y))` has `Y` increasing and `c, g > 0`, so it is
//! one-to-one and the mesh stays closed, 2-manifold and outward-oriented like the icosphere.
//!
//! Frame: the body's long axis is `x`, the wings extend along `+-y`, they are thin along `z`;
//! the shape is centred at the origin.

use super::icosphere;
use crate::{MeshError, TriMesh};
use nalgebra::{Point3, Vector3};

/// Parameters of [`winged_ellipsoid`] (lengths in metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WingParams {
    /// Semi-axes of the body along `x`, `y`, `z` (default 0.03, 0.02, 0.015).
    pub semi_axes: Vector3<f64>,
    /// How far each wing tip reaches beyond the body along `y` (default 0.03: 0.1 m tip to
    /// tip).
    pub span: f64,
    /// Thickness of a wing across `z` (default 0.004: two walls 4 mm apart).
    pub wing_thickness: f64,
    /// Taper of the wing's chord along `x` at the tip (default 0.5: half the body's length).
    pub taper: f64,
    /// Icosphere subdivisions (default 3: 642 vertices; 4: 2562).
    pub subdivisions: u32,
}

impl Default for WingParams {
    fn default() -> Self {
        Self {
            semi_axes: Vector3::new(0.03, 0.02, 0.015),
            span: 0.03,
            wing_thickness: 0.004,
            taper: 0.5,
            subdivisions: 3,
        }
    }
}

/// Where the wing starts and ends on the unit sphere's `|y|` (the smooth step between).
const WING_ROOT: f64 = 0.35;
const WING_FULL: f64 = 0.8;

fn smoothstep(a: f64, b: f64, x: f64) -> f64 {
    let u = ((x - a) / (b - a)).clamp(0.0, 1.0);
    u * u * (3.0 - 2.0 * u)
}

fn check(q: &WingParams) -> Result<(), MeshError> {
    let positive = super::check_positive;
    for k in 0..3 {
        positive("semi_axes", q.semi_axes[k])?;
    }
    positive("span", q.span)?;
    positive("wing_thickness", q.wing_thickness)?;
    if q.wing_thickness >= 2.0 * q.semi_axes.z {
        return Err(MeshError::InvalidParameter {
            name: "wing_thickness",
            value: q.wing_thickness.to_string(),
            reason: format!(
                "must be thinner than the body ({} m along z)",
                2.0 * q.semi_axes.z
            ),
        });
    }
    if !(q.taper.is_finite() && (0.0..1.0).contains(&q.taper)) {
        return Err(MeshError::InvalidParameter {
            name: "taper",
            value: q.taper.to_string(),
            reason: "must be in [0, 1) (the fraction of the chord the tip loses)".into(),
        });
    }
    Ok(())
}

/// The winged ellipsoid (see the module doc): closed, 2-manifold, outward-oriented.
///
/// ```
/// use balloon_mesh::generate::{WingParams, winged_ellipsoid};
/// let m = winged_ellipsoid(&WingParams::default())?;
/// assert_eq!(m.num_vertices(), 642);
/// balloon_mesh::validate::validate_closed_manifold(&m)?;
/// # Ok::<(), balloon_mesh::MeshError>(())
/// ```
///
/// # Errors
/// [`MeshError::InvalidParameter`] for a non-positive length, a wing not thinner than the
/// body, a taper outside `[0, 1)`, or more than 8 subdivisions.
pub fn winged_ellipsoid(params: &WingParams) -> Result<TriMesh, MeshError> {
    check(params)?;
    let mut mesh = icosphere(1.0, params.subdivisions)?;
    let a = params.semi_axes;
    let thin = 0.5 * params.wing_thickness / a.z;
    for p in &mut mesh.vertices {
        let s = smoothstep(WING_ROOT, WING_FULL, p.y.abs());
        let y = a.y * p.y + params.span * s * p.y.signum();
        let x = a.x * p.x * (1.0 - params.taper * s);
        let z = a.z * p.z * (1.0 - s * (1.0 - thin));
        *p = Point3::new(x, y, z);
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{bounding_box, enclosed_volume};
    use crate::validate::validate_closed_manifold;

    #[test]
    fn the_winged_ellipsoid_is_closed_and_has_thin_wings() {
        for subdivisions in [3, 4] {
            let q = WingParams {
                subdivisions,
                ..WingParams::default()
            };
            let m = winged_ellipsoid(&q).unwrap();
            validate_closed_manifold(&m).unwrap();
            assert!(enclosed_volume(&m) > 0.0, "outward");
            let b = bounding_box(&m).unwrap();
            let tip = q.semi_axes.y + q.span;
            assert!((b.max.y - tip).abs() < 1e-12 && (b.min.y + tip).abs() < 1e-12);
            // Past the wing's full start every vertex lies within the wing's thickness.
            let wing: Vec<_> = m
                .vertices
                .iter()
                .filter(|p| p.y.abs() > WING_FULL * q.semi_axes.y + q.span)
                .collect();
            assert!(wing.len() > 20, "{}", wing.len());
            assert!(
                wing.iter()
                    .all(|p| p.z.abs() <= 0.5 * q.wing_thickness + 1e-12)
            );
        }
    }

    #[test]
    fn bad_wing_parameters_are_refused() {
        for (q, name) in [
            (
                WingParams {
                    wing_thickness: 0.05,
                    ..Default::default()
                },
                "wing_thickness",
            ),
            (
                WingParams {
                    taper: 1.0,
                    ..Default::default()
                },
                "taper",
            ),
            (
                WingParams {
                    span: -1.0,
                    ..Default::default()
                },
                "span",
            ),
        ] {
            let e = winged_ellipsoid(&q).unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
    }
}
