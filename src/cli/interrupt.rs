//! Ctrl-C, and SIGTERM where asked: the first one sets a flag so that runs and recordings finish
//! what they have into valid files (a `timeout` that sent SIGTERM left `.NAME.partial` files
//! behind); any second one terminates as usual.

use std::sync::atomic::{AtomicI32, Ordering};

/// The signal that interrupted the run, or 0.
static SIGNAL: AtomicI32 = AtomicI32::new(0);

/// Said when the first signal arrives: a step or a frame may take long (a huge constraint
/// budget, a tiny dt), and a user who sees nothing happen would not know a second one ends it.
const FINISHING: &[u8] =
    b"\ninterrupted: finishing the current step and writing what is done; press Ctrl-C again to stop at once\n";

extern "C" fn on_signal(signal: libc::c_int) {
    // The first signal is the one the exit status reports.
    let _ = SIGNAL.compare_exchange(0, signal, Ordering::SeqCst, Ordering::SeqCst);
    // Async-signal-safe: write(2), and back to the default action for the next one, of either
    // kind.
    unsafe {
        libc::write(
            libc::STDERR_FILENO,
            FINISHING.as_ptr().cast(),
            FINISHING.len(),
        );
        libc::signal(libc::SIGINT, libc::SIG_DFL);
        libc::signal(libc::SIGTERM, libc::SIG_DFL);
    }
}

/// Installs the handler of SIGINT, and of SIGTERM with `term` (Unix; a no-op elsewhere). The
/// window leaves SIGTERM alone: its event loop may sleep until the next input, and `kill`
/// should end it at once.
pub fn install(term: bool) {
    #[cfg(unix)]
    for signal in [libc::SIGINT, libc::SIGTERM] {
        if signal == libc::SIGINT || term {
            unsafe {
                libc::signal(signal, on_signal as *const () as libc::sighandler_t);
            }
        }
    }
}

/// Whether Ctrl-C was pressed (or SIGTERM sent, where caught) since [`install`].
pub fn interrupted() -> bool {
    SIGNAL.load(Ordering::SeqCst) != 0
}

/// The conventional exit status of a run stopped by the signal: 128 plus its number (130 for
/// Ctrl-C, 143 for SIGTERM).
pub fn exit_status() -> i32 {
    128 + SIGNAL.load(Ordering::SeqCst)
}
