//! The z-buffer triangle rasteriser, shading, legend and title.

use crate::camera::{self, Framing, Projection, ViewTransform};
use crate::colormap::ColorScale;
use crate::font::{self, GLYPH_HEIGHT};
use crate::image::check_size;
use crate::{Camera, Image, Prop, RenderError};

/// A triangle surface to draw: flat positions (3 per vertex, m), triangles, and optionally one
/// scalar per vertex to colour it by (see [`RenderOptions::color_scale`]).
#[derive(Clone, Copy, Debug)]
pub struct Surface<'a> {
    /// Flat positions `[x0, y0, z0, x1, ...]`.
    pub positions: &'a [f64],
    /// Triangles (vertex indices). Both sides are drawn; back faces are lit from their side.
    pub triangles: &'a [[usize; 3]],
    /// One value per vertex, mapped through the colour scale; NaN draws as the lowest colour.
    pub scalars: Option<&'a [f64]>,
}

impl<'a> Surface<'a> {
    /// A surface without scalars.
    pub fn new(positions: &'a [f64], triangles: &'a [[usize; 3]]) -> Self {
        Self {
            positions,
            triangles,
            scalars: None,
        }
    }

    /// The same surface coloured by `scalars` (one per vertex).
    pub fn with_scalars(mut self, scalars: &'a [f64]) -> Self {
        self.scalars = Some(scalars);
        self
    }

    fn validate(&self) -> Result<usize, RenderError> {
        if !self.positions.len().is_multiple_of(3) {
            return Err(RenderError::PositionsLength {
                len: self.positions.len(),
            });
        }
        let n = self.positions.len() / 3;
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(&v) = tri.iter().find(|&&v| v >= n) {
                return Err(RenderError::VertexOutOfRange {
                    triangle: t,
                    vertex: v,
                    num_vertices: n,
                });
            }
        }
        if let Some(s) = self.scalars
            && s.len() != n
        {
            return Err(RenderError::ScalarCount {
                len: s.len(),
                num_vertices: n,
            });
        }
        Ok(n)
    }
}

/// What to draw and how.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Image width, pixels (1..=16384).
    pub width: u32,
    /// Image height, pixels (1..=16384).
    pub height: u32,
    /// The camera.
    pub camera: Camera,
    /// Background colour.
    pub background: [u8; 3],
    /// Surface colour when there is no colour scale (or no scalars).
    pub base_color: [u8; 3],
    /// Colour the surface by its scalars over this range and draw a legend bar on the right.
    pub color_scale: Option<ColorScale>,
    /// Text drawn at the top left.
    pub title: Option<String>,
    /// Smooth (interpolated vertex normals, Phong) or flat (per-face) shading.
    pub smooth: bool,
    /// Strength of the Blinn-Phong highlight, `0..=1`.
    pub specular: f32,
    /// Skip triangles facing away from the camera: about twice as fast for closed,
    /// outward-oriented surfaces, whose back faces are hidden anyway. Leave off for open or
    /// inconsistently oriented meshes (triangle soups, the 2D two-layer band).
    pub cull_back_faces: bool,
}

impl RenderOptions {
    /// Defaults for a `width x height` image: default camera, light background, balloon red,
    /// smooth shading, a moderate highlight, no colour scale, no title.
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            camera: Camera::default(),
            background: [236, 239, 243],
            base_color: [214, 58, 52],
            color_scale: None,
            title: None,
            smooth: true,
            specular: 0.35,
            cull_back_faces: false,
        }
    }
}

/// Reusable buffers for rendering many frames (depth buffer, projected vertices, normals, the
/// image): after the first frame of a given size, rendering allocates only the vertex normals.
#[derive(Debug)]
pub struct Renderer {
    depth: Vec<f32>,
    screen: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    tvals: Vec<f32>,
    image: Image,
}

impl Default for Renderer {
    fn default() -> Self {
        Self::new()
    }
}

/// Screen layout in pixels.
struct Layout {
    scale: u32,
    pad: i64,
    title_h: i64,
    legend_w: i64,
    ticks: Vec<(f64, String)>,
}

const TICKS: usize = 5;

