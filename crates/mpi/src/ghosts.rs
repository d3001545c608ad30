//! Ghost boxes (the locally essential tree): for every box of this rank,
//! the boxes of other ranks in its U, V, W and X lists.
//!
//! # Which boxes a box needs
//!
//! With the 2:1 balance, the lists of a box `B` of level `l` reference
//! only boxes of levels `l - 1 ..= l + 1` inside `parent(B)` and its
//! colleagues (V: children of the parent's colleagues; U, W: adjacent
//! leaves and children of colleagues; X: leaves of level `l - 1` adjacent
//! to the parent; see [`ferrofmm_tree::lists`]). So, for each of its boxes,
//! a rank asks for the **regions** `C` in `{parent(B)} ∪ colleagues(parent(B))`
//! that are not wholly its own, down to level `l + 1`, and only the ranks
//! whose ranges meet `C` (known from the cuts, which every rank holds) are
//! asked.
//!
//! # Protocol
//!
//! 1. requests `(C, depth)`, merged per region, point to point to the
//!    owners of `C`;
//! 2. each owner answers with its boxes inside `C` down to `depth` and its
//!    boxes that are ancestors of `C`, with their leaf flags and point
//!    counts (24 bytes a box);
//! 3. the rank computes the lists of its boxes with the tree crate's own
//!    list code ([`lists_of_boxes`]) on its boxes, the coarse tree and the
//!    received boxes, each with its leaf flag (a received box whose
//!    children were not sent is still internal if flagged so). For each of its boxes that is exactly the rows of the
//!    single-machine tree, since everything the rows depend on is present.
//!    The ghosts are the list entries that are not its own.
//!
//! # Separate targets
//!
//! With targets that are not the sources ([`SeparateTargets`]), a box
//! exists when it holds a source or a target, and the single-machine lists
//! are pruned ([`ferrofmm_tree::lists`]): an entry `A` of a row of `B` is
//! kept only if `A` holds a source and `B` a target. The skeleton's lists
//! count every box as holding both, and the pruned rows are exactly those
//! lists filtered by the two flags (every rule of the lists keeps or drops
//! a candidate by `has_sources` alone, after walking the existing boxes).
//! So answers carry each box's source and target counts, every rank knows
//! the coarse boxes' global counts, and the rows are filtered before the
//! ghosts are picked: only boxes with sources become ghosts.

use std::collections::BTreeMap;

use ferrofmm_tree::lists::{InteractionLists, lists_of_boxes};
use ferrofmm_tree::{Csr, MortonKey, TreeShape};

use crate::exchange::sparse_exchange;
use crate::partition::owners;
use mpi::traits::*;

const TAG_REQUEST: i32 = 21;
const TAG_ANSWER: i32 = 22;

/// A box of another rank (or of the shared coarse tree) that some list of
/// this rank's boxes references.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Ghost {
    /// The box.
    pub key: MortonKey,
    /// Whether it is a leaf of the global tree.
    pub leaf: bool,
    /// Points (sources) in it (0 for a box of the coarse tree, whose points
    /// are spread over ranks).
    pub points: usize,
    /// Targets in it: [`Ghost::points`] when the targets are the sources;
    /// 0 for a box of the coarse tree.
    pub targets: usize,
}

/// The target counts of a build with separate targets, which prune the
/// lists as the single-machine tree with targets does (see the
/// [module docs](self)).
#[derive(Clone, Copy, Debug)]
pub struct SeparateTargets<'a> {
    /// Targets in each of this rank's boxes (parallel to its boxes).
    pub own: &'a [usize],
    /// Sources and targets in each coarse box (parallel to the coarse
    /// boxes), summed over all ranks.
    pub coarse: &'a [[u64; 2]],
}

