//! The `balloon` Python package's extension module (`balloon._balloon`, built with maturin from
//! `python/pyproject.toml`).
//!
//! It is what the Python API calls: whole jobs (`inflate`, `volumetric`, `two_layer`,
//! `connect`, `run_scenario`) and step-wise simulations (`Shell`, `Volumetric`, `TwoLayer`).
//! Keyword options are the scenario's parameters by name (`newton_tol=1e-8` sets
//! `newton_tol`, the command line's `--newton-tol`): each Python value becomes a typed value of
//! `balloon_scenario` directly (no text on the way), the scenario is checked by the library,
//! the simulation built by the scenario's `build`, and whole jobs run through `balloon_run`,
//! the command-line tool's run loop; so defaults, units, checks and results are the CLI's. It is
//! not a Rust API: Rust code uses `balloon` and `balloon-scenario`.
//!
//! From Python (the crate's tests are `python/tests`, run by pytest; a Rust doctest cannot
//! load an extension module):
//!
//! ```text
//! >>> import balloon
//! >>> r = balloon.inflate("builtin:sphere", steps=15, gas="constant", pressure=900.0)
//! >>> r["positions"].shape, r["summary"]["steps"]
//! ((2562, 3), 15)
//! ```

mod args;
mod cancel;
mod convert;
mod design;
mod errors;
mod jobs;
mod options;
mod shared;
mod sims;

use errors::{BalloonError, InvalidOption, MeshError, SolverError, check_python_signals};
use jobs::{connect, inflate, run_scenario, two_layer, volumetric};
use pyo3::prelude::*;
use sims::{Shell, TwoLayer, Volumetric};

/// The extension module `balloon._balloon`.
#[pymodule]
fn _balloon(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    // Ctrl-C as Python sees it stops the run loops between steps ...
    balloon_run::interrupt::set_checker(check_python_signals);
    // ... and, through a C-level flag, inside a Newton solve of the main thread.
    cancel::register();
    m.add("BalloonError", py.get_type::<BalloonError>())?;
    m.add("InvalidOption", py.get_type::<InvalidOption>())?;
    m.add("MeshError", py.get_type::<MeshError>())?;
    m.add("SolverError", py.get_type::<SolverError>())?;
    m.add_function(wrap_pyfunction!(inflate, m)?)?;
    m.add_function(wrap_pyfunction!(volumetric, m)?)?;
    m.add_function(wrap_pyfunction!(two_layer, m)?)?;
    m.add_function(wrap_pyfunction!(connect, m)?)?;
    m.add_function(wrap_pyfunction!(run_scenario, m)?)?;
    m.add_function(wrap_pyfunction!(design::design, m)?)?;
    m.add_class::<Shell>()?;
    m.add_class::<Volumetric>()?;
    m.add_class::<TwoLayer>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