impl Layout {
    fn new(opts: &RenderOptions) -> Self {
        let scale = (opts.width.min(opts.height) / 240).clamp(1, 4);
        let pad = 4 * scale as i64;
        let th = (GLYPH_HEIGHT * scale) as i64;
        let title_h = if opts.title.is_some() {
            th + 2 * pad
        } else {
            0
        };
        let (legend_w, ticks) = match &opts.color_scale {
            None => (0, Vec::new()),
            Some(cs) => {
                let ticks: Vec<(f64, String)> = crate::colormap::tick_labels(cs.min, cs.max, TICKS)
                    .into_iter()
                    .enumerate()
                    .map(|(i, label)| (i as f64 / (TICKS - 1) as f64, label))
                    .collect();
                let label_w = ticks
                    .iter()
                    .map(|(_, s)| font::text_width(s, scale))
                    .max()
                    .unwrap_or(0) as i64;
                let bar_w = 10 * scale as i64;
                (3 * pad + bar_w + label_w, ticks)
            }
        };
        Self {
            scale,
            pad,
            title_h,
            legend_w,
            ticks,
        }
    }
}

/// Lights in view space (x right, y up, z towards the eye).
const KEY: [f32; 3] = [-0.40, 0.55, 0.73];
const FILL: [f32; 3] = [0.60, -0.25, 0.76];
const AMBIENT: f32 = 0.16;
const SHININESS: i32 = 32;

impl Renderer {
    /// A renderer with empty buffers.
    pub fn new() -> Self {
        Self {
            depth: Vec::new(),
            screen: Vec::new(),
            normals: Vec::new(),
            tvals: Vec::new(),
            image: Image::new(1, 1, [0; 3]).expect("1x1 is a valid size"),
        }
    }

    /// Renders `surface` and returns the image (valid until the next call). `framing` fixes
    /// the region shown (e.g. [`Framing::union`] over all frames of an animation, so that the
    /// scale is the same in every frame); `None` frames this surface's own finite vertices.
    /// Triangles with a non-finite vertex are skipped.
    pub fn render(
        &mut self,
        surface: &Surface<'_>,
        opts: &RenderOptions,
        framing: Option<&Framing>,
    ) -> Result<&Image, RenderError> {
        self.render_with_props(surface, &[], opts, framing)
    }

