//! Load balance: each rank gets one contiguous range of finest Morton codes,
//! `[cuts[r], cuts[r + 1])`, cut only at boundaries of leaves.
//!
//! # Where to cut
//!
//! After the [sort](crate::sort) the points are in global Morton order. The
//! ideal cut `k` (`k = 1 .. R - 1`) is at cumulative weight `k W / R` (`W`
//! the total weight; the weight of a point is 1 by default). Let `c_k` be the
//! code of the point at that position. A cut must not split a box that the
//! refinement would leave as a leaf: that box's refinement would depend on
//! points of two ranks. So the cut is moved to a boundary of `B_k`, the
//! leaf of the (unbalanced) adaptive refinement of all points that holds
//! `c_k`: the coarsest ancestor of `c_k`'s finest cell holding at most
//! `leaf_size` points (or the box at `max_level`; with separate targets,
//! at most `leaf_size` sources and at most `leaf_size` targets, the tree
//! crate's rule for two point sets). All its strict ancestors
//! hold more than `leaf_size` points, so they are split, and `B_k` is a
//! leaf. The cut goes to `B_k`'s start or its end, whichever is closer in
//! weight to `k W / R`; a cut is thus at most one leaf (`<= leaf_size`
//! points) from the ideal one.
//!
//! Counting the points of the `D + 1` ancestors of every `c_k` takes one
//! `all_reduce` of `(R - 1)(D + 1)` integers (each rank counts its sorted
//! codes by binary search), and the weights before each `B_k`'s two ends one
//! more of `2 (R - 1)` numbers: the cuts cost `O(R D)` words per rank,
//! whatever the number of points.
//!
//! # Why the cuts keep the tree the same
//!
//! A box that contains codes on both sides of a cut at `B_k`'s start (or
//! end) contains `B_k`'s first (last) finest cell and a cell outside `B_k`,
//! so it is a strict ancestor of `B_k`: split in the refinement of all
//! points, and so in the balanced tree too (the balance only splits more).
//! Every other box lies inside one rank's range, and its refinement sees
//! all its points on that rank. The boxes that straddle a cut form the
//! **coarse tree**, computed from the cuts alone ([`straddling`]) and
//! replicated on every rank; everything else is refined locally below the
//! coarsest boxes tiling the rank's range ([`covering_boxes`]).

use std::borrow::Cow;

use ferrofmm_tree::{DEEPEST_LEVEL, MortonKey};
use mpi::collective::SystemOperation;
use mpi::traits::*;

use crate::exchange::all_to_all;
use crate::sort::LocalPoints;

/// One past the last finest Morton code.
pub const END: u64 = 1 << (3 * DEEPEST_LEVEL);

/// The cuts `cuts[0] = 0 <= cuts[1] <= ... <= cuts[R] = END` (see the
/// [module docs](self)). `pts` must be globally sorted (rank order).
///
/// `first_target`: `None` when the points are sources and targets at once;
/// in a build with separate targets, the first id of a target (ids below
/// are sources). A box is then a leaf when `max(#sources, #targets) <=
/// leaf_size`, the tree crate's rule for two point sets, and the cuts
/// balance the weight of both.
pub fn find_cuts<C: Communicator>(
    comm: &C,
    pts: &LocalPoints,
    first_target: Option<u64>,
    leaf_size: usize,
    max_level: u32,
) -> Vec<u64> {
    let size = comm.size() as usize;
    let mut cuts = vec![0u64; size + 1];
    cuts[size] = END;
    if size == 1 {
        return cuts;
    }
    // Cumulative weights, locally and over the ranks before this one.
    let mut prefix = Vec::with_capacity(pts.len() + 1);
    prefix.push(0.0f64);
    for &w in &pts.weights {
        prefix.push(prefix.last().unwrap() + w);
    }
    let mine = *prefix.last().unwrap();
    let mut per_rank = vec![0.0f64; size];
    comm.all_gather_into(&mine, &mut per_rank[..]);
    let me = comm.rank() as usize;
    let before: f64 = per_rank[..me].iter().sum();
    let total: f64 = per_rank.iter().sum();

    // The code at each ideal cut.
    let mut codes = vec![0u64; size - 1];
    for (k, code) in codes.iter_mut().enumerate() {
        let target = (k + 1) as f64 * total / size as f64;
        if mine > 0.0 && before <= target && target < before + mine {
            let i = prefix.partition_point(|&p| p <= target - before);
            *code = pts.codes[i.saturating_sub(1).min(pts.len() - 1)];
        }
    }
    let mut ideal = vec![0u64; size - 1];
    comm.all_reduce_into(&codes[..], &mut ideal[..], SystemOperation::max());

    // Point counts (per point set) of every ancestor of each ideal code.
    let levels = DEEPEST_LEVEL as usize + 1;
    let sets: Vec<Cow<[u64]>> = match first_target {
        None => vec![Cow::Borrowed(&pts.codes)],
        Some(first) => {
            let (mut s, mut t) = (Vec::new(), Vec::new());
            for (&c, &id) in pts.codes.iter().zip(&pts.ids) {
                if id < first { &mut s } else { &mut t }.push(c);
            }
            vec![Cow::Owned(s), Cow::Owned(t)]
        }
    };
    let m = sets.len();
    let count = |codes: &[u64], key: MortonKey| {
        let r = key.morton_range();
        let lo = codes.partition_point(|&c| c < r.start);
        (codes[lo..].partition_point(|&c| c < r.end)) as u64
    };
    let local: Vec<u64> = ideal
        .iter()
        .flat_map(|&c| (0..levels).map(move |l| MortonKey::from_morton(c, l as u32)))
        .flat_map(|key| sets.iter().map(move |codes| count(codes, key)))
        .collect();
    let mut global = vec![0u64; local.len()];
    comm.all_reduce_into(&local[..], &mut global[..], SystemOperation::sum());
    let leaves: Vec<MortonKey> = ideal
        .iter()
        .enumerate()
        .map(|(k, &c)| {
            let size = |l: usize| {
                let at = (k * levels + l) * m;
                global[at..at + m].iter().copied().max().unwrap_or(0)
            };
            let l = (0..levels)
                .find(|&l| size(l) <= leaf_size as u64 || l as u32 >= max_level)
                .unwrap_or(levels - 1);
            MortonKey::from_morton(c, l as u32)
        })
        .collect();

    // Weights before each leaf's two ends; cut at the closer one.
    let weight_below = |code: u64| prefix[pts.codes.partition_point(|&c| c < code)];
    let local: Vec<f64> = leaves
        .iter()
        .flat_map(|b| {
            let r = b.morton_range();
            [weight_below(r.start), weight_below(r.end)]
        })
        .collect();
    let mut global = vec![0.0f64; local.len()];
    comm.all_reduce_into(&local[..], &mut global[..], SystemOperation::sum());
    for (k, b) in leaves.iter().enumerate() {
        let target = (k + 1) as f64 * total / size as f64;
        let r = b.morton_range();
        let (lo, hi) = (global[2 * k], global[2 * k + 1]);
        let cut = if target - lo <= hi - target {
            r.start
        } else {
            r.end
        };
        cuts[k + 1] = cut.max(cuts[k]);
    }
    cuts
}

