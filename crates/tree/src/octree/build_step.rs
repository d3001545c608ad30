//! The steps of a tree build ([`Octree::new_reporting`](super::Octree::new_reporting)),
//! with the share of the build's time each takes, so that a caller can
//! turn them into a bar with the time left.

/// A step of [`Octree::new_reporting`](super::Octree::new_reporting), reported as it ends; the
/// steps come in the order of [`TreeBuildStep::ALL`], each once.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TreeBuildStep {
    /// Options and coordinates checked, the domain found.
    Checked,
    /// Morton keys of every point computed and sorted (the points in
    /// Morton order).
    Sorted,
    /// Boxes refined down to the leaf size (or the uniform depth).
    Refined,
    /// 2:1 balance (a no-op for uniform or unbalanced trees).
    Balanced,
    /// Boxes flattened into (level, Morton) order; colleague table built.
    Colleagues,
    /// U, V, W and X interaction lists built: the tree is done.
    Lists,
}

impl TreeBuildStep {
    /// Every step, in the order they are reported.
    pub const ALL: [TreeBuildStep; 6] = [
        TreeBuildStep::Checked,
        TreeBuildStep::Sorted,
        TreeBuildStep::Refined,
        TreeBuildStep::Balanced,
        TreeBuildStep::Colleagues,
        TreeBuildStep::Lists,
    ];

    /// The share of a build's wall time done when this step ends, in
    /// `(0, 1]` and rising with the steps (`Lists` is 1). Measured at
    /// 1e7 points, leaves of 192, 2 threads (`examples/tree_timing.rs`
    /// prints it): sorting ends at 0.66-0.70 of the time on a cube, a
    /// sphere and clusters; at 1e6 (leaves of 64) at 0.31-0.53, so a bar
    /// drawn from these shares is an estimate, best for the large trees
    /// that need one.
    pub fn done_share(self) -> f64 {
        match self {
            TreeBuildStep::Checked => 0.03,
            TreeBuildStep::Sorted => 0.62,
            TreeBuildStep::Refined => 0.68,
            TreeBuildStep::Balanced => 0.72,
            TreeBuildStep::Colleagues => 0.77,
            TreeBuildStep::Lists => 1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shares_rise_to_one() {
        let shares: Vec<f64> = TreeBuildStep::ALL.iter().map(|s| s.done_share()).collect();
        assert!(shares.windows(2).all(|w| w[0] < w[1]), "{shares:?}");
        assert!(shares[0] > 0.0);
        assert_eq!(shares[5], 1.0);
    }
}
