//! Cross-crate integration tests live in `integration/`; this library only offers paths.

use std::path::PathBuf;

/// The shared real meshes folder (`../shared/meshes` beside the repository), if present.
pub fn shared_meshes_dir() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/meshes");
    dir.is_dir().then_some(dir)
}
