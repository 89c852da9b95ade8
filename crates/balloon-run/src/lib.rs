//! Runs a `balloon` scenario as a job: the front ends' shared run loop (the command-line tool
//! and the Python package run exactly the same code).
//!
//! A job takes a validated scenario (`balloon_scenario`), checks its output folder, builds the
//! simulation with the scenario's `build`, steps it through [`run::run_simulation`] (or solves
//! the static shell), and writes what the scenario's `[output]` table asks for: frames,
//! `stats.jsonl`, `summary.json`, the recorded `scenario.toml` and the pictures
//! ([`output`]). It returns the summary and the final simulation ([`Finished`]). One job per
//! system: [`jobs::shell`] (with its static solve, [`jobs::statics`]), [`jobs::connect`],
//! [`jobs::volumetric`], [`jobs::two_layer`].
//!
//! It is not the simulation library (that is `balloon`, with `balloon-scenario` to set runs
//! up): it writes files and, unless quiet, a progress bar and a summary line. Its errors are
//! `anyhow` chains whose messages name parameters in backticks (`` `out` ``); the front ends
//! spell them as their users write them (`balloon_scenario::names`).
//!
//! ```
//! use balloon_scenario::two_layer::TwoLayerScenario;
//! let mut s = TwoLayerScenario::default();
//! s.body.level = 1;
//! s.run.steps = 3;
//! s.validate().unwrap();
//! let done = balloon_run::jobs::two_layer::run(&s, None, true).unwrap();
//! assert_eq!(done.summary.unwrap()["steps"], 3);
//! ```

pub mod interrupt;
pub mod jobs;
pub mod output;
pub mod run;

pub use run::Finished;
