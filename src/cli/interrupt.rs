//! Ctrl-C, and SIGTERM where asked: the first one sets a flag so that runs and recordings finish
//! what they have into valid files (a `timeout` that sent SIGTERM left `.NAME.partial` files
//! behind); any later one terminates as usual. A copy of the first that arrives with it is not
//! a later one: GNU `timeout` sends its signal to the command and then to the command's process
//! group, and the copy ended 3 in 30 `timeout -s INT` recordings at once, leaving no file.

use std::sync::atomic::{AtomicI32, AtomicI64, Ordering};

/// The signal that interrupted the run, or 0.
static SIGNAL: AtomicI32 = AtomicI32::new(0);

/// When the first signal came, in nanoseconds of the monotonic clock.
#[cfg(unix)]
static FIRST_AT_NS: AtomicI64 = AtomicI64::new(0);

/// Signals this soon after the first are copies of it (one sender's two deliveries take
/// microseconds; a person pressing Ctrl-C twice takes over a tenth of a second).
#[cfg(unix)]
const COPY_WITHIN_NS: i64 = 50_000_000;

/// Said when the first signal arrives: a step or a frame may take long (a huge constraint
/// budget, a tiny dt), and a user who sees nothing happen would not know a second one ends it.
#[cfg(unix)]
const FINISHING: &[u8] =
    b"\ninterrupted: finishing the current step and writing what is done; press Ctrl-C again to stop at once\n";

/// The monotonic clock in nanoseconds (clock_gettime is async-signal-safe).
#[cfg(unix)]
fn monotonic_ns() -> i64 {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid pointer to a timespec the call fills.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut now) };
    now.tv_sec
        .saturating_mul(1_000_000_000)
        .saturating_add(now.tv_nsec)
}

#[cfg(unix)]
extern "C" fn on_signal(signal: libc::c_int) {
    let now = monotonic_ns();
    // The first signal is the one the exit status reports.
    if SIGNAL
        .compare_exchange(0, signal, Ordering::SeqCst, Ordering::SeqCst)
        .is_ok()
    {
        FIRST_AT_NS.store(now, Ordering::SeqCst);
        // SAFETY: write(2) is async-signal-safe.
        unsafe {
            libc::write(
                libc::STDERR_FILENO,
                FINISHING.as_ptr().cast(),
                FINISHING.len(),
            );
        }
        return;
    }
    if now.saturating_sub(FIRST_AT_NS.load(Ordering::SeqCst)) < COPY_WITHIN_NS {
        return;
    }
    // A later signal: its default action, at once. signal(2) and raise(3) are
    // async-signal-safe.
    unsafe {
        libc::signal(signal, libc::SIG_DFL);
        libc::raise(signal);
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
