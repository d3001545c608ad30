//! Progress of a build ([`FmmBuilder::setup_progress`](crate::FmmBuilder::setup_progress)):
//! each step of the setup reports how much of it is done, so that a front
//! end can show a bar with the time left for each.
//!
//! The steps run in the order of [`SetupStep`], each from `done = 0` to
//! `done == total`; a step that does not run (no tuning when the order and
//! leaf size are given, no tree for a direct sum) reports nothing. A build of several
//! far-separated clusters runs the tree, operator and layout steps once per
//! cluster with a tree, each from 0 again. Within a step `done` rises from
//! 0 to `total`:
//!
//! - [`SetupStep::Tuning`]: one unit per root weighed by the parameter
//!   search (each a Morton sort of every point and a search over leaf
//!   sizes and orders; see [`tuning::choose_root`](crate::tuning::choose_root)).
//! - [`SetupStep::Tree`]: thousandths of the tree build, at the end of each
//!   of its steps ([`TreeBuildStep::done_share`]).
//! - [`SetupStep::Operators`]: `0 / 1` as it starts, then the operator
//!   precomputation's weighted work units (the
//!   [`PrecomputeProgress`](ferrofmm_field::PrecomputeProgress) of the
//!   [`PrecomputeMonitor`](ferrofmm_field::PrecomputeMonitor)), if it
//!   reports any (operators from the cache, or computed in milliseconds,
//!   may not), and its end.
//! - [`SetupStep::Layout`]: the points and the interaction blocks put in
//!   tree order, from 0 to 1.

use std::fmt;
use std::sync::{Arc, Mutex};

use ferrofmm_tree::TreeBuildStep;

/// A step of a build, in the order they run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SetupStep {
    /// Choosing the order, leaf size and root for a tolerance.
    Tuning,
    /// Building the octree: sort, refine, balance, lists.
    Tree,
    /// Precomputing (or loading) the operators and the M2L scheme.
    Operators,
    /// Points and interaction blocks in tree order.
    Layout,
}

impl SetupStep {
    /// A short lower-case name (`"tuning"`, `"tree"`, `"operators"`,
    /// `"layout"`), as the front ends show it.
    pub fn name(self) -> &'static str {
        match self {
            SetupStep::Tuning => "tuning",
            SetupStep::Tree => "tree",
            SetupStep::Operators => "operators",
            SetupStep::Layout => "layout",
        }
    }
}

/// A snapshot of a build's progress, given to the callback of
/// [`FmmBuilder::setup_progress`](crate::FmmBuilder::setup_progress).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SetupProgress {
    /// The step running.
    pub step: SetupStep,
    /// Units of this step done.
    pub done: u64,
    /// Units of this step in all: with `elapsed` seconds spent in the
    /// step, about `elapsed (total - done) / done` are left of it.
    pub total: u64,
}

/// A build's progress callback.
pub type SetupProgressFn = dyn Fn(SetupProgress) + Send + Sync;

/// Units of the tree step ([`SetupStep::Tree`]).
pub(crate) const TREE_UNITS: u64 = 1000;

/// The last report a [`SetupReporter`] passed on: its step, total and
/// units done.
type LastStep = Arc<Mutex<Option<(SetupStep, u64, u64)>>>;

/// The builder's callback, if any (a cheap clone), and the last step
/// and total it was told (so that a step can be ended on its own total).
#[derive(Clone, Default)]
pub(crate) struct SetupReporter(Option<(Arc<SetupProgressFn>, LastStep)>);

impl fmt::Debug for SetupReporter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(if self.0.is_some() {
            "SetupReporter(callback)"
        } else {
            "SetupReporter(none)"
        })
    }
}

impl SetupReporter {
    pub(crate) fn new(f: Arc<SetupProgressFn>) -> Self {
        Self(Some((f, Arc::default())))
    }

