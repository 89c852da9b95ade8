//! Cross-crate integration tests: one binary for the whole workspace (linking is slow on 2 cores).

mod anchors;
mod bulge;
mod connected;
mod layout;
mod limit_point;
mod newton;
mod shell;
mod statics;
mod two_layer;
mod volumetric;