    /// Renders `surface` and the rigid objects `props` (a sphere, a floor: [`Prop`]), each
    /// drawn through its triangulation ([`Prop::mesh`]) in its own colour, shaded like the
    /// surface and depth-tested against it. `framing` as in [`Renderer::render`]; `None` frames
    /// the surface alone (a large floor then reaches beyond the picture; include a sphere in
    /// the framing with [`Framing::union`] to keep it in view). Both sides of a prop's
    /// triangles are drawn.
    pub fn render_with_props(
        &mut self,
        surface: &Surface<'_>,
        props: &[Prop],
        opts: &RenderOptions,
        framing: Option<&Framing>,
    ) -> Result<&Image, RenderError> {
        check_size(opts.width, opts.height)?;
        camera::validate(&opts.camera)?;
        let n = surface.validate()?;
        if let Some(cs) = &opts.color_scale {
            cs.validate()?;
        }
        for prop in props {
            prop.validate()?;
        }
        let framing = match framing {
            Some(f) => {
                if !(f.radius.is_finite()
                    && f.radius > 0.0
                    && f.center.iter().all(|c| c.is_finite()))
                {
                    return Err(RenderError::invalid(
                        "framing",
                        format!("{f:?}"),
                        "needs a finite centre and a positive radius",
                    ));
                }
                *f
            }
            None => Framing::of_points(surface.positions).ok_or(RenderError::NothingToFrame)?,
        };
        let layout = Layout::new(opts);
        let (w, h) = (opts.width as i64, opts.height as i64);
        let (vx0, vy0) = (0i64, layout.title_h);
        let (vw, vh) = (w - layout.legend_w, h - layout.title_h);
        if vw < 8 || vh < 8 {
            return Err(RenderError::invalid(
                "width x height",
                format!("{}x{}", opts.width, opts.height),
                "too small for the title and legend; use a larger image",
            ));
        }
        self.image.reset(opts.width, opts.height, opts.background);
        self.depth.clear();
        self.depth
            .resize((opts.width * opts.height) as usize, f32::NEG_INFINITY);

        let view = ViewTransform::new(&opts.camera, &framing);
        let (cx, cy) = (vx0 as f64 + 0.5 * vw as f64, vy0 as f64 + 0.5 * vh as f64);
        let r = framing.radius;
        let persp = match opts.camera.projection {
            Projection::Perspective { fov_y_deg } => {
                let half_y = 0.5 * fov_y_deg.to_radians();
                let half_x = (half_y.tan() * vw as f64 / vh as f64).atan();
                let dist = 1.04 * r / half_y.min(half_x).sin();
                let focal = 0.5 * vh as f64 / half_y.tan();
                Some((dist, focal))
            }
            Projection::Orthographic => None,
        };
        let projector = Projector {
            view: &view,
            center: (cx, cy),
            persp,
            ortho_scale: 0.96 * 0.5 * (vw.min(vh) as f64) / r,
        };
        let key = normalize(KEY);
        let shade = Shade {
            key,
            fill: normalize(FILL),
            half: normalize([key[0], key[1], key[2] + 1.0]),
            spec: opts.specular.clamp(0.0, 1.0),
            width: opts.width as usize,
            clip: (
                vx0 as f32,
                (vx0 + vw - 1) as f32,
                vy0 as f32,
                (vy0 + vh - 1) as f32,
            ),
        };

        // The surface: projected vertices, vertex normals (balloon_mesh::fields) in view
        // space, colour coordinates.
        projector.project(surface.positions, &mut self.screen);
        debug_assert_eq!(self.screen.len(), n);
        view_normals(
            &view,
            opts.smooth,
            surface.positions,
            surface.triangles,
            &mut self.normals,
        )?;
        self.tvals.clear();
        let lut = opts.color_scale.as_ref().map(|cs| cs.map.table());
        if let (Some(cs), Some(s)) = (&opts.color_scale, surface.scalars) {
            self.tvals.extend(s.iter().map(|&v| {
                let t = cs.normalize(v);
                if t.is_nan() { 0.0 } else { t as f32 }
            }));
        }
        let mut target = Target {
            depth: &mut self.depth,
            image: &mut self.image,
        };
        target.draw(
            &Mesh {
                positions: surface.positions,
                triangles: surface.triangles,
                screen: &self.screen,
                normals: &self.normals,
                tvals: &self.tvals,
            },
            &Paint {
                base: opts.base_color.map(|c| c as f32 / 255.0),
                lut: lut.as_ref(),
                cull: opts.cull_back_faces,
            },
            &view,
            &shade,
        );
        // The props, in their own colours.
        for prop in props {
            let (x, t) = prop.mesh()?;
            projector.project(&x, &mut self.screen);
            view_normals(&view, opts.smooth, &x, &t, &mut self.normals)?;
            target.draw(
                &Mesh {
                    positions: &x,
                    triangles: &t,
                    screen: &self.screen,
                    normals: &self.normals,
                    tvals: &[],
                },
                &Paint {
                    base: prop.color().map(|c| c as f32 / 255.0),
                    lut: None,
                    cull: false,
                },
                &view,
                &shade,
            );
        }
        self.draw_overlays(opts, &layout);
        Ok(&self.image)
    }

    fn draw_overlays(&mut self, opts: &RenderOptions, layout: &Layout) {
        let bg = opts.background;
        let luma = 0.299 * bg[0] as f32 + 0.587 * bg[1] as f32 + 0.114 * bg[2] as f32;
        let ink = if luma > 128.0 {
            [20, 20, 24]
        } else {
            [235, 235, 235]
        };
        let s = layout.scale;
        let th = (GLYPH_HEIGHT * s) as i64;
        let (w, h) = (opts.width as i64, opts.height as i64);
        let pad = layout.pad;
        let img = &mut self.image;
        if let Some(title) = &opts.title {
            font::draw_text(img, pad, pad, title, s, ink);
        }
        if let Some(cs) = &opts.color_scale {
            let x0 = w - layout.legend_w + pad;
            let bar_w = 10 * s as i64;
            // Caption above the bar, right-aligned to the image edge.
            let cap_w = font::text_width(&cs.label, s) as i64;
            let cap_y = layout.title_h + pad;
            font::draw_text(img, (w - pad - cap_w).max(pad), cap_y, &cs.label, s, ink);
            let y0 = cap_y + th + 2 * pad;
            let y1 = h - pad - th / 2;
            if y1 - y0 < 4 {
                return;
            }
            for y in y0..=y1 {
                let t = 1.0 - (y - y0) as f64 / (y1 - y0) as f64;
                let col = cs.map.eval_u8(t);
                img.fill_rect(x0, y, bar_w, 1, col);
            }
            // Frame.
            img.fill_rect(x0 - 1, y0 - 1, bar_w + 2, 1, ink);
            img.fill_rect(x0 - 1, y1 + 1, bar_w + 2, 1, ink);
            img.fill_rect(x0 - 1, y0 - 1, 1, y1 - y0 + 3, ink);
            img.fill_rect(x0 + bar_w, y0 - 1, 1, y1 - y0 + 3, ink);
            for (t, label) in &layout.ticks {
                let y = y1 - (t * (y1 - y0) as f64).round() as i64;
                img.fill_rect(x0 + bar_w, y, pad / 2 + 1, 1, ink);
                font::draw_text(img, x0 + bar_w + pad, y - th / 2, label, s, ink);
            }
        }
    }
}

