//! 2:1 balance of an adaptive tree that holds no empty boxes.
//!
//! # The condition
//!
//! The classical condition (Sundar, Sampath & Biros 2008) asks that any two
//! adjacent leaves of the *full* octree — where an internal box always has 8
//! children, empty ones included — differ by at most one level. In that tree
//! a leaf `L` of level `l` is adjacent to no leaf of level `>= l + 2` exactly
//! when no **internal** box of level `>= l + 1` is adjacent to `L` (such a
//! box has children, empty or not, touching `L`). We never create empty
//! boxes, so we enforce that form on the boxes that exist:
//!
//! > for every leaf `L` of level `l`, every box adjacent to `L` of level
//! > `>= l + 1` is a leaf.
//!
//! It suffices to check internal boxes of level exactly `l + 1`: an internal
//! box deeper than that has an ancestor of level `l + 1` that is internal and
//! adjacent to `L` as well. The condition implies the usual one between
//! existing leaves (adjacent leaves differ by at most one level) and bounds
//! the interaction lists as for the full balanced tree: W-list entries of a
//! leaf are children of its colleagues, X-list entries are one level coarser
//! (see [`lists`](crate::lists)).
//!
//! In a periodic tree ([`TreeOptions::periodic`](crate::TreeOptions::periodic))
//! adjacency is that of the periodic tiling: a leaf and the boxes across a
//! periodic face of the cell obey the condition like any adjacent boxes, so
//! the bounds of the lists hold for the wrapped lists too.
//!
//! # The algorithm
//!
//! A ripple to a fixed point. A leaf that breaks the condition is split into
//! its non-empty children; splitting can only create new violations for the
//! new children (an internal box two levels below the split leaf may touch
//! them) and for leaves one or more levels coarser than the new internal
//! box. Each round therefore checks only these candidates (the first round:
//! every leaf at least two levels above the deepest level), splits all
//! violators at once, and stops when none is left. Every split only moves
//! points from a leaf to its children, so no point is lost or duplicated,
//! and the tree stays complete. The checks of a round run in parallel, with
//! binary searches in the per-level sorted boxes. The result is the least
//! balanced refinement of the input tree.

use rayon::prelude::*;

use crate::build::{Node, PointKeys, split};
use crate::morton::MortonKey;

/// The box with `key`, if it exists.
fn find(levels: &[Vec<Node>], key: MortonKey) -> Option<usize> {
    levels
        .get(key.level() as usize)?
        .binary_search_by_key(&key, |n| n.key)
        .ok()
}

fn node(levels: &[Vec<Node>], key: MortonKey) -> Option<&Node> {
    find(levels, key).map(|i| &levels[key.level() as usize][i])
}

/// Same-level neighbours of `key` (up to 26), with their image shifts:
/// inside the domain along open axes, wrapped around the periodic ones (see
/// [`MortonKey::neighbour_periodic`]).
fn neighbours(key: MortonKey, periodic: [bool; 3]) -> impl Iterator<Item = (MortonKey, [i8; 3])> {
    (0..27).filter(|&i| i != 13).filter_map(move |i: i32| {
        key.neighbour_periodic([i % 3 - 1, (i / 3) % 3 - 1, i / 9 - 1], periodic)
    })
}

/// `true` if the leaf `key` is adjacent to an internal box one level deeper
/// (in the periodic tiling along periodic axes).
fn violates(levels: &[Vec<Node>], key: MortonKey, periodic: [bool; 3]) -> bool {
    let level = key.level() as usize;
    // An internal box of level l + 1 has children, so level l + 2 must exist.
    if level + 2 >= levels.len() {
        return false;
    }
    neighbours(key, periodic).any(|(n, s)| {
        node(levels, n).is_some_and(|nn| !nn.leaf)
            && n.children().into_iter().any(|c| {
                c.is_adjacent_shifted(s, key) && node(levels, c).is_some_and(|cn| !cn.leaf)
            })
    })
}

/// Leaves coarser than `key` and adjacent to it (wrapping around periodic
/// axes).
fn coarser_adjacent_leaves(
    levels: &[Vec<Node>],
    key: MortonKey,
    periodic: [bool; 3],
    out: &mut Vec<MortonKey>,
) {
    for (n, _) in neighbours(key, periodic) {
        for level in (0..key.level()).rev() {
            let a = n.ancestor(level);
            if let Some(an) = node(levels, a) {
                if an.leaf {
                    out.push(a);
                }
                break;
            }
        }
    }
}

/// Balances the tree in place (see the [module documentation](self)).
///
/// Along the axes flagged in `periodic` the condition wraps around the
/// domain's faces: a leaf and the boxes adjacent to it across a periodic
/// face obey it as any adjacent boxes (all `false`: free space).
pub(crate) fn balance(levels: &mut [Vec<Node>], pts: &PointKeys<'_>, periodic: [bool; 3]) {
    let depth = levels.len() - 1;
    let mut candidates: Vec<MortonKey> = levels
        .iter()
        .take(depth.saturating_sub(1))
        .flat_map(|lv| lv.iter().filter(|n| n.leaf).map(|n| n.key))
        .collect();
    loop {
        candidates.par_sort_unstable();
        candidates.dedup();
        let lv: &[Vec<Node>] = levels;
        let bad: Vec<MortonKey> = candidates
            .par_iter()
            .copied()
            .filter(|&k| node(lv, k).is_some_and(|n| n.leaf) && violates(lv, k, periodic))
            .collect();
        if bad.is_empty() {
            return;
        }
        let mut pending: Vec<Vec<Node>> = vec![Vec::new(); levels.len()];
        for &k in &bad {
            let l = k.level() as usize;
            let i = find(levels, k).expect("violating leaf exists");
            let n = &mut levels[l][i];
            n.leaf = false;
            pending[l + 1].extend(split(n, pts));
        }
        candidates.clear();
        for (l, mut new) in pending.into_iter().enumerate() {
            if new.is_empty() {
                continue;
            }
            candidates.extend(new.iter().map(|n| n.key));
            levels[l].append(&mut new);
            levels[l].par_sort_unstable_by_key(|n| n.key);
        }
        let lv: &[Vec<Node>] = levels;
        let coarse: Vec<MortonKey> = bad
            .par_iter()
            .flat_map_iter(|&k| {
                let mut out = Vec::new();
                coarser_adjacent_leaves(lv, k, periodic, &mut out);
                out
            })
            .collect();
        candidates.extend(coarse);
    }
}
