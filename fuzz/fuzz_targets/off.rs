//! Fuzz target: the OFF reader on arbitrary bytes, then what `balloon mesh info` does with a
//! mesh it read (validation and topology). Must never panic, hang or allocate without bound.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(mesh) = balloon_mesh::io::off::parse_off(data, Path::new("fuzz.off")) {
        balloon_fuzz_check(&mesh);
    }
});

fn balloon_fuzz_check(mesh: &balloon_mesh::TriMesh) {
    let _ = balloon_mesh::validate::validate_closed_manifold(mesh);
    let _ = balloon_mesh::topology::Topology::new(mesh);
}