#[inline]
fn dot3(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
fn normalize(a: [f32; 3]) -> [f32; 3] {
    let l = dot3(a, a).sqrt();
    if l > 0.0 { a.map(|q| q / l) } else { a }
}

/// World to screen: pixel x, pixel y and a depth that grows towards the eye (`1 / z` with
/// perspective, the view-space z orthographic).
struct Projector<'a> {
    view: &'a ViewTransform,
    center: (f64, f64),
    persp: Option<(f64, f64)>,
    ortho_scale: f64,
}

impl Projector<'_> {
    /// Projects flat positions into `screen` (cleared first); a vertex behind the eye is NaN.
    fn project(&self, positions: &[f64], screen: &mut Vec<[f32; 3]>) {
        let (cx, cy) = self.center;
        screen.clear();
        screen.extend(positions.chunks_exact(3).map(|p| {
            let v = self.view.apply([p[0], p[1], p[2]]);
            match self.persp {
                Some((dist, focal)) => {
                    let z = dist - v[2];
                    if z.is_nan() || z <= 1e-6 * dist {
                        return [f32::NAN; 3];
                    }
                    [
                        (cx + focal * v[0] / z) as f32,
                        (cy - focal * v[1] / z) as f32,
                        (1.0 / z) as f32,
                    ]
                }
                None => [
                    (cx + self.ortho_scale * v[0]) as f32,
                    (cy - self.ortho_scale * v[1]) as f32,
                    v[2] as f32,
                ],
            }
        }));
    }
}

/// Vertex normals in view space into `out` (cleared; left empty for flat shading or no
/// triangles).
fn view_normals(
    view: &ViewTransform,
    smooth: bool,
    positions: &[f64],
    triangles: &[[usize; 3]],
    out: &mut Vec<[f32; 3]>,
) -> Result<(), RenderError> {
    out.clear();
    if smooth && !triangles.is_empty() {
        let nrm = balloon_mesh::fields::vertex_normals(positions, triangles)?;
        out.extend(nrm.chunks_exact(3).map(|c| {
            let v = view.rotate([c[0], c[1], c[2]]);
            [v[0] as f32, v[1] as f32, v[2] as f32]
        }));
    }
    Ok(())
}

/// A projected triangle mesh: world positions, triangles, screen positions, view-space vertex
/// normals (empty: flat shading) and colour coordinates in `[0, 1]` (empty: uncoloured).
struct Mesh<'a> {
    positions: &'a [f64],
    triangles: &'a [[usize; 3]],
    screen: &'a [[f32; 3]],
    normals: &'a [[f32; 3]],
    tvals: &'a [f32],
}

/// How a mesh is coloured: its base colour (linear 0..1 channels of the sRGB bytes), the colour
/// table for its `tvals`, and whether back faces are skipped.
struct Paint<'a> {
    base: [f32; 3],
    lut: Option<&'a [[f32; 3]; 256]>,
    cull: bool,
}

/// Lighting and the viewport.
struct Shade {
    key: [f32; 3],
    fill: [f32; 3],
    half: [f32; 3],
    spec: f32,
    width: usize,
    /// Viewport pixel bounds: x min, x max, y min, y max.
    clip: (f32, f32, f32, f32),
}

/// The depth buffer and the image being drawn into.
struct Target<'a> {
    depth: &'a mut [f32],
    image: &'a mut Image,
}

