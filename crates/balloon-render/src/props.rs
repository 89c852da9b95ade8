//! Rigid scene objects drawn beside the simulated surface: a sphere (the falling ball of the
//! volumetric drop-sphere scene, Diziol, Bender and Bayer 2011, Fig. 4) and a floor plane.
//!
//! The rasteriser draws a [`Prop`] through its triangulation ([`Prop::mesh`]: an icosphere, or
//! a square grid on the plane), in its own solid colour; the POV-Ray export writes the exact
//! primitive (`sphere { }`, `plane { }`).

use crate::RenderError;

/// Default colour of a drawn sphere: a blue-grey steel, far from the colour maps' ends and from
/// the balloon red.
pub const SPHERE_COLOR: [u8; 3] = [88, 108, 140];
/// Default colour of a drawn floor: a warm light grey, darker than the default background.
pub const FLOOR_COLOR: [u8; 3] = [178, 174, 164];

/// Subdivisions of the icosphere that draws a sphere (1280 triangles).
const SPHERE_SUBDIVISIONS: u32 = 3;
/// Squares along each side of the grid that draws a floor: with a perspective camera, a
/// triangle with a vertex behind the eye is skipped, so the floor is cut into small pieces.
const FLOOR_CELLS: usize = 16;

/// A rigid object of the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Prop {
    /// A sphere.
    Sphere {
        /// Centre (m).
        center: [f64; 3],
        /// Radius (m), > 0.
        radius: f64,
        /// Colour.
        color: [u8; 3],
    },
    /// A plane, drawn by the rasteriser as the square of half side `half_size` centred at
    /// `point` (POV-Ray draws the infinite plane).
    Plane {
        /// A point of the plane, the centre of the drawn square (m).
        point: [f64; 3],
        /// Normal towards the free side (any length > 0).
        normal: [f64; 3],
        /// Half the side of the drawn square (m), > 0.
        half_size: f64,
        /// Colour.
        color: [u8; 3],
    },
}

impl Prop {
    /// A sphere in [`SPHERE_COLOR`].
    pub fn sphere(center: [f64; 3], radius: f64) -> Self {
        Prop::Sphere {
            center,
            radius,
            color: SPHERE_COLOR,
        }
    }

    /// A floor square in [`FLOOR_COLOR`].
    pub fn floor(point: [f64; 3], normal: [f64; 3], half_size: f64) -> Self {
        Prop::Plane {
            point,
            normal,
            half_size,
            color: FLOOR_COLOR,
        }
    }

    /// The colour.
    pub fn color(&self) -> [u8; 3] {
        match *self {
            Prop::Sphere { color, .. } | Prop::Plane { color, .. } => color,
        }
    }

    /// Checks that every number is finite, the sizes positive and the normal non-zero.
    pub fn validate(&self) -> Result<(), RenderError> {
        let finite = |v: &[f64]| v.iter().all(|c| c.is_finite());
        match *self {
            Prop::Sphere { center, radius, .. } => {
                if !(finite(&center) && radius.is_finite() && radius > 0.0) {
                    return Err(RenderError::invalid(
                        "sphere",
                        format!("centre {center:?}, radius {radius}"),
                        "needs a finite centre and a positive finite radius",
                    ));
                }
            }
            Prop::Plane {
                point,
                normal,
                half_size,
                ..
            } => {
                let n2 = normal.iter().map(|c| c * c).sum::<f64>();
                if !(finite(&point)
                    && finite(&normal)
                    && n2 > 0.0
                    && half_size.is_finite()
                    && half_size > 0.0)
                {
                    return Err(RenderError::invalid(
                        "plane",
                        format!("point {point:?}, normal {normal:?}, half size {half_size}"),
                        "needs a finite point, a non-zero finite normal and a positive half size",
                    ));
                }
            }
        }
        Ok(())
    }

    /// The four corners of a plane's drawn square, counter-clockwise seen from the free side
    /// (`None` for a sphere or an invalid plane): the floor as one quad in frame files.
    pub fn corners(&self) -> Option<[[f64; 3]; 4]> {
        self.validate().ok()?;
        match *self {
            Prop::Sphere { .. } => None,
            Prop::Plane {
                point,
                normal,
                half_size,
                ..
            } => {
                let (u, v, _) = plane_frame(normal);
                let at = |a: f64, b: f64| -> [f64; 3] {
                    std::array::from_fn(|k| point[k] + half_size * (a * u[k] + b * v[k]))
                };
                Some([at(-1.0, -1.0), at(1.0, -1.0), at(1.0, 1.0), at(-1.0, 1.0)])
            }
        }
    }

