//! Typed scenarios of the `balloon` simulations: what a run is, checked, read from and written
//! to scenario files, and built into a simulation.
//!
//! A scenario holds every parameter of a run of one of the four systems: the shell balloon of
//! Wang et al. 2015 ([`shell::ShellScenario`], `balloon inflate`, also its static solve),
//! connected shell balloons ([`connect::ConnectScenario`]), the volume-conserving body of
//! Diziol, Bender and Bayer 2011 ([`volumetric::VolumetricScenario`]) and the two-layer body of
//! Song 2009 ([`two_layer::TwoLayerScenario`]). Its parts are serde structs that mirror the
//! tables of a scenario file (`[mesh]`, `[shell]`, `[gas]`, `[run]`, `[output]`, `[[anchors]]`,
//! `[[loads]]`, ...; `docs/scenarios.md`), with the program's defaults.
//!
//! It is what every front end builds: the command-line flags, `balloon run FILE` ([`file`](mod@file)),
//! the Python package's keywords and `xtask` all set a scenario's keys ([`keys`], one table per
//! system with each key's name, type and range), check it once ([`Scenario::validate`]: errors
//! name the parameter and its value; a file's errors also its line), and build the simulation
//! with the system's one `build` function. It is not for writing outputs (frames, summaries:
//! the job runner of the front ends does that from [`output::Output`]), nor for stepping.
//!
//! | part | for |
//! |---|---|
//! | [`shell`], [`connect`], [`volumetric`], [`two_layer`] | the typed scenario of each system and its `build` |
//! | [`keys`], [`value`], [`range`] | setting a key from untyped input, its range |
//! | [`file`](mod@file) | TOML and JSON scenario files with errors at their lines, the recorded scenario |
//! | [`selection`] | vertex selections, thickness maps, anchors and scheduled loads |
//! | [`material`], [`gas`], [`mesh`], [`output`] | the shared tables |
//! | [`design`](mod@design) | the `[design]` table: an inverse design (`balloon design`) |
//! | [`names`] | parameter names as the command line (`--dt`) and Python (`dt=`) spell them |
//!
//! ```
//! use balloon_scenario::{Scenario, SystemKind, value::Value};
//! // Set keys by name, as a front end does, then check and build.
//! let mut s = Scenario::new(SystemKind::Shell);
//! s.set("mesh", &Value::Text("builtin:icosphere".into())).unwrap();
//! s.set("gas", &Value::Text("constant".into())).unwrap();
//! s.set("pressure", &Value::Int(600)).unwrap();
//! s.validate().unwrap();
//! let Scenario::Shell(shell) = &s else { unreachable!() };
//! let (mut sim, _loads) = shell.build(None).unwrap();
//! balloon::Simulation::step(&mut sim).unwrap();
//! assert!(sim.gas_volume() > sim.rest_gas_volume());
//! ```

pub mod connect;
pub mod design;
mod error;
pub mod file;
pub mod gas;
pub mod keys;
pub mod material;
pub mod mesh;
pub mod names;
pub mod output;
pub mod range;
mod scenario;
pub mod selection;
pub mod serde_text;
pub mod shell;
pub mod two_layer;
pub mod value;
pub mod volumetric;

pub use error::ScenarioError;
pub use scenario::{KeyInfo, Scenario, SystemKind};

#[cfg(test)]
mod tests;
