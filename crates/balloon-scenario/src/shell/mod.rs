//! The shell balloon's scenario (`balloon inflate`, Wang et al. 2015): the mesh, the material
//! and the wall (`[shell]`), the gas (`[gas]`), the time stepping, Newton and the linear solver
//! (`[run]`), the outputs, anchors and loads; and [`ShellScenario::build`], the one function
//! that sets a shell run up.
//!
//! ```
//! use balloon_scenario::shell::ShellScenario;
//! use balloon_scenario::gas::GasControl;
//! let mut s = ShellScenario::default();
//! s.mesh.path = "builtin:sphere".into();
//! s.gas.model = GasControl::Constant;
//! s.gas.pressure = 800.0;
//! s.validate().unwrap();
//! let (mut sim, _loads) = s.build(None).unwrap();
//! balloon::Simulation::step(&mut sim).unwrap();
//! assert!(sim.gas_volume() > sim.rest_gas_volume());
//! ```

mod build;
mod check;
mod keys;
mod types;

pub use build::{ShellBuildError, ShellSim};
pub use keys::SHELL_KEYS;
pub(crate) use keys::rule_text;
pub use types::{Gas, ProjectionMode, SHELL_COLORS, ShellRun, ShellScenario, Wall};

#[cfg(test)]
mod tests;
