//! Times the software renderer: `cargo run --release -p balloon-render --example render_timing
//! [OUT.png]`. Renders a ~10k-triangle sphere coloured by height at 640x480, 50 times, and
//! prints the mean time per frame; with an argument, also writes the last frame as PNG.

use balloon_render::{ColorScale, RenderOptions, Renderer, Surface};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // uv sphere 72 x 72: 72 * 70 * 2 + 2 * 72 = 10 224 triangles.
    let mesh = balloon_mesh::generate::uv_sphere(1.0, 72, 72)?;
    let x = mesh.positions_flat();
    let s: Vec<f64> = x.chunks(3).map(|p| p[2]).collect();
    let opts = RenderOptions {
        color_scale: Some(ColorScale::from_values(&s, "height (m)")),
        title: Some(format!("{} triangles", mesh.num_triangles())),
        ..RenderOptions::new(640, 480)
    };
    let surface = Surface::new(&x, &mesh.triangles).with_scalars(&s);
    let mut r = Renderer::new();
    r.render(&surface, &opts, None)?; // warm-up (allocates the buffers)
    let n = 50;
    let t = Instant::now();
    for _ in 0..n {
        r.render(&surface, &opts, None)?;
    }
    let ms = t.elapsed().as_secs_f64() * 1e3 / n as f64;
    println!(
        "{} triangles, 640x480: {ms:.2} ms per frame (mean of {n})",
        mesh.num_triangles()
    );
    let culled = RenderOptions {
        cull_back_faces: true,
        ..opts.clone()
    };
    let t = Instant::now();
    for _ in 0..n {
        r.render(&surface, &culled, None)?;
    }
    let ms = t.elapsed().as_secs_f64() * 1e3 / n as f64;
    println!("  with back-face culling: {ms:.2} ms per frame (mean of {n})");
    if let Some(path) = std::env::args().nth(1) {
        r.render(&surface, &opts, None)?
            .write_png(std::path::Path::new(&path))?;
        println!("wrote {path}");
    }
    Ok(())
}
