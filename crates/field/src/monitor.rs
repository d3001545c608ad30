//! Observing and cancelling a long precomputation: the progress callback
//! and cancel flag of [`PrecomputeMonitor`], and the weighted work counter
//! ([`Units`]) the builders report to.
//!
//! A precomputation of `total` work units (each weighted by its rough cost:
//! one kernel matrix, one block factorisation) reports `done / total` after
//! every unit; with `elapsed` seconds spent the remaining time is about
//! `elapsed (total - done) / done`. Uses only [`FieldError`].

use std::fmt;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use crate::FieldError;

/// A snapshot of a precomputation's progress, given to the callback of a
/// [`PrecomputeMonitor`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PrecomputeProgress {
    /// Work units done (weighted by their cost, see `total`).
    pub done: u64,
    /// Work units in all; `done / total` is the fraction done, so the
    /// remaining time is about `elapsed (total - done) / done`.
    pub total: u64,
}

type ProgressFn = dyn Fn(PrecomputeProgress) + Send + Sync;

/// Observes and controls a long operator precomputation: a progress
/// callback, called from worker threads after each unit of work (one
/// kernel matrix, one block factorisation), and a cancel flag, checked
/// between units (and between the column panels of a factorisation), so
/// that setting it ends the precomputation within a fraction of a second
/// with [`FieldError::Cancelled`].
///
/// Cloning shares the flag and the callback. The default monitor reports
/// nothing and cannot be cancelled.
///
/// ```
/// use std::sync::Arc;
/// use std::sync::atomic::{AtomicBool, Ordering};
/// use ferrofmm_field::{DenseM2l, DenseConfig, FieldError, M2lScheme, M2lUsage, OperatorParams, PrecomputeMonitor};
/// use ferrofmm_kernels::Laplace3d;
/// let cancel = Arc::new(AtomicBool::new(true));
/// let mut params = OperatorParams::new(3);
/// params.monitor = PrecomputeMonitor::new().with_cancel_flag(cancel.clone());
/// let r = DenseM2l::<f64>::precompute_for(&Laplace3d, &params, &DenseConfig, 1.0, 3, &M2lUsage::all(3));
/// assert!(matches!(r, Err(FieldError::Cancelled)));
/// ```
#[derive(Clone, Default)]
pub struct PrecomputeMonitor {
    cancel: Option<Arc<AtomicBool>>,
    progress: Option<Arc<ProgressFn>>,
}

impl PrecomputeMonitor {
    /// No callback, no cancel flag.
    pub fn new() -> Self {
        Self::default()
    }

    /// Cancel when `flag` becomes true (e.g. set by a Ctrl-C handler).
    pub fn with_cancel_flag(mut self, flag: Arc<AtomicBool>) -> Self {
        self.cancel = Some(flag);
        self
    }

    /// Call `f` after each unit of work.
    pub fn with_progress(mut self, f: impl Fn(PrecomputeProgress) + Send + Sync + 'static) -> Self {
        self.progress = Some(Arc::new(f));
        self
    }

    /// Call `f` after each unit of work as well as the callback already
    /// set (if any): how a driver adds its own report to a caller's
    /// monitor.
    ///
    /// ```
    /// use std::sync::Arc;
    /// use std::sync::atomic::{AtomicU64, Ordering};
    /// use ferrofmm_field::{DenseM2l, DenseConfig, M2lScheme, M2lUsage, OperatorParams, PrecomputeMonitor};
    /// use ferrofmm_kernels::Laplace3d;
    /// let (first, second) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicU64::new(0)));
    /// let (a, b) = (first.clone(), second.clone());
    /// let mut params = OperatorParams::new(3);
    /// params.monitor = PrecomputeMonitor::new()
    ///     .with_progress(move |_| {
    ///         a.fetch_add(1, Ordering::Relaxed);
    ///     })
    ///     .and_progress(move |_| {
    ///         b.fetch_add(1, Ordering::Relaxed);
    ///     });
    /// DenseM2l::<f64>::precompute_for(&Laplace3d, &params, &DenseConfig, 1.0, 3, &M2lUsage::all(3))
    ///     .unwrap();
    /// let n = first.load(Ordering::Relaxed);
    /// assert!(n > 0);
    /// assert_eq!(second.load(Ordering::Relaxed), n);
    /// ```
    pub fn and_progress(self, f: impl Fn(PrecomputeProgress) + Send + Sync + 'static) -> Self {
        match self.progress.clone() {
            None => self.with_progress(f),
            Some(first) => self.with_progress(move |p| {
                first(p);
                f(p);
            }),
        }
    }

    /// Whether cancellation was asked for.
    pub fn is_cancelled(&self) -> bool {
        self.cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
    }

    /// `Err(FieldError::Cancelled)` once cancellation was asked for.
    pub fn check(&self) -> Result<(), FieldError> {
        if self.is_cancelled() {
            Err(FieldError::Cancelled)
        } else {
            Ok(())
        }
    }

    /// A counter of `total` units reporting to this monitor.
    pub(crate) fn units(&self, total: u64) -> Units<'_> {
        let units = Units {
            monitor: self,
            done: AtomicU64::new(0),
            total,
        };
        units.report(0);
        units
    }
}

impl fmt::Debug for PrecomputeMonitor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("PrecomputeMonitor")
            .field("cancel", &self.cancel)
            .field("progress", &self.progress.as_ref().map(|_| "Fn"))
            .finish()
    }
}

/// Monitors observe a computation and take no part in its result: any two
/// compare equal (so [`OperatorParams`](crate::OperatorParams) compare by
/// what they compute).
impl PartialEq for PrecomputeMonitor {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// Progress counter of one precomputation.
pub(crate) struct Units<'a> {
    monitor: &'a PrecomputeMonitor,
    done: AtomicU64,
    total: u64,
}

impl Units<'_> {
    /// `Err(Cancelled)` when cancelled.
    pub fn check(&self) -> Result<(), FieldError> {
        self.monitor.check()
    }

    /// Whether cancellation was asked for.
    pub fn cancelled(&self) -> bool {
        self.monitor.is_cancelled()
    }

    /// Count `n` more units done, then check for cancellation.
    pub fn add(&self, n: u64) -> Result<(), FieldError> {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        self.report(done);
        self.check()
    }

    fn report(&self, done: u64) {
        if let Some(f) = &self.monitor.progress {
            f(PrecomputeProgress {
                done: done.min(self.total),
                total: self.total,
            });
        }
    }
}
