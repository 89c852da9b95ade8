//! Cameras: where the eye is, and how the mesh is framed.

use crate::RenderError;

/// Which world axis points up on screen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum UpAxis {
    /// +y up (mesh files, the built-in teddy).
    Y,
    /// +z up (the volumetric and two-layer scenes, where gravity points along -z).
    #[default]
    Z,
}

/// Perspective or orthographic projection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// A pinhole camera with the given vertical field of view (degrees, in `(0, 170)`).
    Perspective {
        /// Vertical field of view, degrees.
        fov_y_deg: f64,
    },
    /// Parallel projection.
    Orthographic,
}

impl Default for Projection {
    fn default() -> Self {
        Projection::Perspective { fov_y_deg: 30.0 }
    }
}

/// A camera orbiting the framed region: `azimuth` about the up axis, then `elevation` above
/// the horizontal plane. At `azimuth = elevation = 0` the camera looks along `-z` with `+y` up
/// (for [`UpAxis::Y`]) or along `+y` with `+z` up (for [`UpAxis::Z`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Rotation about the up axis, degrees.
    pub azimuth_deg: f64,
    /// Angle above the horizontal plane, degrees (positive: looking down on the body).
    pub elevation_deg: f64,
    /// The up axis.
    pub up: UpAxis,
    /// Projection.
    pub projection: Projection,
}

impl Default for Camera {
    fn default() -> Self {
        Self {
            azimuth_deg: 30.0,
            elevation_deg: 20.0,
            up: UpAxis::Z,
            projection: Projection::default(),
        }
    }
}

/// The world region a camera must show: a bounding sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Framing {
    /// Centre (m).
    pub center: [f64; 3],
    /// Radius (m), > 0.
    pub radius: f64,
}

impl Framing {
    /// The sphere around the finite points of `x` (flat, 3 per vertex): centred on the bounding
    /// box, radius the largest distance from that centre. `None` when there is no finite point.
    pub fn of_points(x: &[f64]) -> Option<Self> {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut any = false;
        for p in x.chunks_exact(3) {
            if p.iter().all(|c| c.is_finite()) {
                any = true;
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
        }
        if !any {
            return None;
        }
        let center: [f64; 3] = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
        let mut r2: f64 = 0.0;
        for p in x.chunks_exact(3) {
            if p.iter().all(|c| c.is_finite()) {
                r2 = r2.max((0..3).map(|k| (p[k] - center[k]).powi(2)).sum());
            }
        }
        Some(Self {
            center,
            radius: r2.sqrt().max(1e-9),
        })
    }

    /// The smallest sphere of this construction containing both (for a common framing of
    /// several frames, e.g. an animation).
    pub fn union(&self, other: &Framing) -> Framing {
        let d: [f64; 3] = std::array::from_fn(|k| other.center[k] - self.center[k]);
        let dist = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if dist + other.radius <= self.radius {
            return *self;
        }
        if dist + self.radius <= other.radius {
            return *other;
        }
        let radius = 0.5 * (dist + self.radius + other.radius);
        let t = (radius - self.radius) / dist;
        Framing {
            center: std::array::from_fn(|k| self.center[k] + t * d[k]),
            radius,
        }
    }
}

/// World -> view rotation (rows) and the helpers the rasteriser and the POV exporter share.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ViewTransform {
    /// Rows: screen right, screen up, towards the eye (all in world coordinates).
    pub rows: [[f64; 3]; 3],
    pub center: [f64; 3],
}

impl ViewTransform {
    pub fn new(camera: &Camera, framing: &Framing) -> Self {
        let (az, el) = (
            camera.azimuth_deg.to_radians(),
            camera.elevation_deg.to_radians(),
        );
        // In a y-up frame: towards-eye vector for azimuth 0, elevation 0 is +z.
        let back_y = [el.cos() * az.sin(), el.sin(), el.cos() * az.cos()];
        let right_y = [az.cos(), 0.0, -az.sin()];
        let up_y = cross(back_y, right_y);
        // Map the y-up frame to world coordinates.
        let to_world = |v: [f64; 3]| match camera.up {
            UpAxis::Y => v,
            // y-up (x, y, z) -> z-up world: up is +z, "towards the viewer at rest" is -y.
            UpAxis::Z => [v[0], -v[2], v[1]],
        };
        Self {
            rows: [to_world(right_y), to_world(up_y), to_world(back_y)],
            center: framing.center,
        }
    }