/// The ghost data of one rank.
#[derive(Clone, Debug, Default)]
pub struct GhostLayer {
    /// Foreign boxes referenced by the lists of this rank's boxes, sorted.
    pub ghosts: Vec<Ghost>,
    /// Boxes received before keeping only the referenced ones.
    pub received: usize,
    /// The boxes the lists were computed on (this rank's, the coarse tree,
    /// the received ones and their ancestors), in the tree's order.
    pub skeleton: Vec<MortonKey>,
    /// The lists of [`GhostLayer::skeleton`] (rows of this rank's boxes are
    /// those of the single-machine tree).
    pub lists: InteractionLists,
    /// Ranks this one asked for boxes.
    pub partners: Vec<usize>,
}

/// Whether the codes of `key` lie in `[lo, hi)`.
pub(crate) fn inside(key: MortonKey, lo: u64, hi: u64) -> bool {
    let r = key.morton_range();
    lo <= r.start && r.end <= hi
}

/// Finds the ghost layer (see the [module docs](self)); returns it and the
/// bytes sent. `local` holds this rank's boxes with their leaf flags and
/// point (source) counts, sorted; `coarse` the boxes straddling cuts;
/// `targets` the target counts when the targets are another point set
/// (`None`: the points are the targets).
pub fn exchange_ghosts<C: Communicator>(
    comm: &C,
    local: &[(MortonKey, bool, usize)],
    coarse: &[MortonKey],
    cuts: &[u64],
    targets: Option<SeparateTargets<'_>>,
) -> (GhostLayer, u64) {
    let me = comm.rank() as usize;
    let (lo, hi) = (cuts[me], cuts[me + 1]);
    // 1. Requests: region -> deepest level needed, per owner.
    let mut wanted: BTreeMap<(usize, MortonKey), u32> = BTreeMap::new();
    for &(b, _, _) in local {
        if b.level() == 0 {
            continue;
        }
        let p = b.parent();
        for c in std::iter::once(p).chain(p.colleagues()) {
            if inside(c, lo, hi) {
                continue;
            }
            for r in owners(cuts, c.morton_range()).filter(|&r| r != me) {
                let d = wanted.entry((r, c)).or_insert(0);
                *d = (*d).max(b.level() + 1);
            }
        }
    }
    let mut requests: BTreeMap<usize, Vec<u64>> = BTreeMap::new();
    for ((r, c), d) in wanted {
        requests.entry(r).or_default().extend([c.raw(), d as u64]);
    }
    let partners: Vec<usize> = requests.keys().copied().collect();
    let send: Vec<(usize, Vec<u64>)> = requests.into_iter().collect();
    let (asked, mut bytes) = sparse_exchange(comm, &send, TAG_REQUEST);

    // 2. Answers: own boxes inside each region (to its depth) and own
    // ancestors of it, as (key, leaf flag and target count, point count).
    let find = |k: MortonKey| local.binary_search_by_key(&k, |&(key, _, _)| key).ok();
    let n_targets = |i: usize| targets.map_or(local[i].2, |t| t.own[i]);
    let mut answers: Vec<(usize, Vec<u64>)> = Vec::new();
    for (r, words) in asked {
        let mut out: Vec<usize> = Vec::new();
        for pair in words.chunks_exact(2) {
            let Some(c) = MortonKey::from_raw(pair[0]) else {
                continue;
            };
            let depth = pair[1] as u32;
            let end = c.morton_range().end;
            let start = local.partition_point(|&(k, _, _)| k < c);
            let stop = start + local[start..].partition_point(|&(k, _, _)| k.morton() < end);
            out.extend((start..stop).filter(|&i| local[i].0.level() <= depth));
            for a in c.ancestors() {
                if inside(a, lo, hi)
                    && let Some(i) = find(a)
                {
                    out.push(i);
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        answers.push((
            r,
            out.iter()
                .flat_map(|&i| {
                    let (k, leaf, n) = local[i];
                    [
                        k.raw(),
                        u64::from(leaf) | (n_targets(i) as u64) << 1,
                        n as u64,
                    ]
                })
                .collect(),
        ));
    }
    let (got, b) = sparse_exchange(comm, &answers, TAG_ANSWER);
    bytes += b;

    // 3. Lists on everything known; ghosts are the foreign entries.
    let mut received: Vec<Ghost> = got
        .iter()
        .flat_map(|(_, w)| w.chunks_exact(3))
        .filter_map(|p| {
            MortonKey::from_raw(p[0]).map(|key| Ghost {
                key,
                leaf: p[1] & 1 == 1,
                points: p[2] as usize,
                targets: (p[1] >> 1) as usize,
            })
        })
        .collect();
    received.sort_unstable();
    received.dedup();
    let boxes: Vec<(MortonKey, bool)> = local
        .iter()
        .map(|&(k, leaf, _)| (k, leaf))
        .chain(coarse.iter().map(|&k| (k, false)))
        .chain(received.iter().map(|g| (g.key, g.leaf)))
        .collect();
    let (skeleton, mut lists) = lists_of_boxes(&boxes);
    if let Some(t) = targets {
        let held = |key: MortonKey| -> [bool; 2] {
            if inside(key, lo, hi) {
                find(key).map_or([true; 2], |i| [local[i].2 > 0, t.own[i] > 0])
            } else if let Ok(i) = coarse.binary_search(&key) {
                t.coarse[i].map(|n| n > 0)
            } else {
                received
                    .binary_search_by_key(&key, |g| g.key)
                    .map_or([true; 2], |i| {
                        [received[i].points > 0, received[i].targets > 0]
                    })
            }
        };
        let flags: Vec<[bool; 2]> = skeleton.iter().map(|&k| held(k)).collect();
        lists = prune(&lists, &flags);
    }
    let mut referenced: Vec<MortonKey> = Vec::new();
    for (b, &key) in skeleton.iter().enumerate() {
        if !inside(key, lo, hi) {
            continue;
        }
        for csr in [&lists.u, &lists.v, &lists.w, &lists.x] {
            referenced.extend(
                csr.get(b)
                    .iter()
                    .map(|&a| skeleton[a])
                    .filter(|&a| !inside(a, lo, hi)),
            );
        }
    }
    referenced.sort_unstable();
    referenced.dedup();
    let ghosts = referenced
        .into_iter()
        .map(|key| match received.binary_search_by_key(&key, |g| g.key) {
            Ok(i) => received[i],
            Err(_) => Ghost {
                key,
                leaf: false,
                points: 0,
                targets: 0,
            },
        })
        .collect();
    (
        GhostLayer {
            ghosts,
            received: received.len(),
            skeleton,
            lists,
            partners,
        },
        bytes,
    )
}

/// The lists with the rows of boxes holding no target emptied and the
/// entries holding no source dropped (`flags[b]`: box `b` holds a source,
/// a target): the single-machine pruning (see the [module docs](self)).
fn prune(lists: &InteractionLists, flags: &[[bool; 2]]) -> InteractionLists {
    let filter = |csr: &Csr| -> Csr {
        let rows: Vec<Vec<usize>> = (0..csr.n_rows())
            .map(|b| match flags[b][1] {
                true => csr
                    .get(b)
                    .iter()
                    .copied()
                    .filter(|&a| flags[a][0])
                    .collect(),
                false => Vec::new(),
            })
            .collect();
        Csr::from_rows(&rows)
    };
    InteractionLists {
        u: filter(&lists.u),
        v: filter(&lists.v),
        w: filter(&lists.w),
        x: filter(&lists.x),
    }
}

/// This rank's boxes of `shape` (those inside `[lo, hi)`), sorted, with
/// their leaf flags and source counts, and their target counts.
pub(crate) fn own_boxes(
    shape: &TreeShape,
    lo: u64,
    hi: u64,
) -> (Vec<(MortonKey, bool, usize)>, Vec<usize>) {
    let mut out: Vec<(MortonKey, bool, usize, usize)> = (0..shape.n_levels())
        .flat_map(|l| shape.level(l))
        .filter(|b| inside(b.key, lo, hi))
        .map(|b| (b.key, b.leaf, b.n_sources(), b.n_targets()))
        .collect();
    out.sort_unstable_by_key(|b| b.0);
    out.into_iter().map(|(k, l, s, t)| ((k, l, s), t)).unzip()
}
