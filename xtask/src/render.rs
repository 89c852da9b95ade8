//! A small software renderer for the "before / after" figures: orthographic camera, z-buffer
//! triangle rasteriser, Lambert shading with a fixed light. Meshes are flat position arrays
//! (`3N`, m) and outward-oriented triangles.

use nalgebra::{Rotation3, Vector3};

/// A view: yaw about the +y (up) axis, then pitch about x, orthographic along -z.
#[derive(Clone, Copy, Debug)]
pub struct View {
    /// Rotation about +y, radians.
    pub yaw: f64,
    /// Rotation about +x, radians.
    pub pitch: f64,
}

fn transform(view: View, x: &[f64]) -> Vec<Vector3<f64>> {
    let r = Rotation3::from_axis_angle(&Vector3::x_axis(), view.pitch)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), view.yaw);
    x.chunks_exact(3)
        .map(|p| r * Vector3::new(p[0], p[1], p[2]))
        .collect()
}

/// Renders the meshes side by side into one `width x height` RGB image (one panel each, same
/// scale in every panel, so growth is visible). Returns the image bytes.
pub fn render_panels(
    meshes: &[(&[f64], &[[usize; 3]])],
    view: View,
    width: u32,
    height: u32,
    base: [f64; 3],
) -> Vec<u8> {
    let (w, h) = (width as usize, height as usize);
    let mut rgb = vec![255u8; 3 * w * h];
    if meshes.is_empty() {
        return rgb;
    }
    let panel_w = w / meshes.len();
    let views: Vec<Vec<Vector3<f64>>> = meshes.iter().map(|(x, _)| transform(view, x)).collect();
    // Common scale: the largest extent over all panels fills 90% of a panel.
    let mut extent: f64 = 1e-12;
    let mut centres = Vec::new();
    for v in &views {
        let (mut lo, mut hi) = (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        );
        for p in v {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        extent = extent
            .max((hi.x - lo.x) / panel_w as f64)
            .max((hi.y - lo.y) / h as f64);
        centres.push(0.5 * (lo + hi));
    }
    let scale = 0.9 / extent;
    let light = Vector3::new(0.35, 0.55, 1.0).normalize();
    let mut depth = vec![f64::NEG_INFINITY; w * h];
    for (k, ((_, tris), v)) in meshes.iter().zip(&views).enumerate() {
        let c = centres[k];
        let ox = (k * panel_w + panel_w / 2) as f64;
        let oy = h as f64 / 2.0;
        let screen: Vec<(f64, f64, f64)> = v
            .iter()
            .map(|p| (ox + (p.x - c.x) * scale, oy - (p.y - c.y) * scale, p.z))
            .collect();
        for t in tris.iter() {
            let (a, b, cc) = (v[t[0]], v[t[1]], v[t[2]]);
            let n = (b - a).cross(&(cc - a));
            let nn = n.norm();
            if nn == 0.0 || n.z <= 0.0 {
                continue; // degenerate or facing away
            }
            let lambert = (n / nn).dot(&light).max(0.0);
            let shade = 0.25 + 0.75 * lambert;
            let col = [
                (base[0] * shade * 255.0).min(255.0) as u8,
                (base[1] * shade * 255.0).min(255.0) as u8,
                (base[2] * shade * 255.0).min(255.0) as u8,
            ];
            let (p0, p1, p2) = (screen[t[0]], screen[t[1]], screen[t[2]]);
            let xmin = p0.0.min(p1.0).min(p2.0).floor().max(0.0) as usize;
            let xmax = (p0.0.max(p1.0).max(p2.0).ceil() as usize).min(w - 1);
            let ymin = p0.1.min(p1.1).min(p2.1).floor().max(0.0) as usize;
            let ymax = (p0.1.max(p1.1).max(p2.1).ceil() as usize).min(h - 1);
            let area = (p1.0 - p0.0) * (p2.1 - p0.1) - (p2.0 - p0.0) * (p1.1 - p0.1);
            if area.abs() < 1e-12 {
                continue;
            }
            for py in ymin..=ymax {
                for px in xmin..=xmax {
                    let (sx, sy) = (px as f64 + 0.5, py as f64 + 0.5);
                    let w0 = ((p1.0 - sx) * (p2.1 - sy) - (p2.0 - sx) * (p1.1 - sy)) / area;
                    let w1 = ((p2.0 - sx) * (p0.1 - sy) - (p0.0 - sx) * (p2.1 - sy)) / area;
                    let w2 = 1.0 - w0 - w1;
                    if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                        continue;
                    }
                    let z = w0 * p0.2 + w1 * p1.2 + w2 * p2.2;
                    let i = py * w + px;
                    if z > depth[i] {
                        depth[i] = z;
                        rgb[3 * i..3 * i + 3].copy_from_slice(&col);
                    }
                }
            }
        }
    }
    rgb
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_front_facing_triangle_covers_the_centre_and_a_back_facing_one_is_culled() {
        // Counter-clockwise seen from +z: normal +z, towards the camera.
        let x = [-1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 0.0, 1.0, 0.0];
        let view = View {
            yaw: 0.0,
            pitch: 0.0,
        };
        let img = render_panels(&[(&x, &[[0, 1, 2]])], view, 20, 20, [1.0, 0.0, 0.0]);
        let c = 3 * (10 * 20 + 10);
        assert!(img[c] > 0 && img[c + 1] == 0, "centre pixel is shaded red");
        let back = render_panels(&[(&x, &[[0, 2, 1]])], view, 20, 20, [1.0, 0.0, 0.0]);
        assert!(back.iter().all(|&b| b == 255), "a back face draws nothing");
    }
}
