//! A direct sum instead of the FMM where it is predicted cheaper
//! ([`Tuner::prefer_direct`]).

use crate::tuning::error_model::estimated_svd_rank;
use crate::tuning::work::WorkCounts;

use super::{ChosenParameters, Tuner};

impl Tuner {
    /// Predicted seconds of summing every source on every target directly
    /// (the P2P rate of the cost model, on the same threads):
    /// `p2p_pair N_s N_t + p2p_entry`.
    pub fn direct_seconds(&self, n_sources: usize, n_targets: usize) -> f64 {
        self.cost.p2p_pair * n_sources as f64 * n_targets as f64 + self.cost.p2p_entry
    }

    /// Turn `chosen` into a direct sum when that is predicted cheaper than
    /// its tree, its evaluation and `precompute` seconds of operators
    /// (what [`precompute_seconds`](crate::tuning::precompute_seconds) predicts, 0 when they are cached).
    /// A direct sum is one leaf holding every point: no far field, no
    /// operators beyond the lowest order's (built at
    /// [`MIN_ORDER`](ferrofmm_field::MIN_ORDER)), exact to rounding
    /// (`predicted_error` 0).
    pub fn prefer_direct(
        &self,
        mut chosen: ChosenParameters,
        n_sources: usize,
        n_targets: usize,
        precompute: f64,
    ) -> ChosenParameters {
        let direct = self.direct_seconds(n_sources, n_targets);
        chosen.direct_seconds = Some(direct);
        chosen.precompute_seconds = precompute;
        if direct < chosen.predicted_seconds + precompute {
            chosen.direct = true;
            chosen.order = ferrofmm_field::MIN_ORDER;
            chosen.leaf_size = n_sources.max(n_targets).max(1);
            chosen.svd_tolerance = self.error.base_svd_tolerance(chosen.order);
            chosen.estimated_svd_rank = estimated_svd_rank(chosen.order, chosen.svd_tolerance);
            chosen.predicted_error = 0.0;
            chosen.estimated_work = WorkCounts {
                n_sources,
                n_targets,
                n_boxes: 1,
                n_leaves: 1,
                p2p_pairs: n_sources as f64 * n_targets as f64,
                u_entries: 1.0,
                ..WorkCounts::default()
            };
        }
        chosen
    }
}
