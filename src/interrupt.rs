//! Stopping a long run cleanly: a [`Cancel`] token that a run looks at between windows of
//! steps, and one source that sets it, SIGINT (Ctrl-C) or SIGTERM (what a cluster scheduler
//! sends before it kills a job at its time limit).
//!
//! A run given a token ([`crate::run`]) checks it after each window of steps; once it is
//! set, the run writes a checkpoint and returns [`crate::Error::Interrupted`], so the record
//! ends at a checkpoint and `cdlab biaxial --resume` (or [`crate::run::resume`], or the same
//! `cdlab sweep`) continues from it.
//!
//! Signal handling is opt-in: only [`install`] changes what SIGINT and SIGTERM do, and only
//! the command line calls it. A library caller (a Python session, a notebook) keeps its own
//! Ctrl-C and stops a run through [`Cancel::cancel`]. The handler restores the default
//! action, so a second signal ends the process at once.

use std::sync::Arc;
use std::sync::atomic::{AtomicI32, Ordering};

/// The signal received, 0 before any.
static RECEIVED: AtomicI32 = AtomicI32::new(0);

/// The value [`Cancel::requested`] gives for a stop asked by [`Cancel::cancel`] rather than
/// by a signal (no signal number is negative).
pub const CANCELLED: i32 = -1;

#[cfg(unix)]
extern "C" fn on_signal(sig: libc::c_int) {
    RECEIVED.store(sig, Ordering::SeqCst);
    // SAFETY: signal() is async-signal-safe (POSIX), and SIG_DFL a valid disposition.
    unsafe {
        libc::signal(sig, libc::SIG_DFL);
    }
}

/// A request to stop a run at its next checkpoint, shared by clones: cheap to clone and to
/// check, safe to set from another thread.
///
/// ```
/// let cancel = cdlab::interrupt::Cancel::new();
/// let worker = cancel.clone();
/// assert_eq!(worker.requested(), None);
/// cancel.cancel();
/// assert_eq!(worker.requested(), Some(cdlab::interrupt::CANCELLED));
/// ```
#[derive(Clone, Debug, Default)]
pub struct Cancel {
    flag: Arc<AtomicI32>,
    /// Whether a signal caught by [`install`]'s handler also stops the run.
    signals: bool,
}

impl Cancel {
    /// A token that only [`Cancel::cancel`] sets.
    pub fn new() -> Self {
        Self::default()
    }

    /// A token that a signal caught by [`install`]'s handler also sets. It does not install
    /// the handler: without it, the signals keep their default action.
    pub fn with_signals() -> Self {
        Cancel {
            flag: Arc::default(),
            signals: true,
        }
    }

    /// Asks every run holding a clone of this token to stop at its next checkpoint.
    pub fn cancel(&self) {
        let _ = self
            .flag
            .compare_exchange(0, CANCELLED, Ordering::SeqCst, Ordering::SeqCst);
    }

    /// Why the run should stop, if it should: the signal received, or [`CANCELLED`].
    pub fn requested(&self) -> Option<i32> {
        match self.flag.load(Ordering::SeqCst) {
            0 if self.signals => requested(),
            0 => None,
            why => Some(why),
        }
    }
}

/// Makes SIGINT and SIGTERM request a stop at the next checkpoint instead of ending the
/// process, and returns a token they set. Only commands that watch such a token while they
/// run call this: elsewhere a signal must keep its default action. Without Unix signals,
/// only the token's own [`Cancel::cancel`] sets it.
pub fn install() -> Cancel {
    #[cfg(unix)]
    // SAFETY: the handler only stores into an atomic and calls signal().
    unsafe {
        let handler = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
        libc::signal(libc::SIGINT, handler);
        libc::signal(libc::SIGTERM, handler);
    }
    Cancel::with_signals()
}

/// The signal that asked the run to stop, if one did.
pub fn requested() -> Option<i32> {
    match RECEIVED.load(Ordering::SeqCst) {
        0 => None,
        sig => Some(sig),
    }
}

/// The name of what stopped a run, in messages: a signal, or [`CANCELLED`].
pub fn signal_name(sig: i32) -> &'static str {
    if sig == CANCELLED {
        return "its caller";
    }
    #[cfg(unix)]
    {
        if sig == libc::SIGINT {
            return "SIGINT";
        }
        if sig == libc::SIGTERM {
            return "SIGTERM";
        }
    }
    "a signal"
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A token set by `cancel` stays set for every clone and keeps its first reason; a plain
    /// token ignores the process's signal state, which only a token with signals reads.
    #[test]
    fn cancel_is_shared_by_clones_and_signals_are_opt_in() {
        let a = Cancel::new();
        let b = a.clone();
        assert_eq!(b.requested(), None);
        a.cancel();
        a.cancel();
        assert_eq!(b.requested(), Some(CANCELLED));
        assert_eq!(signal_name(CANCELLED), "its caller");
        // No handler is installed in the unit tests, so no signal has been recorded.
        assert_eq!(Cancel::with_signals().requested(), requested());
    }
}
