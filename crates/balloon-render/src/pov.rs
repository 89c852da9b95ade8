//! POV-Ray scene export of one frame: the paper's own rendering pipeline (Wang et al. 2015 renders its
//! balloons with POV-Ray).
//!
//! The scene holds a `mesh2` (vertex positions, smooth vertex normals from
//! `balloon_mesh::fields::vertex_normals`, face indices and, with a colour scale, one texture per
//! vertex interpolated across faces), a camera framing the body like [`crate::Renderer`] does,
//! two lights, a background and a glossy rubber-like finish. Coordinates are converted to
//! POV-Ray's left-handed, y-up system (`UpAxis::Z`: `(x, z, y)`; `UpAxis::Y`: `(x, y, -z)`), so
//! the picture matches the rasteriser's for the same [`crate::Camera`].
//!
//! Render with e.g. `povray +Ifinal.pov +Ofinal.png +W800 +H600 +A`.

use crate::camera::{Framing, Projection, UpAxis, ViewTransform};
use crate::image::write_atomically;
use crate::{Prop, RenderError, RenderOptions, Surface};
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;

/// The POV-Ray scene text for `surface` as seen with `opts` (camera, aspect ratio from
/// `width x height`, base colour or colour scale, title as a comment). `framing` as in
/// [`crate::Renderer::render`]. Every vertex must be finite.
pub fn scene(
    surface: &Surface<'_>,
    opts: &RenderOptions,
    framing: Option<&Framing>,
) -> Result<String, RenderError> {
    scene_with_props(surface, &[], opts, framing)
}

