//! The three simulations behind one interface: controls, stepping, positions, scalar fields and
//! drags, as the server needs them; one file per system ([`shell`], [`volumetric`],
//! [`two_layer`]).

mod shell;
mod two_layer;
mod view;
mod volumetric;

pub use shell::ShellView;
pub use two_layer::TwoLayerView;
pub use view::{DragRequest, ViewSystem, ViewedSimulation, first_non_finite};
pub use volumetric::VolumetricView;

#[cfg(test)]
mod tests;