    /// The triangulation the rasteriser draws (flat positions, outward / free-side oriented
    /// triangles): an icosphere of 1280 triangles whose vertices lie on the sphere, or a
    /// 16 x 16 grid of squares covering the plane's drawn square.
    pub fn mesh(&self) -> Result<(Vec<f64>, Vec<[usize; 3]>), RenderError> {
        self.validate()?;
        match *self {
            Prop::Sphere { center, radius, .. } => {
                let m = balloon_mesh::generate::icosphere(radius, SPHERE_SUBDIVISIONS).map_err(
                    |e| RenderError::invalid("sphere", format!("radius {radius}"), &e.to_string()),
                )?;
                let x = m
                    .vertices
                    .iter()
                    .flat_map(|p| [p.x + center[0], p.y + center[1], p.z + center[2]])
                    .collect();
                Ok((x, m.triangles))
            }
            Prop::Plane {
                point,
                normal,
                half_size,
                ..
            } => {
                let (u, v, _) = plane_frame(normal);
                let n = FLOOR_CELLS;
                let mut x = Vec::with_capacity(3 * (n + 1) * (n + 1));
                for j in 0..=n {
                    let b = half_size * (2.0 * j as f64 / n as f64 - 1.0);
                    for i in 0..=n {
                        let a = half_size * (2.0 * i as f64 / n as f64 - 1.0);
                        x.extend((0..3).map(|k| point[k] + a * u[k] + b * v[k]));
                    }
                }
                let id = |i: usize, j: usize| j * (n + 1) + i;
                let mut t = Vec::with_capacity(2 * n * n);
                for j in 0..n {
                    for i in 0..n {
                        // u x v = normal: counter-clockwise seen from the free side.
                        t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                        t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
                    }
                }
                Ok((x, t))
            }
        }
    }
}

/// An orthonormal frame `(u, v, n)` with `n` the unit `normal` and `u x v = n`.
pub(crate) fn plane_frame(normal: [f64; 3]) -> ([f64; 3], [f64; 3], [f64; 3]) {
    let len = normal.iter().map(|c| c * c).sum::<f64>().sqrt();
    let n = normal.map(|c| c / len);
    // The axis least aligned with n.
    let k = (0..3)
        .min_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs()))
        .unwrap_or(0);
    let mut e = [0.0; 3];
    e[k] = 1.0;
    let u = normalize(crate::camera::cross(e, n));
    let v = crate::camera::cross(n, u);
    (u, v, n)
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = crate::camera::dot(a, a).sqrt();
    a.map(|c| c / l)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_mesh_lies_on_the_sphere_and_floor_mesh_on_the_plane() {
        let s = Prop::sphere([1.0, -2.0, 0.5], 0.25);
        let (x, t) = s.mesh().unwrap();
        assert_eq!(t.len(), 1280);
        for p in x.chunks(3) {
            let r = ((p[0] - 1.0).powi(2) + (p[1] + 2.0).powi(2) + (p[2] - 0.5).powi(2)).sqrt();
            assert!((r - 0.25).abs() < 1e-12, "{r}");
        }
        let f = Prop::floor([0.0, 0.0, -1.0], [0.0, 0.0, 2.0], 3.0);
        let (x, t) = f.mesh().unwrap();
        assert_eq!(t.len(), 2 * 16 * 16);
        assert!(x.chunks(3).all(|p| (p[2] + 1.0).abs() < 1e-12));
        let span = |k: usize| {
            let v = x.chunks(3).map(|p| p[k]);
            v.clone().fold(f64::MIN, f64::max) - v.fold(f64::MAX, f64::min)
        };
        assert!((span(0) - 6.0).abs() < 1e-12 && (span(1) - 6.0).abs() < 1e-12);
        let c = f.corners().unwrap();
        assert!(
            c.iter()
                .all(|p| (p[2] + 1.0).abs() < 1e-12 && p[0].abs() == 3.0)
        );
        let turn = crate::camera::cross(
            [c[1][0] - c[0][0], c[1][1] - c[0][1], 0.0],
            [c[2][0] - c[1][0], c[2][1] - c[1][1], 0.0],
        );
        assert!(turn[2] > 0.0, "counter-clockwise from +z");
        assert_eq!(s.corners(), None);
        // Every triangle faces the free side (+z).
        for tri in &t {
            let p = |i: usize| [x[3 * tri[i]], x[3 * tri[i] + 1], x[3 * tri[i] + 2]];
            let (a, b, c) = (p(0), p(1), p(2));
            let n = crate::camera::cross(
                [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
                [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
            );
            assert!(n[2] > 0.0);
        }
        for bad in [
            Prop::sphere([0.0; 3], 0.0),
            Prop::sphere([f64::NAN, 0.0, 0.0], 1.0),
            Prop::floor([0.0; 3], [0.0; 3], 1.0),
            Prop::floor([0.0; 3], [0.0, 0.0, 1.0], -1.0),
        ] {
            assert!(bad.mesh().is_err(), "{bad:?}");
        }
    }
}
