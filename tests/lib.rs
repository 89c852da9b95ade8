//! Cross-crate integration tests live in `integration/`; this library offers paths and
//! measurements that do not go through the quantity under test (those of `balloon-measure`,
//! re-exported).

pub use balloon_measure::*;
use std::path::PathBuf;

/// The shared real meshes folder (`../shared/meshes` beside the repository), if present.
///
/// # Panics
/// When it is absent and the `CI` environment variable is set: in CI the tests on the real
/// meshes must run, not skip.
pub fn shared_meshes_dir() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/meshes");
    if dir.is_dir() {
        return Some(dir);
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "CI is set but {} is missing: the tests on the real meshes would be skipped",
        dir.display()
    );
    None
}
