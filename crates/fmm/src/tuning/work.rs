//! Work counts of a built tree (the cost model's inputs).

use ferrofmm_field::M2lScheme;
use ferrofmm_kernels::{Kernel, Real};
use ferrofmm_tree::Octree;
use rayon::prelude::*;

use super::occupancy::center_ratio;
use crate::Fmm;

/// The work of one evaluation, counted on a tree (exactly, with
/// [`WorkCounts::of_tree`]) or estimated from the point distribution
/// without building one ([`Occupancy::work`](super::Occupancy::work)).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct WorkCounts {
    /// Sources.
    pub n_sources: usize,
    /// Targets.
    pub n_targets: usize,
    /// Deepest level.
    pub depth: u32,
    /// Boxes.
    pub n_boxes: usize,
    /// Leaves.
    pub n_leaves: usize,
    /// Boxes on levels 2 and deeper (columns of the M2L products).
    pub m2l_boxes: usize,
    /// Source-target pairs of the near field (P2P over U lists).
    pub p2p_pairs: f64,
    /// V-list pairs (M2L).
    pub m2l_pairs: f64,
    /// Points evaluated against surfaces beyond P2M and L2P: targets times
    /// W-list boxes (M2P) plus sources of X-list leaves (P2L). Each costs
    /// `n` kernel evaluations like a P2M or L2P point.
    pub far_points: f64,
    /// U-list entries of the leaves (one P2P block each).
    pub u_entries: f64,
    /// `max |center - o| / half-width` over the leaves (Euclidean norm of
    /// the centre relative to the tree's coordinate origin `o`, a point
    /// near the domain that the FMM subtracts in `f64` before rounding to
    /// its float type): how many digits of the coordinates the smallest
    /// boxes need ([`ErrorModel::rounding_floor`](super::ErrorModel::rounding_floor)). A domain far from zero
    /// costs nothing; a small cluster far from the rest of its tree does.
    pub rounding_ratio: f64,
}

impl WorkCounts {
    /// Exact counts of a built FMM's main tree: [`WorkCounts::of_tree`]
    /// with the V-list pairs taken from the FMM's M2L interactions. A built
    /// tree hands its V lists over to them, so `of_tree` on
    /// [`Fmm::tree`] counts no V pairs.
    ///
    /// ```
    /// use ferrofmm_fmm::{FmmBuilder, Geometry, tuning::WorkCounts};
    /// let points: Vec<f64> = Geometry::Cube.points(4000, 1);
    /// let fmm = FmmBuilder::new(&points).order(4).leaf_size(32).build_svd().unwrap();
    /// let work = WorkCounts::of_fmm(&fmm);
    /// assert_eq!(work.m2l_pairs, fmm.summary().list_entries[1] as f64);
    /// assert!(work.m2l_pairs > 0.0);
    /// ```
    pub fn of_fmm<T: Real, K: Kernel, S: M2lScheme<T>>(fmm: &Fmm<T, K, S>) -> Self {
        let main = fmm.main();
        WorkCounts {
            m2l_pairs: main.m2l_pairs() as f64,
            ..Self::of_tree(&main.tree)
        }
    }

    /// Exact counts of a tree (its V pairs from its own V lists: none once
    /// an FMM has taken them; see [`WorkCounts::of_fmm`]).
    pub fn of_tree(tree: &Octree) -> Self {
        let n = tree.n_boxes();
        let (p2p, m2l, far, u) = (0..n)
            .into_par_iter()
            .map(|b| {
                let nt = tree.target_range(b).len() as f64;
                let mut p2p = 0.0;
                let mut u = 0.0;
                if tree.is_leaf(b) && nt > 0.0 {
                    let ns: usize = tree
                        .u_list(b)
                        .iter()
                        .map(|&a| tree.source_range(a).len())
                        .sum();
                    p2p = nt * ns as f64;
                    u = tree.u_list(b).len() as f64;
                }
                let x: usize = tree
                    .x_list(b)
                    .iter()
                    .map(|&a| tree.source_range(a).len())
                    .sum();
                let far = nt * tree.w_list(b).len() as f64 + x as f64;
                (p2p, tree.v_list(b).len() as f64, far, u)
            })
            .reduce(
                || (0.0, 0.0, 0.0, 0.0),
                |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2, a.3 + b.3),
            );
        let domain = tree.domain();
        let rounding_ratio = tree
            .leaves()
            .par_iter()
            .map(|&b| center_ratio(tree.key(b), domain))
            .reduce(|| 0.0, f64::max);
        let depth = tree.depth();
        let top = if depth >= 2 {
            tree.level_range(2).start
        } else {
            n
        };
        WorkCounts {
            n_sources: tree.n_sources(),
            n_targets: tree.n_targets(),
            depth,
            n_boxes: n,
            n_leaves: tree.leaves().len(),
            m2l_boxes: n - top,
            p2p_pairs: p2p,
            m2l_pairs: m2l,
            far_points: far,
            u_entries: u,
            rounding_ratio,
        }
    }
}
