//! Fuzz target: the VTK PolyData (.vtp) reader on arbitrary text. Must never panic, hang or
//! allocate without bound.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = balloon_mesh::io::vtp::parse_vtp(text, Path::new("fuzz.vtp"));
    }
});
