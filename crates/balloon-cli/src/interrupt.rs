//! SIGINT (Ctrl-C) and SIGTERM end a simulation cleanly: the run loop finishes the step it is
//! in, writes its records (`summary.json` with `"interrupted": true`, the frames so far) and the
//! process exits with 128 + the signal number (130 for SIGINT, 143 for SIGTERM), as a shell
//! reports a process killed by it. A second signal while the records are written ends the
//! process at once with the same status. The run loop asks for the signal through
//! `balloon_run::interrupt`, every Newton iteration through
//! `balloon::integrate::newton::set_cancel_check` (the step or static point in progress is
//! then abandoned at its last accepted state).

use signal_hook::consts::{SIGINT, SIGTERM};
use signal_hook::iterator::Signals;
use std::sync::atomic::{AtomicUsize, Ordering};

pub use balloon_run::interrupt::Interrupted;

/// The signal received (0: none).
static SIGNAL: AtomicUsize = AtomicUsize::new(0);

/// The signal received so far, if any.
fn received() -> Option<i32> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        s => i32::try_from(s).ok(),
    }
}

/// Installs the handlers for SIGINT and SIGTERM and tells the run loop to ask them (call
/// once, before the run). The signals are taken by a thread of their own: the first is recorded
/// for the run loop; a second removes the temporary files of the output folder (a GIF being
/// encoded, a frame being written) and ends the process at once.
pub fn install() -> std::io::Result<()> {
    let mut signals = Signals::new([SIGINT, SIGTERM])?;
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            for sig in signals.forever() {
                if SIGNAL
                    .compare_exchange(0, sig as usize, Ordering::SeqCst, Ordering::SeqCst)
                    .is_err()
                {
                    balloon_run::interrupt::remove_temp_files();
                    std::process::exit(128 + sig);
                }
            }
        })?;
    balloon_run::interrupt::set_checker(received);
    // The solves ask too, once per Newton iteration: a stalling static solve or a step on tiny
    // sub-steps stops within one iteration instead of when it gives up.
    balloon::integrate::newton::set_cancel_check(|| received().is_some());
    Ok(())
}
