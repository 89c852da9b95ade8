//! Interruptions between steps: a front end that catches SIGINT (Ctrl-C) or SIGTERM reports
//! them through a checker ([`set_checker`]) that the run loop asks between two steps
//! ([`pending`]). The run then finishes the step it is in, writes its records
//! (`summary.json` with `"interrupted": true`, the frames so far) and ends with [`Interrupted`],
//! whose [`Interrupted::exit_code`] is 128 + the signal number (130 for SIGINT, 143 for
//! SIGTERM), as a shell reports a process killed by it.
//!
//! ```
//! assert_eq!(balloon_run::interrupt::pending(), None); // no checker set: never interrupted
//! let i = balloon_run::interrupt::Interrupted { signal: 2, steps: 7 };
//! assert_eq!(i.exit_code(), 130);
//! assert!(i.to_string().starts_with("interrupted by SIGINT after 7 completed step(s)"));
//! ```

use std::sync::OnceLock;

/// The function [`pending`] asks (set once per process).
static CHECKER: OnceLock<fn() -> Option<i32>> = OnceLock::new();

/// Sets the function [`pending`] asks between steps for an interruption (once per process;
/// returns `false` when one was already set). It returns the signal number that stops the run:
/// the command-line tool's signal handlers, or the Python interpreter's (Ctrl-C in Python).
pub fn set_checker(check: fn() -> Option<i32>) -> bool {
    CHECKER.set(check).is_ok()
}

/// The interruption the checker reports now, if any.
pub fn pending() -> Option<i32> {
    CHECKER.get().and_then(|check| check())
}

pub use crate::output::temp::{remove_temp_files, watch_out_dir};

/// SIGINT's number.
const SIGINT: i32 = 2;
/// SIGTERM's number.
const SIGTERM: i32 = 15;

/// A run stopped by a signal after writing its records.
#[derive(Debug, thiserror::Error)]
#[error(
    "interrupted by {} after {steps} completed step(s); the records of the run so far are written",
    signal_name(*signal)
)]
pub struct Interrupted {
    /// The signal number.
    pub signal: i32,
    /// Steps (or static points) completed before it.
    pub steps: usize,
}

impl Interrupted {
    /// The process exit status: 128 + the signal number.
    pub fn exit_code(&self) -> u8 {
        u8::try_from(128 + self.signal).unwrap_or(1)
    }
}

fn signal_name(signal: i32) -> String {
    match signal {
        SIGINT => "SIGINT".into(),
        SIGTERM => "SIGTERM".into(),
        s => format!("signal {s}"),
    }
}