    /// Report `done` of `total` units of `step`.
    ///
    /// Threads (the operator precomputation's) report under one lock, so
    /// the callback is never run twice at once, and a report of the same
    /// step and total below the last one passed on (a thread that counted
    /// before another but reached the lock after it) is dropped: `done`
    /// never falls within a step. A report of 0 always passes (a step
    /// starting again, for the next cluster).
    pub(crate) fn report(&self, step: SetupStep, done: u64, total: u64) {
        if let Some((f, last)) = &self.0 {
            let done = done.min(total);
            let mut last = last.lock().unwrap_or_else(|e| e.into_inner());
            if let Some((s, t, d)) = *last
                && s == step
                && t == total
                && done != 0
                && done < d
            {
                return;
            }
            *last = Some((step, total, done));
            f(SetupProgress { step, done, total });
        }
    }

    /// Report that `step` ended: all of the total it was last told, or
    /// `1 / 1` when it reported nothing since it began.
    pub(crate) fn finish(&self, step: SetupStep) {
        if let Some((_, last)) = &self.0 {
            let total = match *last.lock().unwrap_or_else(|e| e.into_inner()) {
                Some((s, total, _)) if s == step => total,
                _ => 1,
            };
            self.report(step, total, total);
        }
    }

    /// Report the end of a step of the tree build.
    pub(crate) fn tree_step(&self, s: TreeBuildStep) {
        let done = (s.done_share() * TREE_UNITS as f64).round() as u64;
        self.report(SetupStep::Tree, done, TREE_UNITS);
    }

    /// The callback as a precomputation progress callback (operators).
    pub(crate) fn operators(
        &self,
    ) -> Option<impl Fn(ferrofmm_field::PrecomputeProgress) + Send + Sync + 'static> {
        let reporter = self.clone();
        self.0.as_ref().map(|_| {
            move |p: ferrofmm_field::PrecomputeProgress| {
                reporter.report(SetupStep::Operators, p.done, p.total)
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{FmmBuilder, Geometry, charges};
    use std::sync::Mutex;

    /// Every step of a tuned build with the root search reports, in order
    /// (tuning over the three roots, the tree's steps, the operators, the
    /// layout), each rising to its total; the values are those of a build
    /// without a callback, bit for bit.
    #[test]
    fn a_build_reports_each_step_in_order() {
        let n = 6000;
        let points: Vec<f64> = Geometry::Plummer.points(n, 3);
        let q: Vec<f64> = charges(n, 4);
        let build = || {
            FmmBuilder::new(&points)
                .tolerance(1e-4)
                .allow_direct(false)
                .root_search(true)
        };
        let seen = Arc::new(Mutex::new(Vec::new()));
        let log = seen.clone();
        let watched = build()
            .setup_progress(move |p| log.lock().unwrap().push(p))
            .build_svd()
            .unwrap();
        let plain = build().build_svd().unwrap();
        assert_eq!(watched.evaluate(&q).unwrap(), plain.evaluate(&q).unwrap());

        let seen = seen.lock().unwrap().clone();
        let order = |s: SetupStep| s as usize;
        assert!(
            seen.windows(2)
                .all(|w| order(w[0].step) <= order(w[1].step)),
            "steps out of order: {seen:?}"
        );
        for step in [
            SetupStep::Tuning,
            SetupStep::Tree,
            SetupStep::Operators,
            SetupStep::Layout,
        ] {
            let of: Vec<&SetupProgress> = seen.iter().filter(|p| p.step == step).collect();
            assert!(!of.is_empty(), "{step:?} never reported: {seen:?}");
            assert!(of.iter().all(|p| p.done <= p.total && p.total > 0));
            assert!(
                of.windows(2).all(|w| w[0].done <= w[1].done),
                "{step:?} not rising: {of:?}"
            );
            let last = of[of.len() - 1];
            assert_eq!(last.done, last.total, "{step:?} does not end: {of:?}");
        }
        // The three roots of the search, then the end of the tuning.
        let tuning: Vec<(u64, u64)> = seen
            .iter()
            .filter(|p| p.step == SetupStep::Tuning)
            .map(|p| (p.done, p.total))
            .collect();
        assert!(tuning.contains(&(2, 3)), "{tuning:?}");
        let tree = seen.iter().filter(|p| p.step == SetupStep::Tree).count();
        assert_eq!(tree, 1 + TreeBuildStep::ALL.len(), "{seen:?}");
    }
}
