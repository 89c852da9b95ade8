//! A simulation shared between Python threads: calls take turns in the order they arrive
//! (a ticket queue), and a thread waits for its turn with the GIL released, so a reader never
//! blocks the interpreter while a `step()` (which runs with the GIL released) holds the
//! simulation, a stepping thread cannot starve a reader, and Ctrl-C still reaches a waiting
//! thread (`KeyboardInterrupt` once its turn has come and gone: the call then does nothing).

use crate::errors::BalloonError;
use pyo3::prelude::*;
use std::ops::{Deref, DerefMut};
use std::sync::{Condvar, Mutex, MutexGuard};
use std::time::Duration;

/// How often a waiting thread runs Python's signal handlers.
const SIGNAL_CHECK: Duration = Duration::from_millis(20);

/// A value (a simulation) used by one call at a time, in arrival order.
pub(crate) struct Shared<T> {
    data: Mutex<T>,
    /// (next ticket to hand out, ticket being served).
    queue: Mutex<(u64, u64)>,
    turn: Condvar,
}

/// A call's hold on a [`Shared`] value; dropping it lets the next ticket in.
pub(crate) struct Turn<'a, T> {
    guard: Option<MutexGuard<'a, T>>,
    owner: &'a Shared<T>,
}

impl<T> Shared<T> {
    /// Shares `value`.
    pub(crate) fn new(value: T) -> Self {
        Self {
            data: Mutex::new(value),
            queue: Mutex::new((0, 0)),
            turn: Condvar::new(),
        }
    }

    /// Waits (GIL released, signals checked every 20 ms) for this call's turn and takes the
    /// value. A signal handler's exception (Ctrl-C) is raised once the turn has come, without
    /// using the value; a value left poisoned by an earlier panic is refused.
    pub(crate) fn lock(&self, py: Python<'_>) -> PyResult<Turn<'_, T>> {
        let ticket = {
            let mut q = self.queue.lock().unwrap_or_else(|e| e.into_inner());
            q.0 += 1;
            q.0 - 1
        };
        let mut interrupted = None;
        let (queue, turn) = (&self.queue, &self.turn);
        loop {
            let mine = py.detach(|| {
                let q = queue.lock().unwrap_or_else(|e| e.into_inner());
                let (q, _) = turn
                    .wait_timeout_while(q, SIGNAL_CHECK, |q| q.1 != ticket)
                    .unwrap_or_else(|e| e.into_inner());
                q.1 == ticket
            });
            if mine {
                break;
            }
            if interrupted.is_none()
                && let Err(e) = py.check_signals()
            {
                interrupted = Some(e);
            }
        }
        // Only the ticket being served locks `data`: it is free (or poisoned).
        let guard = self.data.try_lock().ok();
        let turn = Turn { guard, owner: self };
        if let Some(e) = interrupted {
            return Err(e);
        }
        if turn.guard.is_none() {
            return Err(BalloonError::new_err(
                "the simulation is unusable after an internal error",
            ));
        }
        Ok(turn)
    }
}

impl<T> Drop for Turn<'_, T> {
    fn drop(&mut self) {
        drop(self.guard.take());
        let mut q = self.owner.queue.lock().unwrap_or_else(|e| e.into_inner());
        q.1 += 1;
        drop(q);
        self.owner.turn.notify_all();
    }
}

impl<T> Deref for Turn<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.guard.as_deref().expect("a turn holds the value")
    }
}

impl<T> DerefMut for Turn<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        self.guard.as_deref_mut().expect("a turn holds the value")
    }
}
