//! Progress of an evaluation: a callback ([`Fmm::set_progress`](crate::Fmm::set_progress))
//! told how much of the work is done, so that a front end can show a bar
//! with the time left.
//!
//! The work is counted in rough cost units fixed before the passes run:
//! a kernel evaluation (one source at one target) is one unit, a matrix
//! entry applied (the translations and check-to-equivalent operators)
//! [`MATRIX_ENTRY`] units. The passes add their units when a pass (or a
//! level of the downward pass) ends; P2P, usually the longest, adds them
//! per block of targets. Nothing is counted without a callback, and the
//! callback runs only when the done fraction moves by 1/1000 or more.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use ferrofmm_field::M2lScheme;
use ferrofmm_kernels::Real;

use crate::part::TreePart;

/// A snapshot of an evaluation's progress, given to the callback of
/// [`Fmm::set_progress`](crate::Fmm::set_progress).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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
}

impl<'a> Work<'a> {
    /// A counter that reports nothing (and counts nothing).
    pub(crate) fn none() -> Self {
        Self {
            callback: None,
            done: AtomicU64::new(0),
            total: 0,
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

    fn report(&self, done: u64) {
        if let Some(f) = self.callback {
            f(EvalProgress {
                done: done.min(self.total),
                total: self.total,
            });
        }
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

/// M2L, P2L and L2L of one level of a tree part.
pub(crate) fn level_units<T: Real, S: M2lScheme<T>>(part: &TreePart<T, S>, level: u32) -> u64 {
    let n = part.operators.n_surface();
    let tree = &part.tree;
    let r = tree.level_range(level);
    let m2l = part
        .m2l_interactions
        .get(level as usize)
        .map_or(0, |i| i.len());
    let p2l: u64 = r.clone().map(|b| sources_of(part, tree.x_list(b))).sum();
    matrix(n * n * (m2l + 2 * r.len())) + n as u64 * p2l
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
}
