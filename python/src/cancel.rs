//! Ctrl-C inside a solve. While a call that solves (a step, a whole job, a static solve) runs
//! with the GIL released in the main thread, SIGINT is first seen by a small C-level handler of
//! this module: it sets a flag and calls the handler that was there before (Python's own, which
//! records the signal for the interpreter), so the Newton iteration in progress sees the flag
//! through `balloon::integrate::newton::set_cancel_check` and ends the solve at its last
//! accepted state; once the call is back in Python, the interpreter runs its handler
//! (`KeyboardInterrupt`). The check never takes the GIL (the solving thread released it, and a
//! thread waiting for the GIL inside the solve is how a deadlock starts).
//!
//! The handler is installed for the duration of each call and the previous one restored
//! afterwards, not once for the process: Python installs its own handler again whenever a
//! program calls `signal.signal` (Jupyter does it around every cell), which would silently
//! remove a handler installed once. Nothing is installed when SIGINT is ignored or left to its
//! default action (then Python does not handle it either), nor in other threads (Python runs
//! signal handlers in the main thread only); solves in other threads are never cancelled.

use pyo3::prelude::*;
use std::cell::Cell;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::ThreadId;

/// Set by the signal handler: SIGINT arrived while a call was armed.
static RECEIVED: AtomicBool = AtomicBool::new(false);

/// The main thread (Python's), once a call from it has been seen.
static MAIN_THREAD: OnceLock<ThreadId> = OnceLock::new();

thread_local! {
    /// Whether this thread is in an armed call (only the main thread ever is).
    static ARMED: Cell<bool> = const { Cell::new(false) };
}

/// Registers the Newton cancel check of the process (at module import).
pub(crate) fn register() {
    // A check set earlier (by a host program embedding the library) is kept.
    let _ = balloon::integrate::newton::set_cancel_check(cancel_requested);
}

/// The cancel check: a SIGINT arrived during this thread's armed call. Reads two flags; never
/// blocks and never takes the GIL.
fn cancel_requested() -> bool {
    ARMED.with(Cell::get) && RECEIVED.load(Ordering::SeqCst)
}

/// Whether the calling thread is Python's main thread.
fn is_main_thread(py: Python<'_>) -> bool {
    let me = std::thread::current().id();
    if let Some(main) = MAIN_THREAD.get() {
        return *main == me;
    }
    let main = py.import("threading").and_then(|t| {
        let ident: u64 = t.call_method0("get_ident")?.extract()?;
        let main: u64 = t.call_method0("main_thread")?.getattr("ident")?.extract()?;
        Ok(ident == main)
    });
    if matches!(main, Ok(true)) {
        let _ = MAIN_THREAD.set(me);
        return true;
    }
    false
}

/// A call armed for Ctrl-C: disarms and restores the previous SIGINT handler when dropped.
pub(crate) struct Armed {
    #[cfg(unix)]
    _handler: Option<sys::Installed>,
    armed: bool,
}

impl Armed {
    /// Whether SIGINT arrived during the call (the solve was then cancelled).
    pub(crate) fn received(&self) -> bool {
        self.armed && RECEIVED.load(Ordering::SeqCst)
    }
}

impl Drop for Armed {
    fn drop(&mut self) {
        if self.armed {
            ARMED.with(|a| a.set(false));
        }
    }
}

/// Arms the calling thread for Ctrl-C inside solves until the returned guard is dropped (call
/// with the GIL held, before releasing it). Does nothing outside the main thread, when SIGINT
/// is ignored or has its default action, or in a call nested in an armed one.
pub(crate) fn arm(py: Python<'_>) -> Armed {
    let idle = Armed {
        #[cfg(unix)]
        _handler: None,
        armed: false,
    };
    if ARMED.with(Cell::get) || !is_main_thread(py) {
        return idle;
    }
    #[cfg(unix)]
    {
        let Some(installed) = sys::install() else {
            return idle;
        };
        RECEIVED.store(false, Ordering::SeqCst);
        ARMED.with(|a| a.set(true));
        Armed {
            _handler: Some(installed),
            armed: true,
        }
    }
    #[cfg(not(unix))]
    {
        idle
    }
}