/// Sends every point to the rank whose range holds its code; returns this
/// rank's points (sorted) and the bytes sent.
///
/// The points are already in global order (rank by rank), so the points a
/// rank receives from lower ranks precede its own, and those from higher
/// ranks follow: no merge, and the points that stay are not copied through
/// the exchange.
pub fn redistribute<C: Communicator>(
    comm: &C,
    pts: LocalPoints,
    cuts: &[u64],
) -> (LocalPoints, u64) {
    if comm.size() == 1 {
        return (pts, 0);
    }
    let me = comm.rank() as usize;
    let bounds: Vec<usize> = cuts
        .iter()
        .map(|&c| pts.codes.partition_point(|&x| x < c))
        .collect();
    let messages = pts.pack_ranges(&bounds, Some(me));
    let (recv, runs, bytes) = all_to_all(comm, &messages);
    drop(messages);
    let split: usize = runs[..me].iter().sum();
    let out = pts.splice(&recv[..split], bounds[me]..bounds[me + 1], &recv[split..]);
    (out, bytes)
}

/// The ranks whose ranges intersect the codes `range` (ranks with empty
/// ranges excluded), ascending.
pub fn owners(cuts: &[u64], range: std::ops::Range<u64>) -> impl Iterator<Item = usize> + '_ {
    let first = cuts
        .partition_point(|&c| c <= range.start)
        .saturating_sub(1);
    (first..cuts.len() - 1)
        .take_while(move |&r| cuts[r] < range.end)
        .filter(move |&r| cuts[r] < cuts[r + 1] && cuts[r + 1] > range.start)
}

/// The coarsest boxes tiling the codes `[lo, hi)`, in Morton order: from
/// `lo`, the largest aligned box starting there that fits, repeatedly
/// (at most `14 D` boxes).
pub fn covering_boxes(lo: u64, hi: u64) -> Vec<MortonKey> {
    let mut out = Vec::new();
    let mut c = lo;
    while c < hi {
        let key = (0..=DEEPEST_LEVEL)
            .map(|l| MortonKey::from_morton(c, l))
            .find(|k| {
                let r = k.morton_range();
                r.start == c && r.end <= hi
            })
            .expect("a finest cell always fits");
        c = key.morton_range().end;
        out.push(key);
    }
    out
}

/// The boxes that hold codes on both sides of `cut` (none for `0` and
/// [`END`]): the common ancestors of the finest cells `cut - 1` and `cut`.
pub fn straddling(cut: u64) -> Vec<MortonKey> {
    if cut == 0 || cut >= END {
        return Vec::new();
    }
    (0..=DEEPEST_LEVEL)
        .map(|l| MortonKey::from_morton(cut, l))
        .take_while(|k| k.morton_range().start < cut)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn covering_boxes_tile_the_range_coarsest_first() {
        for (lo, hi) in [(0, END), (5, 1000), (END / 8 - 3, END / 8 * 5 + 7), (7, 8)] {
            let b = covering_boxes(lo, hi);
            let mut c = lo;
            for k in &b {
                assert_eq!(k.morton_range().start, c);
                // Maximal: the parent does not fit.
                if k.level() > 0 {
                    let p = k.parent().morton_range();
                    assert!(p.start < lo || p.end > hi);
                }
                c = k.morton_range().end;
            }
            assert_eq!(c, hi);
        }
    }

    #[test]
    fn owners_and_straddling() {
        let cuts = [0, 64, 64, 4096, END];
        assert_eq!(owners(&cuts, 0..10).collect::<Vec<_>>(), [0]);
        assert_eq!(owners(&cuts, 60..70).collect::<Vec<_>>(), [0, 2]);
        assert_eq!(owners(&cuts, 64..65).collect::<Vec<_>>(), [2]);
        assert_eq!(owners(&cuts, 0..END).collect::<Vec<_>>(), [0, 2, 3]);
        for cut in [64u64, 4096, 3] {
            for k in straddling(cut) {
                let r = k.morton_range();
                assert!(r.start < cut && cut < r.end);
            }
            let deepest = straddling(cut).last().copied().unwrap();
            let child = MortonKey::from_morton(cut, deepest.level() + 1);
            assert_eq!(child.morton_range().start, cut);
        }
        assert!(straddling(0).is_empty() && straddling(END).is_empty());
    }
}
