//! The package's exceptions and the library's errors as them, with the parameters spelled as
//! the command line does.

use balloon::SimulationError;
use balloon_run::interrupt::Interrupted;
use balloon_scenario::ScenarioError;
use balloon_scenario::keys::Literals;
use balloon_scenario::names::{Spelling, respell, value_message};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt};
use pyo3::prelude::*;
use std::cell::RefCell;

create_exception!(
    _balloon,
    BalloonError,
    PyException,
    "Base class of every error balloon raises; the message is the CLI's."
);
create_exception!(
    _balloon,
    InvalidOption,
    BalloonError,
    "An unknown keyword option, a value of the wrong type or outside its range, keywords that \
     do not go together, or a scenario file that does not parse."
);
create_exception!(
    _balloon,
    MeshError,
    BalloonError,
    "A mesh that cannot be read or used (missing file, unknown format, open or degenerate \
     surface, bad arrays)."
);
create_exception!(
    _balloon,
    SolverError,
    BalloonError,
    "A simulation step that failed (Newton did not converge, an inverted element, a blow-up)."
);

/// How errors spell parameters: as the command line does, so that a message reads the same
/// from Python and from the CLI (the package's tests compare them). `Spelling::Keyword`
/// (`dt=`) is the alternative `balloon_scenario::names` offers.
pub(crate) const SPELLING: Spelling = Spelling::Flag;

/// A library message with its parameters spelled for Python users.
pub(crate) fn spelled(message: &str) -> String {
    respell(message, SPELLING)
}

/// A scenario's check as a Python exception: a value outside its range shows the text given
/// (`invalid value '5.0' for '--dt <DT>': ...`, the CLI's message); keys that do not go
/// together are named.
pub(crate) fn invalid(e: ScenarioError, literals: &Literals) -> PyErr {
    match e {
        ScenarioError::Value(v) => {
            InvalidOption::new_err(value_message(&v, SPELLING, literals.typed(&v)))
        }
        e => InvalidOption::new_err(spelled(&e.to_string())),
    }
}

thread_local! {
    /// The exception Python's signal handler raised while a run checked for Ctrl-C (re-raised
    /// once the run has written its records).
    static SIGNAL_ERROR: RefCell<Option<PyErr>> = const { RefCell::new(None) };
}

/// The interruption check of the CLI's run loop, between steps: runs Python's signal handlers
/// (Ctrl-C raises `KeyboardInterrupt` there) and stops the run when one raised.
pub(crate) fn check_python_signals() -> Option<i32> {
    Python::attach(|py| match py.check_signals() {
        Ok(()) => None,
        Err(e) => {
            SIGNAL_ERROR.with(|s| *s.borrow_mut() = Some(e));
            Some(2)
        }
    })
}

/// The Python exception of a job's error: the signal's exception for an interrupted run, else a
/// [`BalloonError`] subclass by the error's kind, with the CLI's message.
pub(crate) fn to_py_err(e: anyhow::Error) -> PyErr {
    if e.chain().any(|c| c.is::<Interrupted>()) {
        return SIGNAL_ERROR
            .with(|s| s.borrow_mut().take())
            .unwrap_or_else(|| PyKeyboardInterrupt::new_err(error_chain(&e)));
    }
    let msg = error_chain(&e);
    if e.chain().any(|c| c.is::<ScenarioError>()) {
        InvalidOption::new_err(msg)
    } else if e.chain().any(|c| c.is::<SimulationError>()) {
        SolverError::new_err(msg)
    } else if e.chain().any(|c| c.is::<balloon::mesh::MeshError>()) {
        MeshError::new_err(msg)
    } else {
        BalloonError::new_err(msg)
    }
}

/// The error and its causes joined by `: ` (skipping a cause the message already holds), with
/// the parameters spelled for Python users: the CLI's message.
fn error_chain(e: &anyhow::Error) -> String {
    let mut msg = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if msg.contains(&text) {
            continue;
        }
        if !msg.is_empty() {
            msg.push_str(": ");
        }
        msg.push_str(&text);
    }
    spelled(&msg)
}

/// A library error of a step-wise simulation's setter.
pub(crate) fn setter_err(e: impl std::fmt::Display) -> PyErr {
    InvalidOption::new_err(spelled(&e.to_string()))
}
