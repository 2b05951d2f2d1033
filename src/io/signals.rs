//! SIGINT and SIGTERM: what an interrupted run keeps.
//!
//! The handler only records the signal (an atomic store is all a handler may safely do);
//! a watcher thread acts on it. A command that can stop cleanly between units of work (a
//! sweep between cases) declares so with [`Graceful`]: it then finishes the cases in
//! flight, keeps the finished rows in its results marked incomplete, and exits with
//! 128 + the signal number. Any other command is ended by the watcher at once, which first
//! removes the staging directories in flight, so nothing half-written remains. A second
//! signal, or a graceful stop taking longer than [`GRACE`], ends the process the same way.
//!
//! `libc` is already in the dependency tree (through the standard tooling crates); calling
//! `sigaction` directly costs no new crate.

use std::sync::atomic::{AtomicBool, AtomicI32, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// How long a graceful stop may take before the process is ended anyway.
pub const GRACE: Duration = Duration::from_secs(10);

static SIGNAL: AtomicI32 = AtomicI32::new(0);
static COUNT: AtomicUsize = AtomicUsize::new(0);
static GRACEFUL: AtomicBool = AtomicBool::new(false);
static INSTALLED: AtomicBool = AtomicBool::new(false);

#[cfg(unix)]
extern "C" fn on_signal(sig: libc::c_int) {
    SIGNAL.store(sig, Ordering::SeqCst);
    COUNT.fetch_add(1, Ordering::SeqCst);
}

/// Name of a signal number.
pub fn name(sig: i32) -> &'static str {
    match sig {
        2 => "SIGINT",
        15 => "SIGTERM",
        _ => "a signal",
    }
}

/// Exit code for a signal: 128 + its number (130 for SIGINT, 143 for SIGTERM).
pub fn exit_code(sig: i32) -> u8 {
    u8::try_from(128 + sig).unwrap_or(1)
}

/// The signal received, if any.
pub fn interrupted() -> Option<i32> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// While alive, a signal asks the current command to stop between units of work rather
/// than ending the process.
pub struct Graceful(());

impl Graceful {
    /// Declare that the caller polls [`interrupted`] and stops cleanly.
    pub fn begin() -> Graceful {
        GRACEFUL.store(true, Ordering::SeqCst);
        Graceful(())
    }
}

impl Drop for Graceful {
    fn drop(&mut self) {
        GRACEFUL.store(false, Ordering::SeqCst);
    }
}

fn end_now(sig: i32, why: &str) -> ! {
    use std::io::Write as _;
    let removed = super::staging::remove_active();
    let kept = if removed.is_empty() {
        String::from("no results were being written")
    } else {
        format!(
            "nothing kept: partial results removed ({})",
            removed
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    let _ = writeln!(
        std::io::stderr(),
        "error: interrupted by {}{why}; {kept}",
        name(sig)
    );
    std::process::exit(i32::from(exit_code(sig)));
}

/// Install the SIGINT and SIGTERM handlers and the watcher thread (once per process).
pub fn install() {
    if INSTALLED.swap(true, Ordering::SeqCst) {
        return;
    }
    #[cfg(unix)]
    // SAFETY: the handler only performs atomic stores, which are async-signal-safe; the
    // sigaction struct is fully initialised (zeroed, then handler and empty mask set).
    unsafe {
        let mut action: libc::sigaction = std::mem::zeroed();
        action.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
        libc::sigemptyset(&mut action.sa_mask);
        action.sa_flags = libc::SA_RESTART;
        libc::sigaction(libc::SIGINT, &action, std::ptr::null_mut());
        libc::sigaction(libc::SIGTERM, &action, std::ptr::null_mut());
    }
    let spawned = std::thread::Builder::new()
        .name("signal-watcher".into())
        .spawn(|| {
            let mut first_seen: Option<Instant> = None;
            loop {
                std::thread::sleep(Duration::from_millis(20));
                let Some(sig) = interrupted() else { continue };
                let since = *first_seen.get_or_insert_with(Instant::now);
                if !GRACEFUL.load(Ordering::SeqCst) {
                    end_now(sig, "");
                }
                if COUNT.load(Ordering::SeqCst) > 1 {
                    end_now(sig, " (second signal)");
                }
                if since.elapsed() > GRACE {
                    end_now(sig, " (cases in flight did not finish in time)");
                }
            }
        });
    // Without the watcher a signal is only recorded; a sweep still stops cleanly.
    drop(spawned);
}
