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

/// The built-in teddy at a resolution close to the paper's 11090-vertex Teddy (Wang et al. 2015,
/// Table 1); in test mode (`cargo bench -- --test`, which runs every bench once to check that
/// it still works, as CI does) a teddy of about 1500 vertices, so the check exercises the same
/// code without the large model's set-up cost.
pub fn teddy_about_11k() -> TriMesh {
    teddy_with_about(if test_mode() { 1_500 } else { 11_090 })
}

/// Whether criterion runs in test mode (`--test`: each bench once, nothing measured). Benches
/// use it to shrink their set-up, never their measured workload in a real run.
pub fn test_mode() -> bool {
    std::env::args().any(|a| a == "--test")
}