    /// View coordinates of world point `p`, relative to the framing centre.
    #[inline]
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let d = [
            p[0] - self.center[0],
            p[1] - self.center[1],
            p[2] - self.center[2],
        ];
        [
            dot(self.rows[0], d),
            dot(self.rows[1], d),
            dot(self.rows[2], d),
        ]
    }

    /// View components of world direction `v`.
    #[inline]
    pub fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        [
            dot(self.rows[0], v),
            dot(self.rows[1], v),
            dot(self.rows[2], v),
        ]
    }
}

/// Checks the camera parameters.
pub(crate) fn validate(camera: &Camera) -> Result<(), RenderError> {
    if !(camera.azimuth_deg.is_finite() && camera.elevation_deg.is_finite()) {
        return Err(RenderError::invalid(
            "camera",
            format!("{:?}", camera),
            "azimuth and elevation must be finite",
        ));
    }
    if camera.elevation_deg.abs() >= 90.0 {
        return Err(RenderError::invalid(
            "elevation_deg",
            camera.elevation_deg,
            "must be strictly between -90 and 90 degrees",
        ));
    }
    if let Projection::Perspective { fov_y_deg } = camera.projection
        && !(fov_y_deg > 0.0 && fov_y_deg < 170.0)
    {
        return Err(RenderError::invalid(
            "fov_y_deg",
            fov_y_deg,
            "the field of view must be in (0, 170) degrees",
        ));
    }
    Ok(())
}

#[inline]
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_contains_points_and_unions() {
        let f = Framing::of_points(&[0.0, 0.0, 0.0, 2.0, 0.0, 0.0, f64::NAN, 0.0, 0.0]).unwrap();
        assert_eq!(f.center, [1.0, 0.0, 0.0]);
        assert!((f.radius - 1.0).abs() < 1e-12);
        let g = Framing {
            center: [5.0, 0.0, 0.0],
            radius: 1.0,
        };
        let u = f.union(&g);
        assert!((u.radius - 3.0).abs() < 1e-12 && (u.center[0] - 3.0).abs() < 1e-12);
        assert_eq!(f.union(&f), f);
        assert!(Framing::of_points(&[]).is_none());
    }

    #[test]
    fn view_rows_are_orthonormal_and_right_handed() {
        for up in [UpAxis::Y, UpAxis::Z] {
            let cam = Camera {
                azimuth_deg: 37.0,
                elevation_deg: -12.0,
                up,
                ..Camera::default()
            };
            let v = ViewTransform::new(
                &cam,
                &Framing {
                    center: [0.0; 3],
                    radius: 1.0,
                },
            );
            for i in 0..3 {
                for j in 0..3 {
                    let d = dot(v.rows[i], v.rows[j]);
                    assert!((d - f64::from(u8::from(i == j))).abs() < 1e-12);
                }
            }
            let c = cross(v.rows[0], v.rows[1]);
            assert!((dot(c, v.rows[2]) - 1.0).abs() < 1e-12);
        }
        // Z up, no rotation: world +z is screen up, the eye is on -y.
        let v = ViewTransform::new(
            &Camera {
                azimuth_deg: 0.0,
                elevation_deg: 0.0,
                ..Camera::default()
            },
            &Framing {
                center: [0.0; 3],
                radius: 1.0,
            },
        );
        assert_eq!(v.apply([0.0, 0.0, 1.0]), [0.0, 1.0, 0.0]);
        assert_eq!(v.apply([0.0, -1.0, 0.0]), [0.0, 0.0, 1.0]);
        assert!(
            validate(&Camera {
                elevation_deg: 90.0,
                ..Camera::default()
            })
            .is_err()
        );
    }
}