/// [`scene`] with the rigid objects `props` as exact POV-Ray primitives after the `mesh2`: a
/// [`Prop::Sphere`] as `sphere { <centre>, radius }`, a [`Prop::Plane`] as the infinite
/// `plane { <normal>, distance }` (unit normal, `distance = normal . point`), each in its own
/// colour, in the same converted coordinates as the mesh.
pub fn scene_with_props(
    surface: &Surface<'_>,
    props: &[Prop],
    opts: &RenderOptions,
    framing: Option<&Framing>,
) -> Result<String, RenderError> {
    for prop in props {
        prop.validate()?;
    }
    let n = surface.positions.len() / 3;
    if !surface.positions.len().is_multiple_of(3) {
        return Err(RenderError::PositionsLength {
            len: surface.positions.len(),
        });
    }
    if let Some(i) = surface.positions.iter().position(|c| !c.is_finite()) {
        return Err(RenderError::NonFiniteVertex { vertex: i / 3 });
    }
    crate::camera::validate(&opts.camera)?;
    crate::image::check_size(opts.width, opts.height)?;
    let normals = balloon_mesh::fields::vertex_normals(surface.positions, surface.triangles)?;
    let colors: Option<Vec<[f32; 3]>> = match (&opts.color_scale, surface.scalars) {
        (Some(cs), Some(s)) => {
            cs.validate()?;
            if s.len() != n {
                return Err(RenderError::ScalarCount {
                    len: s.len(),
                    num_vertices: n,
                });
            }
            Some(s.iter().map(|&v| cs.map.eval(cs.normalize(v))).collect())
        }
        _ => None,
    };
    let framing = match framing {
        Some(f) => *f,
        None => Framing::of_points(surface.positions).ok_or(RenderError::NothingToFrame)?,
    };
    let up = opts.camera.up;
    let pov = |p: [f64; 3]| match up {
        UpAxis::Z => [p[0], p[2], p[1]],
        UpAxis::Y => [p[0], p[1], -p[2]],
    };
    let view = ViewTransform::new(&opts.camera, &framing);
    let aspect = opts.width as f64 / opts.height as f64;
    let back = view.rows[2];
    let right = view.rows[0];
    let upv = view.rows[1];
    let c = framing.center;
    let r = framing.radius;
    let at = |d: f64| -> [f64; 3] { std::array::from_fn(|k| c[k] + d * back[k]) };
    let mut s = String::with_capacity(64 * (n + surface.triangles.len()) + 2048);
    let mut w = |line: String| {
        s.push_str(&line);
        s.push('\n');
    };
    w("// POV-Ray scene written by balloon-render (balloon, issue 7).".into());
    if let Some(t) = &opts.title {
        w(format!("// {}", t.replace('\n', " ")));
    }
    w(format!(
        "// {} vertices, {} triangles. Render: povray +I<this file> +O<image>.png +W{} +H{} +A",
        n,
        surface.triangles.len(),
        opts.width,
        opts.height
    ));
    w("#version 3.7;".into());
    w("global_settings { assumed_gamma 1.0 }".into());
    let bg = opts.background.map(|v| srgb_to_linear(v as f32 / 255.0));
    w(format!(
        "background {{ color rgb <{:.4}, {:.4}, {:.4}> }}",
        bg[0], bg[1], bg[2]
    ));
    match opts.camera.projection {
        Projection::Perspective { fov_y_deg } => {
            let half_y = 0.5 * fov_y_deg.to_radians();
            let half_x = (half_y.tan() * aspect).atan();
            let dist = 1.04 * r / half_y.min(half_x).sin();
            let eye = pov(at(dist));
            let look = pov(c);
            w("camera {".into());
            w("  perspective".into());
            w(format!("  location <{}, {}, {}>", eye[0], eye[1], eye[2]));
            w(format!("  right x * {aspect:.6}"));
            w("  up y".into());
            w(format!("  angle {:.6}", 2.0 * half_x.to_degrees()));
            w(format!("  look_at <{}, {}, {}>", look[0], look[1], look[2]));
            w("}".into());
        }
        Projection::Orthographic => {
            let eye = pov(at(4.0 * r));
            let look = pov(c);
            let half = 1.04 * r;
            let (hw, hh) = if aspect >= 1.0 {
                (half * aspect, half)
            } else {
                (half, half / aspect)
            };
            w("camera {".into());
            w("  orthographic".into());
            w(format!("  location <{}, {}, {}>", eye[0], eye[1], eye[2]));
            w(format!("  right x * {:.6}", 2.0 * hw));
            w(format!("  up y * {:.6}", 2.0 * hh));
            w(format!("  look_at <{}, {}, {}>", look[0], look[1], look[2]));
            w("}".into());
        }
    }
    // Key light above-left of the camera, fill light from the right, both far away.
    let light = |sx: f64, sy: f64, sb: f64| -> [f64; 3] {
        pov(std::array::from_fn(|k| {
            c[k] + 20.0 * r * (sx * right[k] + sy * upv[k] + sb * back[k])
        }))
    };
    let key = light(-0.45, 0.6, 0.75);
    let fill = light(0.6, -0.2, 0.75);
    w(format!(
        "light_source {{ <{}, {}, {}> color rgb <1, 1, 1> }}",
        key[0], key[1], key[2]
    ));
    w(format!(
        "light_source {{ <{}, {}, {}> color rgb <0.35, 0.35, 0.4> shadowless }}",
        fill[0], fill[1], fill[2]
    ));
    w("#declare BalloonFinish = finish { ambient 0.12 diffuse 0.75 specular 0.5 roughness 0.02 phong 0.3 phong_size 40 reflection 0.03 }".into());
    let base = opts.base_color.map(|v| srgb_to_linear(v as f32 / 255.0));
    w("mesh2 {".into());
    let mut buf = String::new();
    let _ = writeln!(buf, "  vertex_vectors {{ {n},");
    for (i, p) in surface.positions.chunks_exact(3).enumerate() {
        let q = pov([p[0], p[1], p[2]]);
        let sep = if i + 1 < n { "," } else { "" };
        let _ = writeln!(buf, "    <{}, {}, {}>{sep}", q[0], q[1], q[2]);
    }
    buf.push_str("  }\n");
    let _ = writeln!(buf, "  normal_vectors {{ {n},");
    for (i, v) in normals.chunks_exact(3).enumerate() {
        let mut q = pov([v[0], v[1], v[2]]);
        if q.iter().all(|c| *c == 0.0) {
            q = [0.0, 1.0, 0.0];
        }
        let sep = if i + 1 < n { "," } else { "" };
        let _ = writeln!(buf, "    <{:.6}, {:.6}, {:.6}>{sep}", q[0], q[1], q[2]);
    }
    buf.push_str("  }\n");
    if let Some(cols) = &colors {
        let _ = writeln!(buf, "  texture_list {{ {n},");
        for col in cols {
            let l = col.map(srgb_to_linear);
            let _ = writeln!(
                buf,
                "    texture {{ pigment {{ rgb <{:.4}, {:.4}, {:.4}> }} finish {{ BalloonFinish }} }}",
                l[0], l[1], l[2]
            );
        }
        buf.push_str("  }\n");
    }
    let m = surface.triangles.len();
    let _ = writeln!(buf, "  face_indices {{ {m},");
    for (i, t) in surface.triangles.iter().enumerate() {
        let sep = if i + 1 < m { "," } else { "" };
        if colors.is_some() {
            let _ = writeln!(
                buf,
                "    <{}, {}, {}>, {}, {}, {}{sep}",
                t[0], t[1], t[2], t[0], t[1], t[2]
            );
        } else {
            let _ = writeln!(buf, "    <{}, {}, {}>{sep}", t[0], t[1], t[2]);
        }
    }
    buf.push_str("  }\n");
    if colors.is_none() {
        let _ = writeln!(
            buf,
            "  texture {{ pigment {{ rgb <{:.4}, {:.4}, {:.4}> }} finish {{ BalloonFinish }} }}",
            base[0], base[1], base[2]
        );
    }
    buf.push_str("}\n");
    for prop in props {
        let col = prop.color().map(|v| srgb_to_linear(v as f32 / 255.0));
        let texture = format!(
            "texture {{ pigment {{ rgb <{:.4}, {:.4}, {:.4}> }} finish {{ BalloonFinish }} }}",
            col[0], col[1], col[2]
        );
        match *prop {
            Prop::Sphere { center, radius, .. } => {
                let c = pov(center);
                let _ = writeln!(
                    buf,
                    "sphere {{ <{}, {}, {}>, {} {texture} }}",
                    c[0], c[1], c[2], radius
                );
            }
            Prop::Plane { point, normal, .. } => {
                let (_, _, unit) = crate::props::plane_frame(normal);
                // The axis swap is orthogonal, so the distance from the origin is kept.
                let d = crate::camera::dot(unit, point);
                let q = pov(unit);
                let _ = writeln!(
                    buf,
                    "plane {{ <{}, {}, {}>, {} {texture} }}",
                    q[0], q[1], q[2], d
                );
            }
        }
    }
    s.push_str(&buf);
    Ok(s)
}

