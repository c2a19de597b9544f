//! Ctrl-C, and SIGTERM where asked: the first one sets a flag so that runs and recordings finish
//! what they have into valid files (a `timeout` that sent SIGTERM left `.NAME.partial` files
//! behind); any later one terminates as usual. A copy of the first (the same signal, within
//! 50 ms) is not a later one: GNU `timeout` sends its signal to the command and then to the
//! command's process group, and the copy ended 3 in 30 `timeout -s INT` recordings at once,
//! leaving no file.

#[cfg(unix)]
use std::sync::atomic::AtomicI64;
use std::sync::atomic::{AtomicI32, Ordering};

/// The signal that interrupted the run, or 0.
static SIGNAL: AtomicI32 = AtomicI32::new(0);

/// When the first signal came, in nanoseconds of the monotonic clock (0 while its handler has
/// yet to store it).
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
#[allow(clippy::unnecessary_cast)] // The fields are 32 bits wide on 32-bit targets.
fn monotonic_ns() -> i64 {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid pointer to a timespec the call fills.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut now) };
    (now.tv_sec as i64)
        .saturating_mul(1_000_000_000)
        .saturating_add(now.tv_nsec as i64)
}

/// Whether `signal`, arriving at `now` after the first signal `first` (which came at
/// `first_at`, or 0 while its handler has yet to note the time), is a copy of it: the same
/// signal within [`COPY_WITHIN_NS`].
#[cfg(unix)]
fn is_copy(signal: i32, now: i64, (first, first_at): (i32, i64)) -> bool {
    signal == first && (first_at == 0 || now.saturating_sub(first_at) < COPY_WITHIN_NS)
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
    let first = (
        SIGNAL.load(Ordering::SeqCst),
        FIRST_AT_NS.load(Ordering::SeqCst),
    );
    if is_copy(signal, now, first) {
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

#[cfg(all(test, unix))]
mod tests {
    use super::{COPY_WITHIN_NS, is_copy};

    /// The same signal at once is a copy, also while the first's handler has yet to note its
    /// time; a later one, or another signal, is not.
    #[test]
    fn copies_are_the_same_signal_at_once() {
        let first = (libc::SIGINT, 1_000_000_000);
        assert!(is_copy(libc::SIGINT, 1_000_000_100, first));
        assert!(is_copy(libc::SIGINT, 1_000_000_100, (libc::SIGINT, 0)));
        assert!(!is_copy(
            libc::SIGINT,
            1_000_000_000 + COPY_WITHIN_NS,
            first
        ));
        assert!(!is_copy(libc::SIGTERM, 1_000_000_100, first));
    }
}
