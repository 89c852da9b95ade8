//! "Before / after" figures: a thin layer over `balloon-render` (the same software rasteriser
//! the CLI's `--render` uses) that draws several meshes side by side at one scale. Meshes are
//! flat position arrays (`3N`, m) and outward-oriented triangles.

use balloon_render::{Camera, Framing, Projection, RenderOptions, Renderer, Surface, UpAxis};

/// A view: yaw about the +y (up) axis, then pitch about x (positive: seen from above),
/// orthographic.
#[derive(Clone, Copy, Debug)]
pub struct View {
    /// Rotation of the body about +y, radians.
    pub yaw: f64,
    /// Tilt of the body towards the viewer about +x, radians.
    pub pitch: f64,
}

impl View {
    /// The equivalent `balloon-render` camera: turning the body by `yaw` is orbiting the camera
    /// by `-yaw`; tilting its top towards the viewer is looking from above.
    fn camera(self) -> Camera {
        Camera {
            azimuth_deg: -self.yaw.to_degrees(),
            elevation_deg: self.pitch.to_degrees().clamp(-89.0, 89.0),
            up: UpAxis::Y,
            projection: Projection::Orthographic,
        }
    }
}

/// Renders the meshes side by side into one `width x height` RGB image (one panel each, each
/// centred on its own mesh, the same scale in every panel so growth is visible), smooth-shaded
/// in colour `base` (RGB in `[0, 1]`) on white. Returns the image bytes (`3 * width * height`).
pub fn render_panels(
    meshes: &[(&[f64], &[[usize; 3]])],
    view: View,
    width: u32,
    height: u32,
    base: [f64; 3],
) -> Vec<u8> {
    let (w, h) = (width as usize, height as usize);
    let mut rgb = vec![255u8; 3 * w * h];
    if meshes.is_empty() || w == 0 || h == 0 {
        return rgb;
    }
    let panel_w = (w / meshes.len()).max(1);
    let framings: Vec<Option<Framing>> =
        meshes.iter().map(|(x, _)| Framing::of_points(x)).collect();
    let radius = framings
        .iter()
        .flatten()
        .map(|f| f.radius)
        .fold(0.0f64, f64::max);
    let opts = RenderOptions {
        camera: view.camera(),
        background: [255, 255, 255],
        base_color: base.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8),
        ..RenderOptions::new(panel_w as u32, height)
    };
    let mut renderer = Renderer::new();
    for (k, ((x, tris), framing)) in meshes.iter().zip(&framings).enumerate() {
        let Some(f) = framing else { continue };
        let framing = Framing {
            center: f.center,
            radius,
        };
        // A mesh the renderer rejects (bad indices) leaves its panel blank: figures are best
        // effort, the numbers next to them are what validation checks.
        let Ok(img) = renderer.render(&Surface::new(x, tris), &opts, Some(&framing)) else {
            continue;
        };
        for row in 0..h {
            let src = &img.pixels()[3 * row * panel_w..3 * (row + 1) * panel_w];
            let start = 3 * (row * w + k * panel_w);
            rgb[start..start + 3 * panel_w].copy_from_slice(src);
        }
    }
    rgb
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pixel(img: &[u8], w: usize, x: usize, y: usize) -> [u8; 3] {
        let i = 3 * (y * w + x);
        [img[i], img[i + 1], img[i + 2]]
    }

    #[test]
    fn a_triangle_covers_the_centre_in_its_colour() {
        // Counter-clockwise seen from +z: normal +z, towards the camera.
        let x = [-1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 0.0, 1.0, 0.0];
        let view = View {
            yaw: 0.0,
            pitch: 0.0,
        };
        let img = render_panels(&[(&x, &[[0, 1, 2]])], view, 20, 20, [1.0, 0.0, 0.0]);
        let c = pixel(&img, 20, 10, 10);
        assert!(c[0] > 100 && c[1] < c[0] / 2 && c[2] < c[0] / 2, "{c:?}");
        assert_eq!(
            pixel(&img, 20, 0, 0),
            [255, 255, 255],
            "corner is background"
        );
    }

    #[test]
    fn panels_share_one_scale() {
        let m = balloon::mesh::generate::icosphere(1.0, 2).unwrap();
        let small = m.positions_flat();
        let big: Vec<f64> = small.iter().map(|c| 2.0 * c + 5.0).collect();
        let view = View {
            yaw: 0.3,
            pitch: 0.2,
        };
        let img = render_panels(
            &[(&small, &m.triangles), (&big, &m.triangles)],
            view,
            200,
            100,
            [0.9, 0.3, 0.3],
        );
        let covered = |x0: usize| {
            (0..100)
                .flat_map(|y| (x0..x0 + 100).map(move |x| (x, y)))
                .filter(|&(x, y)| pixel(&img, 200, x, y) != [255, 255, 255])
                .count() as f64
        };
        let ratio = covered(100) / covered(0);
        assert!(
            ratio > 3.0 && ratio < 5.0,
            "area ratio {ratio}, expected about 4"
        );
    }
}
