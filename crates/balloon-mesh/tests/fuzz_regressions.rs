//! Every input under `fuzz/regressions/<reader>/` (crashes, hangs and slow units the fuzzers of
//! `fuzz/` found, and hand-made cases of issue 13) goes through its reader and the checks
//! `balloon mesh info` runs on what it read. A panic or a near-hang fails the test; an error is
//! the expected outcome for most of these files, and a few must be refused.

use balloon_mesh::io::{obj, off, ply, stl, vtp};
use balloon_mesh::{TriMesh, topology::Topology, validate::validate_closed_manifold};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn inputs(reader: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fuzz/regressions")
        .join(reader);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
}

/// Runs `parse` on every regression input of `reader`, then the mesh checks on what it read;
/// each file must finish within 20 s (generous: a debug build on a loaded machine; the slow
/// units these files stand for took minutes or ran out of memory). Returns the outcome per
/// file name (`true` = a mesh was read).
fn run(reader: &str, parse: impl Fn(&[u8], &Path) -> Option<TriMesh>) -> Vec<(String, bool)> {
    let files = inputs(reader);
    assert!(!files.is_empty(), "no regression inputs for {reader}");
    files
        .iter()
        .map(|path| {
            let bytes = std::fs::read(path).unwrap();
            let t0 = Instant::now();
            let mesh = parse(&bytes, path);
            if let Some(m) = &mesh {
                let _ = validate_closed_manifold(m);
                let _ = Topology::new(m);
            }
            let s = t0.elapsed().as_secs_f64();
            assert!(s < 20.0, "{} took {s:.1} s", path.display());
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            (name, mesh.is_some())
        })
        .collect()
}

fn outcome(results: &[(String, bool)], name: &str) -> bool {
    results
        .iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("{name} is missing"))
        .1
}

#[test]
fn obj_regressions() {
    let r = run("obj", |b, p| obj::parse_obj(b, p).ok());
    // A UTF-8 byte order mark is skipped, not taken as part of the first line.
    assert!(outcome(&r, "bom.obj"));
    let bytes = std::fs::read(
        inputs("obj")
            .iter()
            .find(|p| p.ends_with("bom.obj"))
            .unwrap(),
    );
    let mesh = obj::parse_obj(&bytes.unwrap(), Path::new("bom.obj")).unwrap();
    assert_eq!((mesh.num_vertices(), mesh.num_triangles()), (4, 4));
}

#[test]
fn off_regressions() {
    let r = run("off", |b, p| off::parse_off(b, p).ok());
    assert!(!outcome(&r, "face_size_overflow.off"));
}

#[test]
fn ply_regressions() {
    let r = run("ply", |b, p| ply::parse_ply(b, p).ok());
    assert!(!outcome(&r, "huge_header_counts.ply"));
}

#[test]
fn stl_regressions() {
    let r = run("stl", |b, p| stl::parse_stl(b, p, 0.0).ok());
    assert!(!outcome(&r, "huge_triangle_count.stl"));
    assert!(!outcome(&r, "only_degenerate.stl"));
}

#[test]
fn vtp_regressions() {
    run("vtp", |b, p| {
        let text = std::str::from_utf8(b).ok()?;
        let _ = vtp::parse_vtp(text, p);
        None
    });
}
