//! A flattened ellipsoid with a thin fin: a test shape for thin flat parts (wings, fins, ears)
//! under pressure.
//!
//! Why this shape: a thin flat part of a balloon's rest shape is two nearly parallel walls a few
//! millimetres apart. A membrane carries pressure only by curving, so when such a part is
//! inflated the walls first bulge apart with almost no stiffness against the pressure (a flat
//! membrane at rest has none; it gains it as it stretches), and the rim where they meet is a
//! fold. Real models have such parts (a bird's wings, a fish's fins, thin ears); the smooth
//! spheres, ellipsoids and the teddy do not. The body is a smooth union of a flattened ellipsoid
//! and a thin, rounded plate standing on its back, meshed by
//! [`implicit_surface`].
//!
//! Frame: the body's long axis is `x`, its back faces `+z`, the fin lies in the `x z` plane
//! (thin along `y`); the shape is centred on the ellipsoid's centre.

use super::implicit::{ImplicitParams, implicit_surface};
use crate::geometry::Aabb;
use crate::{MeshError, TriMesh};
use nalgebra::{Point3, Vector3};

/// Parameters of [`finned_ellipsoid`] (lengths in metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FinParams {
    /// Semi-axes of the body along `x`, `y`, `z` (default 0.05, 0.025, 0.015).
    pub semi_axes: Vector3<f64>,
    /// Thickness of the fin across `y` (default 0.006: two walls 6 mm apart).
    pub fin_thickness: f64,
    /// Length of the fin along `x` (default 0.05).
    pub fin_length: f64,
    /// Height of the fin's top edge above the body's centre, along `z` (default 0.045).
    pub fin_height: f64,
    /// Radius of the fillet where fin and body meet (default 0.004).
    pub fillet: f64,
    /// Grid spacing of the mesher (default 0.003: 6404 vertices with the defaults; at most half
    /// the fin's thickness).
    pub cell_size: f64,
}

impl Default for FinParams {
    fn default() -> Self {
        Self {
            semi_axes: Vector3::new(0.05, 0.025, 0.015),
            fin_thickness: 0.006,
            fin_length: 0.05,
            fin_height: 0.045,
            fillet: 0.004,
            cell_size: 0.003,
        }
    }
}

/// Signed distance (approximate outside the ellipsoid's axes) of the finned body.
fn sdf(p: &Point3<f64>, q: &FinParams) -> f64 {
    // Ellipsoid: the first-order distance |p/a| - 1 scaled by the gradient's length.
    let s = p.coords.component_div(&q.semi_axes);
    let k0 = s.norm();
    let k1 = p
        .coords
        .component_div(&q.semi_axes.component_mul(&q.semi_axes))
        .norm();
    let body = if k1 > 0.0 {
        k0 * (k0 - 1.0) / k1
    } else {
        -q.semi_axes.min()
    };
    // Fin: a rounded box, x in [-L/2, L/2], y in [-t/2, t/2], z in [0, H], edge radius t/2.
    let r = 0.5 * q.fin_thickness;
    let half = Vector3::new(
        0.5 * q.fin_length,
        0.5 * q.fin_thickness,
        0.5 * q.fin_height,
    );
    let centre = Vector3::new(0.0, 0.0, 0.5 * q.fin_height);
    let d = (p.coords - centre).abs() - (half - Vector3::repeat(r));
    let outside = d.map(|v| v.max(0.0)).norm();
    let fin = outside + d.max().min(0.0) - r;
    // Polynomial smooth minimum (fillet of radius `fillet`).
    let k = q.fillet;
    let h = (0.5 + 0.5 * (fin - body) / k).clamp(0.0, 1.0);
    fin * (1.0 - h) + body * h - k * h * (1.0 - h)
}

fn check(q: &FinParams) -> Result<(), MeshError> {
    let positive = super::check_positive;
    for k in 0..3 {
        positive("semi_axes", q.semi_axes[k])?;
    }
    positive("fin_thickness", q.fin_thickness)?;
    positive("fin_length", q.fin_length)?;
    positive("fin_height", q.fin_height)?;
    positive("fillet", q.fillet)?;
    positive("cell_size", q.cell_size)?;
    if q.cell_size > 0.5 * q.fin_thickness {
        return Err(MeshError::InvalidParameter {
            name: "cell_size",
            value: q.cell_size.to_string(),
            reason: format!(
                "must be at most half the fin thickness ({} m) to resolve the fin",
                q.fin_thickness
            ),
        });
    }
    Ok(())
}

/// The finned ellipsoid (see the module doc): closed, 2-manifold, outward-oriented.
///
/// # Errors
/// [`MeshError::InvalidParameter`] for a non-positive length, or a `cell_size` larger than half
/// the fin's thickness (the fin would not be resolved).
pub fn finned_ellipsoid(params: &FinParams) -> Result<TriMesh, MeshError> {
    check(params)?;
    let a = params.semi_axes;
    let top = a.z.max(params.fin_height) + params.fillet;
    let xr = a.x.max(0.5 * params.fin_length);
    let bounds = Aabb {
        min: Point3::new(-xr, -a.y, -a.z),
        max: Point3::new(xr, a.y, top),
    };
    implicit_surface(
        |p| sdf(p, params),
        bounds,
        &ImplicitParams {
            cell_size: params.cell_size,
            relax_iterations: 8,
            ..Default::default()
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{bounding_box, enclosed_volume};
    use crate::validate::validate_closed_manifold;

    #[test]
    fn the_finned_ellipsoid_is_closed_and_has_its_fin() {
        let q = FinParams::default();
        let m = finned_ellipsoid(&q).unwrap();
        validate_closed_manifold(&m).unwrap();
        let b = bounding_box(&m).unwrap();
        // The fin's top edge, not the ellipsoid, sets the height.
        assert!((b.max.z - q.fin_height).abs() < 0.5 * q.cell_size, "{b:?}");
        assert!((b.min.z + q.semi_axes.z).abs() < 0.5 * q.cell_size, "{b:?}");
        // Vertices high above the body lie in the thin fin: |y| <= t/2.
        let high: Vec<_> = m.vertices.iter().filter(|p| p.z > 0.03).collect();
        assert!(high.len() > 50, "{}", high.len());
        assert!(
            high.iter()
                .all(|p| p.y.abs() <= 0.5 * q.fin_thickness + 1e-4)
        );
        // Volume: the ellipsoid's plus about the fin's part outside it.
        let ell = 4.0 / 3.0 * std::f64::consts::PI * q.semi_axes.product();
        let v = enclosed_volume(&m);
        assert!(v > ell && v < 1.15 * ell, "{v} vs {ell}");
    }

    #[test]
    fn a_cell_too_coarse_for_the_fin_is_refused() {
        let q = FinParams {
            cell_size: 0.004,
            ..Default::default()
        };
        let e = finned_ellipsoid(&q).unwrap_err().to_string();
        assert!(e.contains("cell_size"), "{e}");
    }
}
