//! Set-up shared by the viewer's scenario, drag and saved-scenario tests.

use std::path::PathBuf;

/// A folder holding a coarse sphere `sphere.obj` (radius 0.1 m, 162 vertices), and its path.
pub(super) fn sphere_dir() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let sphere = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
    let obj = dir.path().join("sphere.obj");
    balloon_mesh::io::write_obj(&obj, &sphere).unwrap();
    (dir, obj)
}

/// A folder with the coarse sphere ([`sphere_dir`]) and `scenario.toml` of `text`, and the
/// scenario's path.
pub(super) fn scenario_dir(text: &str) -> (tempfile::TempDir, PathBuf) {
    let (dir, _) = sphere_dir();
    let path = dir.path().join("scenario.toml");
    std::fs::write(&path, text).unwrap();
    (dir, path)
}

/// The largest difference between two flat position lists of the same length.
pub(super) fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}
