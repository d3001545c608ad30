//! The locally essential tree of one rank as an [`Octree`] the
//! single-machine passes run on.
//!
//! Boxes: the ghost layer's skeleton (this rank's boxes, the coarse tree,
//! the ghost boxes received and their ancestors), in the tree's order.
//! Sources: this rank's points and the points of the ghost leaves its U and
//! X lists reference, merged along the Morton curve (so every box's points
//! are one range). Targets: this rank's points only (its targets, in a
//! tree built with separate targets). The ghost layer's lists are already
//! pruned as the single-machine tree's (entries with sources, rows of
//! boxes with targets), so the rows below are subsets of global rows.
//!
//! Lists (rows the passes follow):
//!
//! * a box of this rank: its U, V, W and X rows of the global tree (the
//!   ghost layer's rows);
//! * a coarse box `C`: the part of its V and X rows this rank can compute,
//!   the boxes of this rank in `V(C)` and `X(C)` (the skeleton holds all of
//!   them, and the rows on a skeleton are exact for entries that are
//!   present), plus, on `C`'s root (its first owner, which sums its check:
//!   `dfmm/coarse_plan.rs`), the coarse boxes in `V(C)` (all of them are on
//!   every rank).
//!   Summed over ranks, these partial check potentials are those of the
//!   global tree;
//! * every other box: no rows (its data come from its owner).

use std::ops::Range;

use ferrofmm_tree::{Csr, InteractionLists, MortonKey, Octree};

use super::coarse_plan::root_of;
use crate::DistributedTree;

/// What a box of the skeleton is to this rank.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    /// One of this rank's boxes (all its points are here).
    Own,
    /// A box of the coarse tree (straddles a cut; on every rank).
    Coarse,
    /// Another rank's box (or a placeholder).
    Foreign,
}

/// The kind of every skeleton box.
pub(crate) fn kinds(dtree: &DistributedTree) -> Vec<Kind> {
    dtree
        .ghosts
        .skeleton
        .iter()
        .map(|&k| {
            if dtree.boxes.binary_search_by_key(&k, |b| b.0).is_ok() {
                Kind::Own
            } else if dtree.coarse.binary_search(&k).is_ok() {
                Kind::Coarse
            } else {
                Kind::Foreign
            }
        })
        .collect()
}

/// The rows of the locally essential tree (see the [module docs](self)).
pub(crate) fn rows(dtree: &DistributedTree, kinds: &[Kind], me: usize) -> InteractionLists {
    let l = &dtree.ghosts.lists;
    // The rank that adds the coarse-to-coarse part of coarse box `b`'s V
    // row: its root, which sums its check (no message for that part).
    let turn = |b: usize| root_of(&dtree.cuts, dtree.ghosts.skeleton[b]);
    // Whether row `list` (0 U, 1 V, 2 W, 3 X) of box `b` of kind `row`
    // keeps an entry of kind `entry`.
    let keeps = |b: usize, row: Kind, list: usize, entry: Kind| match (row, list) {
        (Kind::Own, _) => true,
        (Kind::Coarse, 1) => entry == Kind::Own || (entry == Kind::Coarse && turn(b) == me),
        (Kind::Coarse, 3) => entry == Kind::Own,
        _ => false,
    };
    let csrs = [&l.u, &l.v, &l.w, &l.x];
    let filtered: Vec<Csr> = csrs
        .iter()
        .enumerate()
        .map(|(list, csr)| {
            let rows: Vec<Vec<usize>> = kinds
                .iter()
                .enumerate()
                .map(|(b, &kind)| {
                    csr.get(b)
                        .iter()
                        .copied()
                        .filter(|&a| keeps(b, kind, list, kinds[a]))
                        .collect()
                })
                .collect();
            Csr::from_rows(&rows)
        })
        .collect();
    let mut it = filtered.into_iter();
    let mut next = || it.next().unwrap_or_default();
    InteractionLists {
        u: next(),
        v: next(),
        w: next(),
        x: next(),
    }
}

/// The merged sources: this rank's points (codes `own`, ascending) and the
/// ghost points (codes `ghost`, any order). Returns the merged codes, the
/// merged position of each own point and of each ghost point.
pub(crate) fn merge(own: &[u64], ghost: &[u64]) -> (Vec<u64>, Vec<usize>, Vec<usize>) {
    let mut g: Vec<usize> = (0..ghost.len()).collect();
    g.sort_by_key(|&i| ghost[i]);
    let mut codes = Vec::with_capacity(own.len() + ghost.len());
    let mut own_pos = Vec::with_capacity(own.len());
    let mut ghost_pos = vec![0; ghost.len()];
    let (mut i, mut j) = (0, 0);
    while i < own.len() || j < g.len() {
        if j == g.len() || (i < own.len() && own[i] <= ghost[g[j]]) {
            own_pos.push(codes.len());
            codes.push(own[i]);
            i += 1;
        } else {
            ghost_pos[g[j]] = codes.len();
            codes.push(ghost[g[j]]);
            j += 1;
        }
    }
    (codes, own_pos, ghost_pos)
}

/// The points of `codes` (ascending) inside `key`, as a range.
pub(crate) fn range_of(codes: &[u64], key: MortonKey) -> Range<usize> {
    let r = key.morton_range();
    codes.partition_point(|&c| c < r.start)..codes.partition_point(|&c| c < r.end)
}

/// The locally essential tree: skeleton boxes with their ranges in the
/// merged sources (`src_codes`) and this rank's points (`own_codes`).
pub(crate) fn octree(
    dtree: &DistributedTree,
    lists: InteractionLists,
    src_codes: &[u64],
    own_codes: &[u64],
) -> Result<Octree, String> {
    let boxes: Vec<(MortonKey, Range<usize>, Range<usize>)> = dtree
        .ghosts
        .skeleton
        .iter()
        .map(|&k| (k, range_of(src_codes, k), range_of(own_codes, k)))
        .collect();
    Octree::from_parts(dtree.domain, &boxes, lists).map_err(|e| e.to_string())
}
