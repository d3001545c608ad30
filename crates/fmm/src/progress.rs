//! Progress of an evaluation: a callback ([`Fmm::set_progress`](crate::Fmm::set_progress))
//! told how much of the work is done, so that a front end can show a bar
//! with the time left.
//!
//! The work is counted in rough cost units fixed before the passes run:
//! a kernel evaluation (one source at one target) is one unit, a matrix
//! entry applied (the translations and check-to-equivalent operators)
//! [`MATRIX_ENTRY`] units. The passes add their units when a pass (or a
//! level of the downward pass) ends; the M2L, as its scheme reports its
//! pieces ([`M2lScheme::apply_with_progress`]); P2P, usually the longest,
//! per block of targets. Nothing is counted without a callback, and the
//! callback runs only when the done fraction moves by 1/1000 or more.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use ferrofmm_field::M2lScheme;
use ferrofmm_kernels::Real;

use crate::part::TreePart;

/// A snapshot of an evaluation's progress, given to the callback of
/// [`Fmm::set_progress`](crate::Fmm::set_progress).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EvalProgress {
    /// Work units done (each pass weighted by its estimated cost).
    pub done: u64,
    /// Work units in all; the remaining time is about
    /// `elapsed (total - done) / done`.
    pub total: u64,
}

/// An evaluation's progress callback.
pub type ProgressFn = dyn Fn(EvalProgress) + Send + Sync;

/// Cost of one matrix entry applied, in kernel evaluations (a kernel
/// evaluation costs some ten flops, a matrix entry two).
pub(crate) const MATRIX_ENTRY: f64 = 0.2;

/// Steps of the done fraction at which the callback runs.
const STEPS: u64 = 1000;

/// The work counter of one evaluation.
pub(crate) struct Work<'a> {
    callback: Option<&'a ProgressFn>,
    done: AtomicU64,
    total: u64,
    /// The last `done` reported: threads that cross a step at once report
    /// under this lock, never a smaller value after a larger one.
    reported: Mutex<u64>,
}

impl<'a> Work<'a> {
    /// A counter that reports nothing (and counts nothing).
    pub(crate) fn none() -> Self {
        Self {
            callback: None,
            done: AtomicU64::new(0),
            total: 0,
            reported: Mutex::new(0),
        }
    }

    /// A counter of `total` units reporting to `callback` (`total` is
    /// computed only when there is a callback).
    pub(crate) fn new(callback: Option<&'a Arc<ProgressFn>>, total: impl FnOnce() -> u64) -> Self {
        match callback {
            Some(f) => {
                let work = Self {
                    callback: Some(f.as_ref()),
                    done: AtomicU64::new(0),
                    total: total().max(1),
                    reported: Mutex::new(0),
                };
                work.report(0);
                work
            }
            None => Self::none(),
        }
    }

    /// Whether anyone listens (the passes skip counting otherwise).
    pub(crate) fn active(&self) -> bool {
        self.callback.is_some()
    }

    /// Count `units` more done.
    pub(crate) fn add(&self, units: u64) {
        if !self.active() || units == 0 {
            return;
        }
        let before = self.done.fetch_add(units, Ordering::Relaxed);
        let after = before + units;
        if before * STEPS / self.total != after * STEPS / self.total {
            self.report(after);
        }
    }

    /// Count `units` more done, computed only when someone listens.
    pub(crate) fn add_with(&self, units: impl FnOnce() -> u64) {
        if self.active() {
            self.add(units());
        }
    }

    /// Everything done (the estimates are rough: the bar ends full).
    pub(crate) fn finish(&self) {
        if self.active() {
            self.report(self.total);
        }
    }

    /// A share of `units` of this counter for one M2L apply, counted as
    /// the scheme reports its pieces ([`M2lProgress`](ferrofmm_field::M2lProgress)).
    pub(crate) fn share(&self, units: u64) -> Share<'_, 'a> {
        Share {
            work: self,
            units,
            parts: AtomicU64::new(0),
            total: AtomicU64::new(0),
        }
    }

    fn report(&self, done: u64) {
        if let Some(f) = self.callback {
            let done = done.min(self.total);
            let mut last = self.reported.lock().unwrap_or_else(|e| e.into_inner());
            if done < *last {
                return;
            }
            *last = done;
            f(EvalProgress {
                done,
                total: self.total,
            });
        }
    }
}

