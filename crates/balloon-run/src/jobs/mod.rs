//! One job per system: build the simulation from its scenario, run it with the shared loop,
//! write its outputs and summary.

pub mod connect;
pub mod design;
pub mod shell;
mod shell_frame;
pub mod statics;
pub mod two_layer;
pub mod volumetric;

pub use shell_frame::shell_frame;
