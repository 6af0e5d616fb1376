//! Stopping a long run cleanly on SIGINT (Ctrl-C) or SIGTERM (what a cluster scheduler sends
//! before it kills a job at its time limit).
//!
//! [`install`] replaces the default action of both signals by a handler that only records
//! the signal; [`crate::protocol::biaxial::Lab::run`] looks at it between windows of steps, writes a
//! checkpoint and returns [`crate::Error::Interrupted`], so the record ends at a checkpoint
//! and `cdlab biaxial --resume` (or the same `cdlab sweep`) continues from it. The handler
//! restores the default action, so a second signal ends the process at once.

use std::sync::atomic::{AtomicI32, Ordering};

/// The signal received, 0 before any.
static RECEIVED: AtomicI32 = AtomicI32::new(0);

#[cfg(unix)]
extern "C" fn on_signal(sig: libc::c_int) {
    RECEIVED.store(sig, Ordering::SeqCst);
    // SAFETY: signal() is async-signal-safe (POSIX), and SIG_DFL a valid disposition.
    unsafe {
        libc::signal(sig, libc::SIG_DFL);
    }
}

/// Makes SIGINT and SIGTERM request a stop at the next checkpoint instead of ending the
/// process. Only commands that check [`requested`] while they run call this: elsewhere a
/// signal must keep its default action. Without Unix signals, does nothing.
pub fn install() {
    #[cfg(unix)]
    // SAFETY: the handler only stores into an atomic and calls signal().
    unsafe {
        let handler = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
        libc::signal(libc::SIGINT, handler);
        libc::signal(libc::SIGTERM, handler);
    }
}

/// The signal that asked the run to stop, if one did.
pub fn requested() -> Option<i32> {
    match RECEIVED.load(Ordering::SeqCst) {
        0 => None,
        sig => Some(sig),
    }
}

/// The name of a signal in messages.
pub fn signal_name(sig: i32) -> &'static str {
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
