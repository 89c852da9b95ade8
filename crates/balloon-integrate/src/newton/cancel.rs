//! A process-wide cancellation check asked once per Newton iteration, so that a long solve (a
//! static solve that stalls, a dynamic step on tiny sub-steps) stops within one iteration of a
//! request instead of when it gives up.
//!
//! A front end that catches SIGINT / SIGTERM registers a check with [`set_cancel_check`]; every
//! Newton solve of the process then asks it at the start of each iteration and, when it returns
//! `true`, ends with [`NewtonError::Interrupted`](crate::newton::NewtonError::Interrupted)
//! (not recoverable: the sub-step controller and the static continuation do not retry it). The
//! state is left at the last accepted iterate, as for any failed solve. The check must be
//! cheap and must not block (read an atomic flag); it is called from whichever thread solves.
//!
//! ```
//! use std::sync::atomic::{AtomicBool, Ordering};
//! static STOP: AtomicBool = AtomicBool::new(false);
//! assert!(!balloon_integrate::newton::cancel_requested()); // no check set: never cancelled
//! assert!(balloon_integrate::newton::set_cancel_check(|| STOP.load(Ordering::Relaxed)));
//! STOP.store(true, Ordering::Relaxed);
//! assert!(balloon_integrate::newton::cancel_requested());
//! ```

use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The check asked by [`cancel_requested`] (set once per process).
static CHECK: OnceLock<fn() -> bool> = OnceLock::new();

/// How many [`without_cancel`] calls are running (the check is not asked while any is).
static SUSPENDED: AtomicUsize = AtomicUsize::new(0);

/// Registers the check every Newton iteration of the process asks (once per process; returns
/// `false` when one was already set, which is kept).
pub fn set_cancel_check(check: fn() -> bool) -> bool {
    CHECK.set(check).is_ok()
}

/// Whether the registered check asks the solves to stop now (`false` without a check, and
/// while a [`without_cancel`] call runs).
pub fn cancel_requested() -> bool {
    SUSPENDED.load(Ordering::SeqCst) == 0 && CHECK.get().is_some_and(|check| check())
}

/// Runs `f` with the cancellation check suspended (process-wide, for every thread): the
/// solves inside run to their own end even after a request. For the work a front end still
/// owes the user once a stop was asked for, such as checking the best result so far (a design
/// stopped with Ctrl-C is checked by a forward solve, which must not stop at its first
/// iteration). A front end that must be able to end such work too ends the process on a
/// second request, as the `balloon` command does.
///
/// ```
/// use balloon_integrate::newton::{cancel_requested, set_cancel_check, without_cancel};
/// set_cancel_check(|| true); // a stop was asked for
/// assert!(cancel_requested());
/// assert!(!without_cancel(cancel_requested));
/// assert!(cancel_requested());
/// ```
pub fn without_cancel<R>(f: impl FnOnce() -> R) -> R {
    /// Ends the suspension also when `f` unwinds.
    struct Resume;
    impl Drop for Resume {
        fn drop(&mut self) {
            SUSPENDED.fetch_sub(1, Ordering::SeqCst);
        }
    }
    SUSPENDED.fetch_add(1, Ordering::SeqCst);
    let _resume = Resume;
    f()
}