/// `units` of a [`Work`] handed out in parts: the M2L scheme says
/// "`done` more parts of `total`" and the share adds the units in
/// proportion; [`Share::finish`] adds what the scheme did not report.
pub(crate) struct Share<'w, 'a> {
    work: &'w Work<'a>,
    units: u64,
    parts: AtomicU64,
    /// The scheme's `total` (0 until it reports).
    total: AtomicU64,
}

impl Share<'_, '_> {
    /// Units of the first `parts` of `total`.
    fn units_of(&self, parts: u64, total: u64) -> u64 {
        (self.units as u128 * parts.min(total) as u128 / total.max(1) as u128) as u64
    }

    /// `done` more parts of `total` are done.
    pub(crate) fn advance(&self, done: u64, total: u64) {
        self.total.store(total, Ordering::Relaxed);
        let before = self.parts.fetch_add(done, Ordering::Relaxed);
        let after = before.saturating_add(done);
        self.work
            .add(self.units_of(after, total) - self.units_of(before, total));
    }

    /// The apply ended: its units are all done.
    pub(crate) fn finish(&self) {
        let total = self.total.load(Ordering::Relaxed);
        let reported = if total == 0 {
            0
        } else {
            self.units_of(self.parts.load(Ordering::Relaxed), total)
        };
        self.work.add(self.units - reported);
    }
}

/// `entries` matrix entries in work units.
fn matrix(entries: usize) -> u64 {
    (entries as f64 * MATRIX_ENTRY).ceil() as u64
}

/// Sources of the boxes `list`.
fn sources_of<T: Real, S>(part: &TreePart<T, S>, list: &[usize]) -> u64 {
    list.iter()
        .map(|&a| part.tree.source_range(a).len() as u64)
        .sum()
}

/// P2M and M2M of a tree part.
pub(crate) fn upward_units<T: Real, S: M2lScheme<T>>(part: &TreePart<T, S>) -> u64 {
    let n = part.operators.n_surface() as u64;
    let tree = &part.tree;
    let p2m = n * sources_of(part, tree.leaves());
    p2m + matrix(n as usize * n as usize * tree.n_boxes())
}

/// M2L of one level of a tree part.
pub(crate) fn m2l_units<T: Real, S: M2lScheme<T>>(part: &TreePart<T, S>, level: u32) -> u64 {
    let n = part.operators.n_surface();
    let m2l = part
        .m2l_interactions
        .get(level as usize)
        .map_or(0, |i| i.len());
    matrix(n * n * m2l)
}

/// M2L, P2L and L2L of one level of a tree part.
pub(crate) fn level_units<T: Real, S: M2lScheme<T>>(part: &TreePart<T, S>, level: u32) -> u64 {
    let n = part.operators.n_surface();
    let tree = &part.tree;
    let r = tree.level_range(level);
    let p2l: u64 = r.clone().map(|b| sources_of(part, tree.x_list(b))).sum();
    m2l_units(part, level) + matrix(n * n * 2 * r.len()) + n as u64 * p2l
}

/// The downward pass of a tree part (every level).
pub(crate) fn downward_units<T: Real, S: M2lScheme<T>>(part: &TreePart<T, S>) -> u64 {
    (part.operators.first_level().max(1)..=part.tree.depth())
        .map(|level| level_units(part, level))
        .sum()
}

/// L2P and M2P of the leaf `b` (`targets` of them).
pub(crate) fn l2p_m2p_units<T: Real, S>(part: &TreePart<T, S>, n: usize, b: usize) -> u64 {
    let targets = part.tree.target_range(b).len() as u64;
    n as u64 * targets * (1 + part.tree.w_list(b).len() as u64)
}

/// P2P of `targets` targets of the leaf `b`.
pub(crate) fn p2p_units<T: Real, S>(part: &TreePart<T, S>, b: usize, targets: usize) -> u64 {
    targets as u64 * sources_of(part, part.tree.u_list(b))
}

