//! Progress of one M2L apply ([`M2lScheme::apply_with_progress`]).
//!
//! [`M2lScheme::apply_with_progress`]: crate::M2lScheme::apply_with_progress

/// Where an M2L apply reports how far it got within a level: a callback
/// told "`done` more parts of `total`" after each piece of work (a chunk
/// of target columns, a task of target groups), from whichever rayon
/// thread did the piece. Over one apply the `done` add up to `total`, and
/// `total` is the same in every call (the scheme picks the unit: pairs,
/// target groups, ...).
///
/// [`M2lProgress::none`] (the default) reports nothing: a scheme should
/// count nothing when [`M2lProgress::is_active`] is false, and report per
/// piece of work, never per box, so that the hook costs nothing without a
/// listener and little with one.
///
/// ```
/// use ferrofmm_field::M2lProgress;
/// use std::sync::atomic::{AtomicU64, Ordering};
/// let seen = AtomicU64::new(0);
/// let report = |done: u64, total: u64| {
///     assert_eq!(total, 10);
///     seen.fetch_add(done, Ordering::Relaxed);
/// };
/// let progress = M2lProgress::new(&report);
/// assert!(progress.is_active());
/// progress.advance(4, 10);
/// progress.advance(6, 10);
/// assert_eq!(seen.load(Ordering::Relaxed), 10);
/// M2lProgress::none().advance(1, 1); // nobody listens
/// ```
#[derive(Clone, Copy, Default)]
pub struct M2lProgress<'a> {
    report: Option<&'a (dyn Fn(u64, u64) + Sync)>,
}

impl<'a> M2lProgress<'a> {
    /// Report nothing.
    pub fn none() -> Self {
        Self { report: None }
    }

    /// Report to `report(done, total)`.
    pub fn new(report: &'a (dyn Fn(u64, u64) + Sync)) -> Self {
        Self {
            report: Some(report),
        }
    }

    /// Whether anyone listens (count nothing otherwise).
    #[inline]
    pub fn is_active(&self) -> bool {
        self.report.is_some()
    }

    /// `done` more parts of `total` are done (nothing without a listener,
    /// or when `done` is 0).
    #[inline]
    pub fn advance(&self, done: u64, total: u64) {
        if let Some(f) = self.report
            && done > 0
        {
            f(done, total);
        }
    }
}

impl std::fmt::Debug for M2lProgress<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("M2lProgress")
            .field("active", &self.is_active())
            .finish()
    }
}