/// Writes [`scene`] to `path` atomically (temporary file, then rename).
pub fn write_scene(
    path: &Path,
    surface: &Surface<'_>,
    opts: &RenderOptions,
    framing: Option<&Framing>,
) -> Result<(), RenderError> {
    write_scene_with_props(path, surface, &[], opts, framing)
}

/// Writes [`scene_with_props`] to `path` atomically (temporary file, then rename).
pub fn write_scene_with_props(
    path: &Path,
    surface: &Surface<'_>,
    props: &[Prop],
    opts: &RenderOptions,
    framing: Option<&Framing>,
) -> Result<(), RenderError> {
    let text = scene_with_props(surface, props, opts, framing)?;
    write_atomically(path, |w| {
        w.write_all(text.as_bytes())
            .map_err(|source| RenderError::Io {
                path: path.to_path_buf(),
                source,
            })
    })
}

/// sRGB-encoded channel to linear (POV-Ray with `assumed_gamma 1.0` works in linear light).
fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ColorScale;

    /// Counts of the entries of block `name { N, ... }` (the declared count and the `<` items
    /// or `texture` items inside).
    fn block(s: &str, name: &str) -> (usize, usize) {
        let start = s.find(&format!("{name} {{")).expect(name);
        let rest = &s[start + name.len() + 2..];
        let end = rest.find("\n  }").unwrap();
        let body = &rest[..end];
        let (count, items) = body.split_once(',').unwrap();
        let declared: usize = count.trim().parse().unwrap();
        let found = items
            .lines()
            .filter(|l| l.trim_start().starts_with('<') || l.trim_start().starts_with("texture"))
            .count();
        (declared, found)
    }

    #[test]
    fn mesh2_has_the_right_counts_and_a_camera() {
        let m = balloon_mesh::generate::icosphere(1.0, 2).unwrap();
        let x = m.positions_flat();
        let s: Vec<f64> = x.chunks(3).map(|p| p[0]).collect();
        let opts = RenderOptions {
            color_scale: Some(ColorScale::new(-1.0, 1.0, "x")),
            title: Some("test".into()),
            ..RenderOptions::new(400, 300)
        };
        let text = scene(
            &Surface::new(&x, &m.triangles).with_scalars(&s),
            &opts,
            None,
        )
        .unwrap();
        let nv = m.num_vertices();
        let nt = m.num_triangles();
        assert_eq!(block(&text, "vertex_vectors"), (nv, nv));
        assert_eq!(block(&text, "normal_vectors"), (nv, nv));
        assert_eq!(block(&text, "texture_list"), (nv, nv));
        assert_eq!(block(&text, "face_indices"), (nt, nt));
        assert!(text.contains("camera {") && text.contains("light_source"));
        assert_eq!(text.matches('{').count(), text.matches('}').count());
        // Without a colour scale: one texture, no texture list.
        let plain = scene(
            &Surface::new(&x, &m.triangles),
            &RenderOptions::new(64, 64),
            None,
        )
        .unwrap();
        assert!(!plain.contains("texture_list"));
        // Z up -> POV y: the top vertex of the sphere (world z = 1) has POV y = 1.
        let top = x
            .chunks(3)
            .position(|p| (p[2] - 1.0).abs() < 1e-12)
            .unwrap();
        let line = plain
            .lines()
            .skip_while(|l| !l.contains("vertex_vectors"))
            .nth(top + 1)
            .unwrap();
        assert!(line.contains(", 1, "), "{line}");
        let nan = [f64::NAN, 0.0, 0.0];
        assert!(scene(&Surface::new(&nan, &[]), &opts, None).is_err());
    }

    #[test]
    fn props_are_written_as_pov_primitives_in_pov_coordinates() {
        let m = balloon_mesh::generate::icosphere(1.0, 1).unwrap();
        let x = m.positions_flat();
        let props = [
            Prop::sphere([0.5, -0.25, 3.0], 0.75),
            Prop::floor([0.0, 0.0, -1.5], [0.0, 0.0, 2.0], 4.0),
        ];
        let text = scene_with_props(
            &Surface::new(&x, &m.triangles),
            &props,
            &RenderOptions::new(64, 48),
            None,
        )
        .unwrap();
        // Z up: world (x, y, z) is POV <x, z, y>.
        assert!(
            text.contains("sphere { <0.5, 3, -0.25>, 0.75 texture"),
            "{text}"
        );
        assert!(text.contains("plane { <0, 1, 0>, -1.5 texture"), "{text}");
        assert_eq!(text.matches('{').count(), text.matches('}').count());
        let bad = [Prop::floor([0.0; 3], [0.0; 3], 1.0)];
        assert!(
            scene_with_props(
                &Surface::new(&x, &m.triangles),
                &bad,
                &RenderOptions::new(64, 48),
                None
            )
            .is_err()
        );
    }

    #[test]
    fn surface_errors_carry_their_numbers_and_the_field_error_as_source() {
        let x = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let opts = RenderOptions::new(64, 48);
        // A triangle naming a missing vertex: the vertex normals' own error is the source.
        let e = scene(&Surface::new(&x, &[[0, 1, 7]]), &opts, None).unwrap_err();
        let source = std::error::Error::source(&e).expect("the field error is the source");
        assert!(matches!(
            source.downcast_ref::<balloon_mesh::fields::FieldError>(),
            Some(balloon_mesh::fields::FieldError::VertexOutOfRange {
                triangle: 0,
                vertex: 7,
                num_vertices: 3
            })
        ));
        assert!(e.to_string().starts_with("bad surface: "), "{e}");
        assert!(e.to_string().contains("vertex 7"), "{e}");
        // Lengths and non-finite vertices are named by number.
        let e = scene(&Surface::new(&x[..8], &[]), &opts, None).unwrap_err();
        assert!(matches!(e, RenderError::PositionsLength { len: 8 }), "{e}");
        assert_eq!(
            e.to_string(),
            "bad surface: positions has length 8, not a multiple of 3"
        );
        let mut bad = x;
        bad[4] = f64::NAN;
        let e = scene(&Surface::new(&bad, &[[0, 1, 2]]), &opts, None).unwrap_err();
        assert!(
            matches!(e, RenderError::NonFiniteVertex { vertex: 1 }),
            "{e}"
        );
        let scalars = [1.0, 2.0];
        let e = scene(
            &Surface::new(&x, &[[0, 1, 2]]).with_scalars(&scalars),
            &RenderOptions {
                color_scale: Some(crate::ColorScale::new(0.0, 1.0, "s")),
                ..RenderOptions::new(64, 48)
            },
            None,
        )
        .unwrap_err();
        assert!(
            matches!(
                e,
                RenderError::ScalarCount {
                    len: 2,
                    num_vertices: 3
                }
            ),
            "{e}"
        );
    }
}
