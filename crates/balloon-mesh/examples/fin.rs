//! Writes a finned ellipsoid (a test shape with a thin flat part) to a mesh file.
//!
//! ```text
//! cargo run --release -p balloon-mesh --example fin -- OUT.obj [FIN_THICKNESS CELL_SIZE]
//! ```
//! Lengths in metres; the defaults (0.006 and 0.003) are those of `builtin:fin`.

use balloon_mesh::generate::{FinParams, finned_ellipsoid};
use balloon_mesh::io::write_mesh;
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(out) = args.first() else {
        return Err("usage: fin OUT.obj [FIN_THICKNESS CELL_SIZE]".into());
    };
    let mut q = FinParams::default();
    if let Some(t) = args.get(1) {
        q.fin_thickness = t.parse().map_err(|e| format!("FIN_THICKNESS `{t}`: {e}"))?;
    }
    if let Some(h) = args.get(2) {
        q.cell_size = h.parse().map_err(|e| format!("CELL_SIZE `{h}`: {e}"))?;
    }
    let mesh = finned_ellipsoid(&q)?;
    write_mesh(Path::new(out), &mesh)?;
    println!("{out}: {} vertices", mesh.vertices.len());
    Ok(())
}
