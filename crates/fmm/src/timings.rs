//! Wall-clock timings of setup and evaluation, per operator.

use std::time::Duration;

/// Time spent building an [`crate::Fmm`].
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct SetupTimings {
    /// Choosing the parameters for a tolerance (the occupancy pre-pass of
    /// [`crate::tuning`]; zero when the parameters were given).
    pub tuning: Duration,
    /// Octree: sort, refine, 2:1 balance, interaction lists.
    pub tree: Duration,
    /// Check/equivalent pseudo-inverses and M2M/L2L operators, and finding
    /// the transfer vectors the tree's V lists use.
    pub operators: Duration,
    /// M2L scheme precomputation (or cache load).
    pub m2l_precompute: Duration,
    /// Sorting points and charges-independent bookkeeping.
    pub layout: Duration,
    /// Everything above.
    pub total: Duration,
}

/// Time spent in one call of [`crate::Fmm::evaluate_timed`], per operator.
///
/// The passes run one after another (each one parallel inside), so the
/// fields add up to `total` up to bookkeeping.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct EvalTimings {
    /// Sources to upward check surfaces of leaves, then check-to-equivalent.
    pub p2m: Duration,
    /// Children's multipoles to parents.
    pub m2m: Duration,
    /// Multipole to local over V lists (the M2L scheme).
    pub m2l: Duration,
    /// Sources of X-list leaves to downward check surfaces.
    pub p2l: Duration,
    /// Downward check-to-equivalent and parents' locals to children.
    pub l2l: Duration,
    /// Local expansions of leaves to their targets.
    pub l2p: Duration,
    /// Multipoles of W-list boxes to targets.
    pub m2p: Duration,
    /// Direct interactions over U lists (and inside small far clusters).
    pub p2p: Duration,
    /// Interactions between far-separated clusters (root expansions or
    /// direct sums; see [`Fmm::n_clusters`](crate::Fmm::n_clusters));
    /// zero for a problem that is one cluster.
    pub coupling: Duration,
    /// The whole evaluation, permutations included.
    pub total: Duration,
}

impl EvalTimings {
    /// `(name, duration)` for every operator, in pass order.
    pub fn operators(&self) -> [(&'static str, Duration); 9] {
        [
            ("P2M", self.p2m),
            ("M2M", self.m2m),
            ("M2L", self.m2l),
            ("P2L", self.p2l),
            ("L2L", self.l2l),
            ("L2P", self.l2p),
            ("M2P", self.m2p),
            ("P2P", self.p2p),
            ("Far", self.coupling),
        ]
    }

    /// Add another call's timings (for averaging over several calls).
    pub fn accumulate(&mut self, other: &EvalTimings) {
        self.p2m += other.p2m;
        self.m2m += other.m2m;
        self.m2l += other.m2l;
        self.p2l += other.p2l;
        self.l2l += other.l2l;
        self.l2p += other.l2p;
        self.m2p += other.m2p;
        self.p2p += other.p2p;
        self.coupling += other.coupling;
        self.total += other.total;
    }
}