/// Runs `job` with the GIL released and this call armed for Ctrl-C; when the job failed
/// because SIGINT cancelled its solve, Python's signal handler runs at once (its exception,
/// `KeyboardInterrupt`, is returned instead of the job's error).
pub(crate) fn solve<T, E, F>(py: Python<'_>, job: F, to_err: impl FnOnce(E) -> PyErr) -> PyResult<T>
where
    T: Send,
    E: Send,
    F: FnOnce() -> Result<T, E> + Send,
{
    let armed = arm(py);
    let result = py.detach(job);
    let received = armed.received();
    drop(armed);
    match result {
        Ok(v) => Ok(v),
        Err(e) => {
            if received {
                py.check_signals()?;
            }
            Err(to_err(e))
        }
    }
}

/// The SIGINT handler (POSIX `sigaction`; the only unsafe code of the package).
#[cfg(unix)]
#[allow(unsafe_code)]
mod sys {
    use std::ptr;
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

    /// The handler that was installed before ours (its address), called after the flag is set.
    static PREVIOUS: AtomicUsize = AtomicUsize::new(0);
    /// Whether [`PREVIOUS`] takes `(signal, info, context)` (`SA_SIGINFO`).
    static PREVIOUS_SIGINFO: AtomicBool = AtomicBool::new(false);

    /// Sets the flag and chains to the previous handler. Async-signal-safe: atomics and a call.
    extern "C" fn on_sigint(sig: libc::c_int, info: *mut libc::siginfo_t, ctx: *mut libc::c_void) {
        super::RECEIVED.store(true, Ordering::SeqCst);
        let previous = PREVIOUS.load(Ordering::SeqCst);
        if previous == libc::SIG_DFL || previous == libc::SIG_IGN {
            return;
        }
        // SAFETY: `previous` is the handler address the kernel held for SIGINT before `install`
        // (neither SIG_DFL nor SIG_IGN), called with the signature its `SA_SIGINFO` flag says.
        unsafe {
            if PREVIOUS_SIGINFO.load(Ordering::SeqCst) {
                let f: extern "C" fn(libc::c_int, *mut libc::siginfo_t, *mut libc::c_void) =
                    std::mem::transmute(previous);
                f(sig, info, ctx);
            } else {
                let f: extern "C" fn(libc::c_int) = std::mem::transmute(previous);
                f(sig);
            }
        }
    }

    /// Our handler installed; dropping it restores the previous one.
    pub(super) struct Installed {
        previous: libc::sigaction,
    }

    /// Installs [`on_sigint`] in front of the current SIGINT handler; `None` when SIGINT is
    /// ignored, has its default action, is already ours, or `sigaction` fails.
    pub(super) fn install() -> Option<Installed> {
        let ours = on_sigint as extern "C" fn(_, _, _) as libc::sighandler_t;
        // SAFETY: `sigaction` with a valid signal and pointers to zero-initialised structs
        // (a valid bit pattern for `libc::sigaction`); reading the current action changes
        // nothing.
        unsafe {
            let mut current: libc::sigaction = std::mem::zeroed();
            if libc::sigaction(libc::SIGINT, ptr::null(), &mut current) != 0 {
                return None;
            }
            let handler = current.sa_sigaction;
            if handler == libc::SIG_DFL || handler == libc::SIG_IGN || handler == ours {
                return None;
            }
            PREVIOUS.store(handler, Ordering::SeqCst);
            PREVIOUS_SIGINFO.store(current.sa_flags & libc::SA_SIGINFO != 0, Ordering::SeqCst);
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = ours;
            action.sa_mask = current.sa_mask;
            action.sa_flags = (current.sa_flags & !libc::SA_RESETHAND) | libc::SA_SIGINFO;
            if libc::sigaction(libc::SIGINT, &action, ptr::null_mut()) != 0 {
                return None;
            }
            Some(Installed { previous: current })
        }
    }

    impl Drop for Installed {
        fn drop(&mut self) {
            // SAFETY: puts back the action read in `install` (a valid `sigaction`).
            unsafe {
                libc::sigaction(libc::SIGINT, &self.previous, ptr::null_mut());
            }
        }
    }
}
