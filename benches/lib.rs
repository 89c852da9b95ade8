//! Shared fixtures of the criterion benchmarks in `benches/`.

use balloon_mesh::TriMesh;
use balloon_mesh::generate::teddy::{TeddyParams, teddy};

/// The built-in teddy with about `target` vertices (the vertex count grows like the square of
/// the mesher resolution; the closest of a few resolutions is taken).
pub fn teddy_with_about(target: usize) -> TriMesh {
    let base = TeddyParams::default();
    let guess = (base.resolution as f64 * (target as f64 / 8000.0).sqrt()).round() as usize;
    let mut best: Option<TriMesh> = None;
    for res in guess.saturating_sub(2).max(8)..=guess + 2 {
        let m = teddy(&TeddyParams {
            resolution: res,
            ..base
        })
        .expect("built-in teddy");
        let better = best
            .as_ref()
            .is_none_or(|b| m.num_vertices().abs_diff(target) < b.num_vertices().abs_diff(target));
        if better {
            best = Some(m);
        }
    }
    best.expect("at least one resolution")
}

/// The built-in teddy at a resolution close to the paper's 11090-vertex Teddy (Wang et al. 2015, Table 1).
pub fn teddy_about_11k() -> TriMesh {
    teddy_with_about(11_090)
}
