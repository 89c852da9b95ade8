//! Vertex selections, thickness maps, anchors and loads: the library's
//! (`balloon_scenario::selection`), under the name the command's tests and users know.

pub use balloon_scenario::selection::*;
