//! Cross-crate integration tests live in `integration/`; this library only offers paths.

use std::path::PathBuf;

/// The shared real meshes folder (`../shared/meshes` beside the repository), if present.
pub fn shared_meshes_dir() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/meshes");
    dir.is_dir().then_some(dir)
}

/// Path of the `balloon` binary built by cargo for the integration tests.
pub fn balloon_bin() -> PathBuf {
    let mut p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target");
    if let Ok(t) = std::env::var("CARGO_TARGET_DIR") {
        p = PathBuf::from(t);
    }
    p.join(if cfg!(debug_assertions) {
        "debug"
    } else {
        "release"
    })
    .join("balloon")
}
