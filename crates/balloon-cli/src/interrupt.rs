//! SIGINT (Ctrl-C) and SIGTERM end a simulation cleanly: the run loop finishes the step it is
//! in, writes its records (`summary.json` with `"interrupted": true`, the frames so far) and the
//! process exits with 128 + the signal number (130 for SIGINT, 143 for SIGTERM), as a shell
//! reports a process killed by it. A second signal while the records are written ends the
//! process at once with the same status.

use signal_hook::consts::{SIGINT, SIGTERM};
use signal_hook::flag;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// The signal received (0: none).
static SIGNAL: AtomicUsize = AtomicUsize::new(0);
/// Set by the first signal: the next one terminates at once.
static ARMED: AtomicBool = AtomicBool::new(false);

/// Installs the handlers for SIGINT and SIGTERM (call once, before the run).
pub fn install() -> std::io::Result<()> {
    for sig in [SIGINT, SIGTERM] {
        // Order matters: the shutdown check must run before the flag that arms it is set.
        flag::register_conditional_shutdown(sig, 128 + sig, &ARMED)?;
        flag::register_usize(sig, &SIGNAL, sig as usize)?;
        flag::register(sig, &ARMED)?;
    }
    Ok(())
}

/// A second source of interruptions, asked between steps when no signal was received: a host
/// that owns the signals itself (the Python package, whose interpreter handles Ctrl-C) reports
/// them through it.
static CHECKER: OnceLock<fn() -> Option<i32>> = OnceLock::new();

/// Sets the function [`pending`] asks between steps for an interruption (once per process;
/// returns `false` when one was already set). It returns the signal number that stops the run.
pub fn set_checker(check: fn() -> Option<i32>) -> bool {
    CHECKER.set(check).is_ok()
}

/// The signal received so far, if any (or the interruption the checker reports now).
pub fn pending() -> Option<i32> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => CHECKER.get().and_then(|check| check()),
        s => i32::try_from(s).ok(),
    }
}

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
