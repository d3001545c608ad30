//! [`ProgressSink`]: the progress of one Python `evaluate` call, from the
//! FMM passes to the Python callback; [`SetupSink`]: the progress of a
//! build (the `Fmm` constructor's `progress`).

use std::sync::{Arc, Mutex};

use ferrofmm_fmm::{EvalProgress, ProgressFn, SetupProgress, SetupProgressFn};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;

/// A `progress` argument: `None` (or Python's `None`), or a callable; anything
/// else is a `TypeError` naming the `arguments` it is called with.
pub(super) fn callable_or_none<'py>(
    progress: Option<Bound<'py, PyAny>>,
    arguments: &str,
) -> PyResult<Option<Bound<'py, PyAny>>> {
    match progress {
        Some(p) if !p.is_none() => {
            if !p.is_callable() {
                return Err(PyTypeError::new_err(format!(
                    "progress must be a callable taking {arguments} or None, not {}",
                    p.get_type().name()?
                )));
            }
            Ok(Some(p))
        }
        _ => Ok(None),
    }
}

/// The progress of one Python `evaluate` call, written by the FMM passes
/// (any thread) and handed to the Python callback by the calling thread,
/// with the GIL held, when it wakes ([`interruptible_polling`](crate::run::interruptible_polling)).
///
/// Each evaluation of the call (one per charge vector, more when the
/// verification raises the order) reports from 0 to its own total; the
/// sink adds the finished ones so that Python sees one rising count.
pub(super) struct ProgressSink {
    /// Charge vectors of the call.
    n_vectors: u64,
    state: Mutex<SinkState>,
}

#[derive(Default)]
struct SinkState {
    /// Evaluations finished before the current one.
    finished: u64,
    /// Units of the evaluations finished before the current one.
    before: u64,
    /// The current evaluation's report.
    current: EvalProgress,
    /// Whether something new came since the last delivery.
    fresh: bool,
}

impl ProgressSink {
    /// The callback for [`Fmm::set_progress`](ferrofmm_fmm::Fmm::set_progress).
    pub(super) fn callback(self: &Arc<Self>) -> Arc<ProgressFn> {
        let sink = self.clone();
        Arc::new(move |p: EvalProgress| {
            let mut s = sink.state.lock().unwrap_or_else(|e| e.into_inner());
            if p.done == 0 && s.current.done > 0 {
                // A new evaluation starts: the previous one is done.
                s.before += s.current.total;
                s.finished += 1;
            }
            s.current = p;
            s.fresh = true;
        })
    }

    /// A sink for a call of `n_vectors` charge vectors.
    pub(super) fn new(n_vectors: usize) -> Self {
        Self {
            n_vectors: n_vectors as u64,
            state: Mutex::default(),
        }
    }

    /// Call `f(done, total)` when something new came: the total counts
    /// each vector not yet finished as the current one (an order raised by
    /// the verification adds an evaluation, so the total may grow once);
    /// the last report of the call has `done == total`.
    pub(super) fn deliver(&self, f: &Bound<'_, PyAny>) -> PyResult<()> {
        let (done, total) = {
            let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
            if !s.fresh {
                return Ok(());
            }
            s.fresh = false;
            let left = self.n_vectors.saturating_sub(s.finished).max(1);
            (s.before + s.current.done, s.before + left * s.current.total)
        };
        f.call1((done, total)).map(drop)
    }
}

/// The progress of one build, written by the build's steps (any thread)
/// and handed to the Python callback by the calling thread, with the GIL
/// held, when it wakes: `progress(step, done, total)` with the latest
/// report, each step's last one always delivered (so every step a build
/// runs is seen ending with `done == total`).
#[derive(Default)]
pub(super) struct SetupSink {
    /// Reports not yet delivered: the latest of each step, in order.
    pending: Mutex<Vec<SetupProgress>>,
}

impl SetupSink {
    /// The callback for [`FmmBuilder::setup_progress`](ferrofmm_fmm::FmmBuilder::setup_progress).
    pub(super) fn callback(self: &Arc<Self>) -> Arc<SetupProgressFn> {
        let sink = self.clone();
        Arc::new(move |p: SetupProgress| {
            let mut pending = sink.pending.lock().unwrap_or_else(|e| e.into_inner());
            match pending.last_mut() {
                Some(last) if last.step == p.step && p.done >= last.done => *last = p,
                _ => pending.push(p),
            }
        })
    }

    /// Call `f(step, done, total)` for what came since the last delivery.
    pub(super) fn deliver(&self, f: &Bound<'_, PyAny>) -> PyResult<()> {
        let pending = std::mem::take(&mut *self.pending.lock().unwrap_or_else(|e| e.into_inner()));
        for p in pending {
            f.call1((p.step.name(), p.done, p.total))?;
        }
        Ok(())
    }
}
