//! The simulations behind one interface: controls, stepping, positions, scalar fields and
//! drags, as the server needs them; one file per built-in system ([`shell`], [`volumetric`],
//! [`two_layer`]) and one for any scenario ([`scenario`]: scenario files and `connect`).

mod saved;
mod scenario;
mod shell;
mod two_layer;
mod view;
mod volumetric;

pub use saved::{DEFAULT_SHELL_MESH, DEFAULT_VOLUMETRIC_MESH, LYING_ON_ITS_BACK};
pub use scenario::{ScenarioView, builtin_connect};
pub use shell::ShellView;
pub use two_layer::TwoLayerView;
pub use view::{DragRequest, Sphere, ViewSystem, ViewedSimulation, first_non_finite};
pub use volumetric::VolumetricView;

#[cfg(test)]
mod saved_tests;
#[cfg(test)]
mod scenario_drag_tests;
#[cfg(test)]
mod scenario_tests;
#[cfg(test)]
mod test_support;
#[cfg(test)]
mod tests;
