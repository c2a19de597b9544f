//! Ctrl-C and SIGTERM: the first one sets a flag so that runs and recordings finish what they
//! have into valid files (a `timeout` that sent SIGTERM left `.NAME.partial` files behind); a
//! second one terminates as usual.

use std::sync::atomic::{AtomicI32, Ordering};

/// The signal that interrupted the run, or 0.
static SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_signal(signal: libc::c_int) {
    SIGNAL.store(signal, Ordering::SeqCst);
    // Async-signal-safe: back to the default action for the next one.
    unsafe {
        libc::signal(signal, libc::SIG_DFL);
    }
}

/// Installs the handler of SIGINT and SIGTERM (Unix; a no-op elsewhere).
pub fn install() {
    #[cfg(unix)]
    for signal in [libc::SIGINT, libc::SIGTERM] {
        unsafe {
            libc::signal(signal, on_signal as *const () as libc::sighandler_t);
        }
    }
}

/// Whether Ctrl-C was pressed (or SIGTERM sent) since [`install`].
pub fn interrupted() -> bool {
    SIGNAL.load(Ordering::SeqCst) != 0
}

/// The conventional exit status of a run stopped by the signal: 128 plus its number (130 for
/// Ctrl-C, 143 for SIGTERM).
pub fn exit_status() -> i32 {
    128 + SIGNAL.load(Ordering::SeqCst)
}