impl Target<'_> {
    /// Rasterises `mesh` with the z-buffer: barycentric interpolation of depth, normal and
    /// colour coordinate per pixel, Lambert (key and fill light) plus a Blinn-Phong highlight.
    fn draw(&mut self, mesh: &Mesh<'_>, paint: &Paint<'_>, view: &ViewTransform, sh: &Shade) {
        let (xmin_vp, xmax_vp, ymin_vp, ymax_vp) = sh.clip;
        let width = sh.width;
        for tri in mesh.triangles {
            let [a, b, c] = *tri;
            let (p0, p1, p2) = (mesh.screen[a], mesh.screen[b], mesh.screen[c]);
            if !(p0.iter().chain(&p1).chain(&p2).all(|v| v.is_finite())) {
                continue;
            }
            let area = (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p2[0] - p0[0]) * (p1[1] - p0[1]);
            if !area.is_finite() || area.abs() < 1e-9 {
                continue;
            }
            // Screen y points down, so a counter-clockwise (outward, towards the eye) triangle
            // has negative signed area here.
            let front = area < 0.0;
            if !front && paint.cull {
                continue;
            }
            let sign = if front { 1.0f32 } else { -1.0 };
            // Face normal in view space for flat shading and as a fallback.
            let face_n = {
                let pa = &mesh.positions[3 * a..3 * a + 3];
                let pb = &mesh.positions[3 * b..3 * b + 3];
                let pc = &mesh.positions[3 * c..3 * c + 3];
                let e1 = [pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]];
                let e2 = [pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]];
                let v = view.rotate(camera::cross(e1, e2));
                let nn = normalize([v[0] as f32, v[1] as f32, v[2] as f32]);
                nn.map(|q| q * sign)
            };
            let (n0, n1, n2) = if mesh.normals.is_empty() {
                (face_n, face_n, face_n)
            } else {
                let f = |v: [f32; 3]| v.map(|q| q * sign);
                (f(mesh.normals[a]), f(mesh.normals[b]), f(mesh.normals[c]))
            };
            let colored = !mesh.tvals.is_empty();
            let (t0, t1, t2) = if colored {
                (mesh.tvals[a], mesh.tvals[b], mesh.tvals[c])
            } else {
                (0.0, 0.0, 0.0)
            };
            let bx0 = p0[0].min(p1[0]).min(p2[0]).floor().max(xmin_vp);
            let bx1 = p0[0].max(p1[0]).max(p2[0]).ceil().min(xmax_vp);
            let by0 = p0[1].min(p1[1]).min(p2[1]).floor().max(ymin_vp);
            let by1 = p0[1].max(p1[1]).max(p2[1]).ceil().min(ymax_vp);
            if bx0 > bx1 || by0 > by1 {
                continue;
            }
            // Barycentric weights as affine functions of the pixel centre: w_i = a_i x + b_i y + c_i.
            let inv = 1.0 / area;
            let edge = |q: [f32; 3], r: [f32; 3]| {
                let ea = (q[1] - r[1]) * inv;
                let eb = (r[0] - q[0]) * inv;
                let ec = (q[0] * r[1] - q[1] * r[0]) * inv;
                (ea, eb, ec)
            };
            let (a0, b0, c0) = edge(p1, p2);
            let (a1, b1, c1) = edge(p2, p0);
            let (a2, b2, c2) = edge(p0, p1);
            let eps = -1e-5f32;
            for py in by0 as i64..=by1 as i64 {
                let sy = py as f32 + 0.5;
                let row = py as usize * width;
                let sx0 = bx0 + 0.5;
                let mut w0 = a0 * sx0 + b0 * sy + c0;
                let mut w1 = a1 * sx0 + b1 * sy + c1;
                let mut w2 = a2 * sx0 + b2 * sy + c2;
                for px in bx0 as usize..=bx1 as usize {
                    if w0 >= eps && w1 >= eps && w2 >= eps {
                        let depth = w0 * p0[2] + w1 * p1[2] + w2 * p2[2];
                        let idx = row + px;
                        if depth > self.depth[idx] {
                            self.depth[idx] = depth;
                            let mut nrm = [
                                w0 * n0[0] + w1 * n1[0] + w2 * n2[0],
                                w0 * n0[1] + w1 * n1[1] + w2 * n2[1],
                                w0 * n0[2] + w1 * n1[2] + w2 * n2[2],
                            ];
                            let l2 = nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2];
                            if l2 > 1e-12 {
                                let il = 1.0 / l2.sqrt();
                                nrm = nrm.map(|q| q * il);
                            } else {
                                nrm = face_n;
                            }
                            let albedo = match paint.lut {
                                Some(lut) if colored => {
                                    let t = (w0 * t0 + w1 * t1 + w2 * t2).clamp(0.0, 1.0);
                                    lut[(t * 255.0 + 0.5) as usize]
                                }
                                _ => paint.base,
                            };
                            let kd = dot3(nrm, sh.key).max(0.0);
                            let fd = dot3(nrm, sh.fill).max(0.0);
                            let diffuse = AMBIENT + 0.72 * kd + 0.22 * fd;
                            let hl = dot3(nrm, sh.half).max(0.0);
                            let highlight = if kd > 0.0 {
                                sh.spec * hl.powi(SHININESS)
                            } else {
                                0.0
                            };
                            let o = 3 * idx;
                            let px_rgb = &mut self.image.pixels_mut()[o..o + 3];
                            for k in 0..3 {
                                let v = albedo[k] * diffuse + highlight;
                                px_rgb[k] = (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
                            }
                        }
                    }
                    w0 += a0;
                    w1 += a1;
                    w2 += a2;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ColorScale, UpAxis};
    use std::collections::HashSet;

    fn sphere(sub: u32) -> (Vec<f64>, Vec<[usize; 3]>) {
        let m = balloon_mesh::generate::icosphere(1.0, sub).unwrap();
        (m.positions_flat(), m.triangles)
    }

    fn covered(img: &Image, bg: [u8; 3]) -> usize {
        img.pixels().chunks(3).filter(|p| p != &bg).count()
    }

    #[test]
    fn a_sphere_covers_a_disc_of_the_expected_size() {
        let (x, t) = sphere(3);
        let mut opts = RenderOptions::new(200, 200);
        opts.camera.projection = Projection::Orthographic;
        let mut r = Renderer::new();
        let img = r
            .render(&Surface::new(&x, &t), &opts, None)
            .unwrap()
            .clone();
        // Orthographic: radius 0.96 * 100 px, so area pi * 96^2 (minus polygon facets).
        let expect = std::f64::consts::PI * 96.0f64.powi(2);
        let got = covered(&img, opts.background) as f64;
        assert!((got / expect - 1.0).abs() < 0.03, "{got} vs {expect}");
        // Centre pixel is the body, corners are background.
        assert_ne!(img.get(100, 100), Some(opts.background));
        assert_eq!(img.get(1, 1), Some(opts.background));
        // Shading varies: many distinct colours.
        let colours: HashSet<&[u8]> = img.pixels().chunks(3).collect();
        assert!(colours.len() > 50, "{} colours", colours.len());
        // The lit side (upper left, towards KEY) is brighter than the lower right.
        let lum = |p: [u8; 3]| p.iter().map(|&c| c as u32).sum::<u32>();
        assert!(lum(img.get(70, 70).unwrap()) > lum(img.get(135, 135).unwrap()));
    }

    #[test]
    fn the_nearer_surface_wins_the_depth_test() {
        // Two parallel squares facing the eye (+y eye side is -y for UpAxis::Z at azimuth 0):
        // red at y = -1 (near), blue at y = +1 (far), drawn far-last.
        let quad = |y: f64| vec![-1.0, y, -1.0, 1.0, y, -1.0, 1.0, y, 1.0, -1.0, y, 1.0];
        for projection in [
            Projection::Orthographic,
            Projection::Perspective { fov_y_deg: 40.0 },
        ] {
            let mut x = quad(-1.0);
            x.extend(quad(1.0));
            let t = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
            let s = [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0];
            let opts = RenderOptions {
                camera: Camera {
                    azimuth_deg: 0.0,
                    elevation_deg: 0.0,
                    up: UpAxis::Z,
                    projection,
                },
                color_scale: Some(ColorScale::new(0.0, 1.0, "s")),
                specular: 0.0,
                ..RenderOptions::new(100, 100)
            };
            let mut r = Renderer::new();
            let img = r
                .render(&Surface::new(&x, &t).with_scalars(&s), &opts, None)
                .unwrap();
            // The legend takes the right part; the square is centred in the rest.
            let vw = 100 - Layout::new(&opts).legend_w as u32;
            let p = img.get(vw / 2, 50).unwrap();
            // Near square has scalar 0: viridis' dark violet, blue > green.
            assert!(
                p[2] > p[1],
                "{projection:?}: got {p:?}, expected the near (violet) square"
            );
        }
    }

    #[test]
    fn legend_and_title_are_drawn_and_bad_input_is_reported() {
        let (x, t) = sphere(2);
        let s: Vec<f64> = x.chunks(3).map(|p| p[2]).collect();
        let opts = RenderOptions {
            color_scale: Some(ColorScale::from_values(&s, "height (m)")),
            title: Some("step 10".into()),
            ..RenderOptions::new(320, 240)
        };
        let mut r = Renderer::new();
        let img = r
            .render(&Surface::new(&x, &t).with_scalars(&s), &opts, None)
            .unwrap()
            .clone();
        let lay = Layout::new(&opts);
        // Legend bar: a column inside the bar, top is yellow-ish, bottom violet.
        let bx = (320 - lay.legend_w + lay.pad + 3) as u32;
        let top = img.get(bx, 60).unwrap();
        let bottom = img.get(bx, 225).unwrap();
        assert!(top[1] > 150 && bottom[1] < 100, "{top:?} {bottom:?}");
        // Title strip has ink.
        let ink = (0..100)
            .any(|xp| (0..lay.title_h as u32).any(|yp| img.get(xp, yp) == Some([20, 20, 24])));
        assert!(ink);
        // Errors.
        let e = r
            .render(&Surface::new(&x, &t).with_scalars(&s[1..]), &opts, None)
            .unwrap_err();
        assert!(e.to_string().contains("scalars"), "{e}");
        let e = r
            .render(&Surface::new(&x, &[[0, 1, 99999]]), &opts, None)
            .unwrap_err();
        assert!(e.to_string().contains("99999"), "{e}");
        let e = r
            .render(&Surface::new(&x, &t), &RenderOptions::new(12, 12), None)
            .map(|_| ());
        assert!(e.is_ok(), "no legend, no title: a tiny image is fine");
        let small = RenderOptions {
            width: 30,
            height: 20,
            ..opts.clone()
        };
        assert!(r.render(&Surface::new(&x, &t), &small, None).is_err());
        let nan = vec![f64::NAN; 9];
        assert!(
            r.render(&Surface::new(&nan, &[[0, 1, 2]]), &opts, None)
                .is_err()
        );
    }

    #[test]
    fn culling_back_faces_does_not_change_a_closed_surface() {
        let (x, t) = sphere(3);
        let opts = RenderOptions::new(120, 90);
        let mut r = Renderer::new();
        let both = r
            .render(&Surface::new(&x, &t), &opts, None)
            .unwrap()
            .clone();
        let culled = RenderOptions {
            cull_back_faces: true,
            ..opts.clone()
        };
        let front = r
            .render(&Surface::new(&x, &t), &culled, None)
            .unwrap()
            .clone();
        // Identical except possibly a few silhouette pixels where a back face touches the edge.
        let differ = both
            .pixels()
            .chunks(3)
            .zip(front.pixels().chunks(3))
            .filter(|(a, b)| a != b)
            .count();
        let body = covered(&both, opts.background);
        assert!(
            body > 1000 && differ * 100 < body,
            "{differ} of {body} pixels differ"
        );
        // A lone triangle facing away (normal +y, the eye is at -y with z up) is drawn only
        // without culling.
        let tri = [-1.0, 0.0, -1.0, 0.0, 0.0, 1.0, 1.0, 0.0, -1.0];
        let away = [[0, 1, 2]];
        let cam = Camera {
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            ..Camera::default()
        };
        let o = RenderOptions {
            camera: cam,
            ..opts.clone()
        };
        let shown = covered(
            r.render(&Surface::new(&tri, &away), &o, None).unwrap(),
            o.background,
        );
        let c = RenderOptions {
            cull_back_faces: true,
            ..o.clone()
        };
        let hidden = covered(
            r.render(&Surface::new(&tri, &away), &c, None).unwrap(),
            c.background,
        );
        assert!(shown > 1000 && hidden == 0, "{shown} / {hidden}");
        let toward = [[0, 2, 1]];
        let front = covered(
            r.render(&Surface::new(&tri, &toward), &c, None).unwrap(),
            c.background,
        );
        assert_eq!(
            front, shown,
            "a triangle facing the eye is drawn with culling"
        );
    }

    #[test]
    fn a_sphere_prop_is_drawn_where_it_projects_and_the_floor_behind_the_body() {
        let (x, t) = sphere(3);
        let ball = Prop::sphere([0.3, 0.2, 2.0], 0.5);
        let floor = Prop::floor([0.0, 0.0, -1.0], [0.0, 0.0, 1.0], 3.0);
        for projection in [
            Projection::Orthographic,
            Projection::Perspective { fov_y_deg: 30.0 },
        ] {
            let opts = RenderOptions {
                camera: Camera {
                    projection,
                    ..Camera::default()
                },
                ..RenderOptions::new(240, 240)
            };
            let (bx, _) = ball.mesh().unwrap();
            let framing = Framing::of_points(&x)
                .unwrap()
                .union(&Framing::of_points(&bx).unwrap());
            let mut r = Renderer::new();
            let plain = r
                .render(&Surface::new(&x, &t), &opts, Some(&framing))
                .unwrap()
                .clone();
            let with = r
                .render_with_props(&Surface::new(&x, &t), &[ball], &opts, Some(&framing))
                .unwrap()
                .clone();
            // The changed pixels form the sphere's projected disc: its centre and area,
            // computed here from the camera independently of the triangulation.
            let (mut n, mut sx, mut sy) = (0usize, 0.0, 0.0);
            for py in 0..240 {
                for px in 0..240 {
                    if plain.get(px, py) != with.get(px, py) {
                        assert_eq!(with.get(px, py).map(|p| p[2] > p[0]), Some(true));
                        n += 1;
                        sx += px as f64 + 0.5;
                        sy += py as f64 + 0.5;
                    }
                }
            }
            let layout = Layout::new(&opts);
            let (vw, vh) = (240 - layout.legend_w, 240 - layout.title_h);
            let view = ViewTransform::new(&opts.camera, &framing);
            let c = view.apply([0.3, 0.2, 2.0]);
            let (cx, cy) = (0.5 * vw as f64, layout.title_h as f64 + 0.5 * vh as f64);
            let (px, py, rad) = match projection {
                Projection::Orthographic => {
                    let k = 0.96 * 0.5 * vw.min(vh) as f64 / framing.radius;
                    (cx + k * c[0], cy - k * c[1], k * 0.5)
                }
                Projection::Perspective { fov_y_deg } => {
                    let half = 0.5 * fov_y_deg.to_radians();
                    let dist = 1.04 * framing.radius / half.sin();
                    let focal = 0.5 * vh as f64 / half.tan();
                    let z = dist - c[2];
                    // A sphere seen from distance z: silhouette radius about f r / z.
                    (
                        cx + focal * c[0] / z,
                        cy - focal * c[1] / z,
                        focal * 0.5 / z,
                    )
                }
            };
            let disc = std::f64::consts::PI * rad * rad;
            let (mx, my) = (sx / n as f64, sy / n as f64);
            assert!(
                (n as f64 / disc - 1.0).abs() < 0.06,
                "{projection:?}: {n} pixels vs disc {disc}"
            );
            assert!(
                (mx - px).abs() < 1.0 && (my - py).abs() < 1.0,
                "{projection:?}: centre ({mx}, {my}) vs ({px}, {py})"
            );
            // The floor below the body fills background pixels and never covers the body
            // (the body is in front of it everywhere it projects).
            let floored = r
                .render_with_props(&Surface::new(&x, &t), &[floor], &opts, Some(&framing))
                .unwrap()
                .clone();
            let (mut bg_changed, mut body_changed) = (0, 0);
            for (a, b) in plain.pixels().chunks(3).zip(floored.pixels().chunks(3)) {
                if a != b {
                    if a == opts.background {
                        bg_changed += 1;
                    } else {
                        body_changed += 1;
                    }
                }
            }
            assert!(bg_changed > 5000, "{projection:?}: floor {bg_changed} px");
            assert_eq!(body_changed, 0, "{projection:?}");
        }
        // A bad prop is an error, not a picture.
        let bad = Prop::sphere([0.0; 3], -1.0);
        let e = Renderer::new()
            .render_with_props(
                &Surface::new(&x, &t),
                &[bad],
                &RenderOptions::new(64, 64),
                None,
            )
            .map(|_| ())
            .unwrap_err();
        assert!(e.to_string().contains("sphere"), "{e}");
    }

    #[test]
    fn a_common_framing_shows_growth() {
        let (x, t) = sphere(2);
        let big: Vec<f64> = x.iter().map(|c| 2.0 * c).collect();
        let f = Framing::of_points(&x)
            .unwrap()
            .union(&Framing::of_points(&big).unwrap());
        let opts = RenderOptions::new(160, 160);
        let mut r = Renderer::new();
        let small_px = covered(
            r.render(&Surface::new(&x, &t), &opts, Some(&f)).unwrap(),
            opts.background,
        );
        let big_px = covered(
            r.render(&Surface::new(&big, &t), &opts, Some(&f)).unwrap(),
            opts.background,
        );
        let ratio = big_px as f64 / small_px as f64;
        assert!(ratio > 3.0 && ratio < 5.5, "area ratio {ratio}");
    }
}
