//! SIGINT (Ctrl-C) and SIGTERM end a simulation cleanly: the run loop finishes the step it is
//! in, writes its records (`summary.json` with `"interrupted": true`, the frames so far) and the
//! process exits with 128 + the signal number (130 for SIGINT, 143 for SIGTERM), as a shell
//! reports a process killed by it. A second signal while the records are written ends the
//! process at once with the same status. The run loop asks for the signal through
//! `balloon_run::interrupt`.

use signal_hook::consts::{SIGINT, SIGTERM};
use signal_hook::flag;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

pub use balloon_run::interrupt::Interrupted;

/// The signal received (0: none).
static SIGNAL: AtomicUsize = AtomicUsize::new(0);
/// Set by the first signal: the next one terminates at once.
static ARMED: AtomicBool = AtomicBool::new(false);

/// The signal received so far, if any.
fn received() -> Option<i32> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        s => i32::try_from(s).ok(),
    }
}

/// Installs the handlers for SIGINT and SIGTERM and tells the run loop to ask them (call
/// once, before the run).
pub fn install() -> std::io::Result<()> {
    for sig in [SIGINT, SIGTERM] {
        // Order matters: the shutdown check must run before the flag that arms it is set.
        flag::register_conditional_shutdown(sig, 128 + sig, &ARMED)?;
        flag::register_usize(sig, &SIGNAL, sig as usize)?;
        flag::register(sig, &ARMED)?;
    }
    balloon_run::interrupt::set_checker(received);
    Ok(())
}
