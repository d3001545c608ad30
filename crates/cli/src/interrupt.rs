//! Ctrl-C (SIGINT, and SIGTERM): stop within a second with exit status
//! 130, leaving no temporary output file behind.
//!
//! The signal handler only sets a flag (async-signal-safe, `signal-hook`).
//! The same flag is the cancel flag of the operator precomputation
//! ([`ferrofmm_fmm::PrecomputeMonitor`]), which checks it between units of
//! work and ends with `FieldError::Cancelled`; the command then exits with
//! status 130 through the normal error path. A watcher thread covers every
//! other moment: outside a precomputation it exits at once, and inside one
//! it gives the cancellation [`GRACE`] before exiting itself; both remove
//! the temporary output files first.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

/// Exit status after an interrupt (128 + SIGINT).
pub const EXIT_INTERRUPTED: u8 = 130;

/// How long a cancelled precomputation may take to stop by itself.
const GRACE: Duration = Duration::from_millis(700);

static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
static IN_PRECOMPUTE: AtomicBool = AtomicBool::new(false);

/// The interrupt flag (set by SIGINT / SIGTERM once [`install`] ran).
pub fn flag() -> Arc<AtomicBool> {
    FLAG.get_or_init(|| Arc::new(AtomicBool::new(false)))
        .clone()
}

/// Install the handlers and start the watcher thread. Without handlers
/// (registration failed) Ctrl-C keeps its default effect.
///
/// `SIGXFSZ` (a write beyond the file size limit, `ulimit -f`) gets a
/// handler that does nothing, so that instead of killing the process (and
/// leaving its temporary file) the write fails with `EFBIG`, which the
/// output code reports and cleans up like any other failed write.
pub fn install() {
    #[cfg(unix)]
    {
        let _ = signal_hook::flag::register(
            signal_hook::consts::SIGXFSZ,
            Arc::new(AtomicBool::new(false)),
        );
    }
    let flag = flag();
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        if signal_hook::flag::register(signal, flag.clone()).is_err() {
            return;
        }
    }
    let _ = std::thread::Builder::new()
        .name("ferrofmm-interrupt".into())
        .spawn(move || watch(&flag));
}

fn watch(flag: &AtomicBool) {
    while !flag.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(20));
    }
    let start = Instant::now();
    while IN_PRECOMPUTE.load(Ordering::Relaxed) && start.elapsed() < GRACE {
        std::thread::sleep(Duration::from_millis(10));
    }
    // Either not in a precomputation (nothing to cancel gracefully), or it
    // did not stop in time (the main thread exits with 130 on its own when
    // it did): end here.
    exit_interrupted();
}

/// Remove the temporary files, say so on stderr and exit with 130.
pub fn exit_interrupted() -> ! {
    remove_temporaries();
    eprintln!("error: interrupted");
    std::process::exit(i32::from(EXIT_INTERRUPTED))
}

/// Marks the operator precomputation as running while alive.
pub struct PrecomputeGuard(());

/// The operator precomputation starts (it ends when the guard drops).
pub fn precomputing() -> PrecomputeGuard {
    IN_PRECOMPUTE.store(true, Ordering::Relaxed);
    PrecomputeGuard(())
}

impl Drop for PrecomputeGuard {
    fn drop(&mut self) {
        IN_PRECOMPUTE.store(false, Ordering::Relaxed);
    }
}

fn remove_temporaries() {
    ferrofmm_io::output::remove_temporaries();
}
