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

/// The check asked by [`cancel_requested`] (set once per process).
static CHECK: OnceLock<fn() -> bool> = OnceLock::new();

/// Registers the check every Newton iteration of the process asks (once per process; returns
/// `false` when one was already set, which is kept).
pub fn set_cancel_check(check: fn() -> bool) -> bool {
    CHECK.set(check).is_ok()
}

/// Whether the registered check asks the solves to stop now (`false` without a check).
pub fn cancel_requested() -> bool {
    CHECK.get().is_some_and(|check| check())
}