/// The leaf passes of a tree part.
pub(crate) fn leaf_units<T: Real, S: M2lScheme<T>>(part: &TreePart<T, S>) -> u64 {
    let n = part.operators.n_surface();
    let tree = &part.tree;
    tree.leaves()
        .iter()
        .map(|&b| {
            let targets = tree.target_range(b).len();
            l2p_m2p_units(part, n, b) + p2p_units(part, b, targets)
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{FmmBuilder, Geometry, charges};
    use std::sync::Mutex;

    /// The passes report from 0 to the total, at most about once per
    /// thousandth, and the values are those of an evaluation without a
    /// callback, bit for bit.
    #[test]
    fn an_evaluation_reports_its_progress_and_changes_nothing() {
        let n = 4000;
        let points: Vec<f64> = Geometry::Cube.points(n, 3);
        let q: Vec<f64> = charges(n, 4);
        let mut fmm = FmmBuilder::new(&points)
            .order(3)
            .leaf_size(32)
            .build_dense()
            .unwrap();
        let plain = fmm.evaluate(&q).unwrap();
        let seen = Arc::new(Mutex::new(Vec::new()));
        let log = seen.clone();
        fmm.set_progress(Some(Arc::new(move |p: EvalProgress| {
            log.lock().unwrap().push(p);
        })));
        let watched = fmm.evaluate(&q).unwrap();
        assert_eq!(plain, watched);

        let seen = seen.lock().unwrap().clone();
        let total = seen[0].total;
        assert!(total > 1, "{seen:?}");
        assert!(seen.iter().all(|p| p.total == total && p.done <= total));
        assert_eq!(seen.first().map(|p| p.done), Some(0));
        assert_eq!(seen.iter().map(|p| p.done).max(), Some(total));
        assert!(
            seen.len() > 3 && seen.len() <= STEPS as usize + 2,
            "{}",
            seen.len()
        );

        fmm.set_progress(None);
        assert_eq!(fmm.evaluate(&q).unwrap(), plain);
    }

    /// The progress of each scheme's evaluation moves in small steps within
    /// the M2L (the schemes report per chunk or task), rises monotonically
    /// and ends at the total: no single report jumps by a large share of
    /// the work, as the M2L of a whole level did when it was counted at
    /// the level's end.
    #[test]
    fn the_m2l_reports_within_a_level() {
        // One thread: chunks that end together on two threads may reach
        // the callback as one step (the earlier value is not reported
        // after the later), which would measure the threads, not the
        // reporting. The many-thread order is checked above.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        pool.install(m2l_reports_within_a_level_on_this_pool);
    }

    fn m2l_reports_within_a_level_on_this_pool() {
        use ferrofmm_field::FftM2l;

        fn steps<K: ferrofmm_kernels::Kernel, S: M2lScheme<f64>>(
            fmm: &mut crate::Fmm<f64, K, S>,
        ) -> Vec<u64> {
            let n = fmm.n_sources();
            let q: Vec<f64> = charges(n, 5);
            let seen = Arc::new(Mutex::new(Vec::new()));
            let log = seen.clone();
            fmm.set_progress(Some(Arc::new(move |p: EvalProgress| {
                log.lock().unwrap().push(p);
            })));
            let plain = fmm.evaluate(&q).unwrap();
            fmm.set_progress(None);
            assert_eq!(
                fmm.evaluate(&q).unwrap(),
                plain,
                "same values without a callback"
            );
            let seen = seen.lock().unwrap().clone();
            let total = seen[0].total;
            assert!(seen.iter().all(|p| p.total == total));
            let done: Vec<u64> = seen.iter().map(|p| p.done).collect();
            assert!(
                done.windows(2).all(|w| w[0] <= w[1]),
                "not monotone: {done:?}"
            );
            assert_eq!(done.first(), Some(&0));
            assert_eq!(done.last(), Some(&total));
            done
        }

        let n = 30_000;
        let points: Vec<f64> = Geometry::Cube.points(n, 7);
        let build = || FmmBuilder::new(&points).order(5).leaf_size(32);
        let mut fft = build()
            .build_with::<FftM2l<f64>>(Default::default())
            .unwrap();
        let mut dense = build().build_dense().unwrap();
        let mut svd = build().build_svd().unwrap();
        for (name, done) in [
            ("fft", steps(&mut fft)),
            ("dense", steps(&mut dense)),
            ("svd", steps(&mut svd)),
        ] {
            let total = *done.last().unwrap();
            let largest = done.windows(2).map(|w| w[1] - w[0]).max().unwrap();
            let mut distinct = done.clone();
            distinct.dedup();
            // The FFT scheme reports per task of at most 16 target groups;
            // the others per chunk of 32 to 256 target boxes, fewer here.
            let many = if name == "fft" { 50 } else { 20 };
            assert!(
                largest * 10 < total && distinct.len() > many,
                "{name}: largest step {largest} of {total}, {} distinct values",
                distinct.len()
            );
        }
    }
}
