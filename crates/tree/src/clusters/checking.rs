//! The checking step of the clustering: clusters whose root expansions
//! cannot couple them accurately are merged.
//!
//! Two bounding boxes `A`, `B` are separated when, along some axis `a`,
//!
//! ```text
//! max(lo_a(B) - hi_a(A), lo_a(A) - hi_a(B)) >= s * max(w(A), w(B))
//! ```
//!
//! ([`separated`], `s = min(ratio, 4)`); [`merge_close`] joins every pair
//! that fails (union-find) and repeats until all pairs pass. The coupling
//! of the result costs about `(sum_i min(n_i, 512))^2` point pairs
//! ([`coupling_work`]).

use rayon::prelude::*;

use crate::bounds::{Bounds, bounds};

/// Merges groups until every two are apart along some axis by at least
/// `separation` times the wider one's width. Each pass joins every pair
/// that fails (union-find over the `O(C^2)` pairs of `C <= MAX_PIECES`
/// groups) and repeats while a pass joined anything.
pub(super) fn merge_close(
    mut groups: Vec<Vec<usize>>,
    point: &(impl Fn(usize) -> [f64; 3] + Sync),
    separation: f64,
) -> Vec<Vec<usize>> {
    let mut boxes: Vec<Bounds> = groups.par_iter().map(|g| bounds(g, point)).collect();
    loop {
        let c = groups.len();
        let mut root: Vec<usize> = (0..c).collect();
        fn find(root: &mut [usize], mut i: usize) -> usize {
            while root[i] != i {
                root[i] = root[root[i]];
                i = root[i];
            }
            i
        }
        let close: Vec<(usize, usize)> = (0..c)
            .into_par_iter()
            .flat_map_iter(|i| {
                let boxes = &boxes;
                (i + 1..c)
                    .filter(move |&j| !separated(&boxes[i], &boxes[j], separation))
                    .map(move |j| (i, j))
            })
            .collect();
        if close.is_empty() {
            return groups;
        }
        for (i, j) in close {
            let (ri, rj) = (find(&mut root, i), find(&mut root, j));
            if ri != rj {
                root[ri.max(rj)] = ri.min(rj);
            }
        }
        let mut merged: Vec<Vec<usize>> = Vec::new();
        let mut merged_boxes = Vec::new();
        let mut slot = vec![usize::MAX; c];
        for (i, (g, b)) in groups.into_iter().zip(boxes).enumerate() {
            let r = find(&mut root, i);
            if slot[r] == usize::MAX {
                slot[r] = merged.len();
                merged.push(g);
                merged_boxes.push(b);
            } else {
                let k = slot[r];
                merged[k].extend(g);
                merged_boxes[k].merge(&b);
            }
        }
        groups = merged;
        boxes = merged_boxes;
    }
}

/// Cost of coupling the clusters pairwise, in units of point-pair
/// interactions: `(sum_i min(n_i, 512))^2`, a cluster interacting through
/// at most about 512 points or expansion-surface points.
pub(super) fn coupling_work(groups: &[Vec<usize>]) -> f64 {
    let s: usize = groups.iter().map(|g| g.len().min(512)).sum();
    (s as f64).powi(2)
}

/// Whether two boxes are apart along some axis by at least `separation`
/// times the wider box's largest extent.
pub(super) fn separated(a: &Bounds, b: &Bounds, separation: f64) -> bool {
    let wider = a.width().max(b.width());
    let gap = (0..3)
        .map(|k| (b.lo[k] - a.hi[k]).max(a.lo[k] - b.hi[k]))
        .fold(f64::NEG_INFINITY, f64::max);
    gap >= separation * wider
}
