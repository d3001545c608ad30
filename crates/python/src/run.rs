//! Running library work off the Python thread: the GIL released, signals
//! handled, an optional thread pool.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use rayon::ThreadPool;

/// How often the waiting Python thread wakes to handle signals.
const SIGNAL_POLL: Duration = Duration::from_millis(100);

/// Where the work runs: rayon's global pool, or a pool of a given size.
#[derive(Clone, Default)]
pub(crate) struct Threads(Option<Arc<ThreadPool>>);

impl Threads {
    /// `None`: `RAYON_NUM_THREADS` when set to a positive integer (lowered
    /// to the cores as below), else rayon's global pool (one thread per
    /// core); any other value of `RAYON_NUM_THREADS` (`abc`, `-2`) is
    /// ignored with a `RuntimeWarning` that says so (rayon itself ignores
    /// it silently). `Some(t)`: a pool of `t` threads, lowered to the
    /// number of cores (more threads than cores only slow the passes down,
    /// as on the command line).
    pub(crate) fn new(py: Python<'_>, threads: Option<usize>) -> PyResult<Self> {
        let threads = match threads {
            Some(t) => Some(t),
            None => env_threads(py)?,
        };
        let Some(t) = threads else {
            return Ok(Threads(None));
        };
        if t == 0 {
            return Err(pyo3::exceptions::PyValueError::new_err(
                "threads must be at least 1 (or None for one per core)",
            ));
        }
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(t.min(cores))
            .thread_name(|i| format!("ferrofmm-{i}"))
            .build()
            .map_err(|e| PyRuntimeError::new_err(format!("cannot start {t} threads: {e}")))?;
        Ok(Threads(Some(Arc::new(pool))))
    }

    /// Number of threads the work runs on.
    pub(crate) fn count(&self) -> usize {
        match &self.0 {
            Some(p) => p.current_num_threads(),
            None => rayon::current_num_threads(),
        }
    }
}

/// Name of rayon's thread-count variable.
const RAYON_ENV: &str = "RAYON_NUM_THREADS";

/// `RAYON_NUM_THREADS` as a thread count: `None` when unset, empty or 0
/// (rayon's "one per core"), with a `RuntimeWarning` when it is not a
/// number of threads.
fn env_threads(py: Python<'_>) -> PyResult<Option<usize>> {
    let Some(raw) = std::env::var_os(RAYON_ENV) else {
        return Ok(None);
    };
    let text = raw.to_string_lossy();
    match text.trim().parse::<usize>() {
        Ok(0) => Ok(None),
        Ok(t) => Ok(Some(t)),
        Err(_) if text.trim().is_empty() => Ok(None),
        Err(_) => {
            let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
            let message = format!(
                "{RAYON_ENV}={text:?} is not a number of threads: ignored, using one thread per \
                 core ({cores}); set it to a positive integer or pass threads="
            );
            PyErr::warn(
                py,
                &py.get_type::<pyo3::exceptions::PyRuntimeWarning>(),
                &std::ffi::CString::new(message).unwrap_or_default(),
                1,
            )?;
            Ok(None)
        }
    }
}

/// Run `job` on a worker thread (inside the pool of `threads`) while the
/// calling thread waits with the GIL released, waking every
/// [`SIGNAL_POLL`] to run Python's signal handlers. When a handler raises
/// (Ctrl-C: `KeyboardInterrupt`), `cancel` is set (a precomputation that
/// watches it stops within a fraction of a second), the exception is
/// returned at once and the job's result, when it comes, is dropped. A
/// panicking job becomes a `RuntimeError`, never a crash of the
/// interpreter.
pub(crate) fn interruptible<R, F>(
    py: Python<'_>,
    threads: &Threads,
    cancel: Option<&Arc<AtomicBool>>,
    job: F,
) -> PyResult<R>
where
    R: Send + 'static,
    F: FnOnce() -> R + Send + 'static,
{
    interruptible_polling(py, threads, cancel, job, |_| Ok(()))
}

/// [`interruptible`], also running `poll` with the GIL held at each wake
/// (every [`SIGNAL_POLL`] at most, so a bounded rate) and once when the
/// job ends, before its result is returned. An error from `poll` is
/// returned at once, as an interrupt is (the job's result is dropped).
pub(crate) fn interruptible_polling<R, F>(
    py: Python<'_>,
    threads: &Threads,
    cancel: Option<&Arc<AtomicBool>>,
    job: F,
    mut poll: impl FnMut(Python<'_>) -> PyResult<()>,
) -> PyResult<R>
where
    R: Send + 'static,
    F: FnOnce() -> R + Send + 'static,
{
    let (tx, rx) = mpsc::channel();
    let pool = threads.0.clone();
    std::thread::Builder::new()
        .name("ferrofmm-call".into())
        .spawn(move || {
            let result = match pool {
                Some(p) => p.install(job),
                None => job(),
            };
            // The caller may have gone (interrupted): nothing to deliver.
            let _ = tx.send(result);
        })
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start a worker thread: {e}")))?;
    let mut rx = rx;
    loop {
        let (back, received) = py.detach(move || {
            let r = rx.recv_timeout(SIGNAL_POLL);
            (rx, r)
        });
        rx = back;
        match received {
            Ok(result) => {
                poll(py)?;
                return Ok(result);
            }
            Err(RecvTimeoutError::Timeout) => {
                if let Err(e) = py.check_signals().and_then(|()| poll(py)) {
                    if let Some(flag) = cancel {
                        flag.store(true, Ordering::Relaxed);
                    }
                    return Err(e);
                }
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(PyRuntimeError::new_err(
                    "internal error: the ferrofmm worker thread panicked (a bug in ferrofmm)",
                ));
            }
        }
    }
}
