//! Sorting points along the Morton curve and top-down refinement.
//!
//! Each point is mapped to the Morton code of its finest cell (table-driven
//! encode, in parallel) and the `(code, index)` pairs are sorted: a counting
//! pass on a coarse level's code distributes them into buckets, which are
//! then sorted in parallel with rayon (`sort_unstable` per bucket,
//! `par_sort_unstable` inside a bucket that holds many points). Ties (points
//! sharing a finest cell) are ordered by original index, so the result is
//! deterministic. After sorting, the points
//! of any box form one contiguous range, because a box of level `l` covers
//! exactly the codes `m .. m + 8^(D - l)`.
//!
//! The tree is then grown level by level from the root: a box to be split
//! finds its children's point ranges with 7 binary searches in its own range
//! (per point set), and only non-empty children are created. Boxes of one
//! level are processed in parallel and stay in Morton order, since the
//! children of a box follow each other in octant order.

use rayon::prelude::*;

use crate::domain::Domain;
use crate::morton::{DEEPEST_LEVEL, MortonKey, cells_in_box};

/// Points sorted by the Morton code of their finest cell.
pub(crate) struct SortedPoints {
    /// Finest-cell Morton codes, ascending.
    pub keys: Vec<u64>,
    /// `perm[k]` is the original index of the point at sorted position `k`.
    pub perm: Vec<usize>,
    /// Coordinates in sorted order, interleaved `xyz`.
    pub coords: Vec<f64>,
}

/// Points per parallel work item when encoding and unzipping.
const BLOCK: usize = 1 << 14;

/// Sorts validated interleaved points of `domain` along the Morton curve.
pub(crate) fn sort_points(points: &[f64], domain: &Domain) -> SortedPoints {
    let n = points.len() / 3;
    let mut keys = vec![0u64; n];
    keys.par_chunks_mut(BLOCK)
        .zip(points.par_chunks(3 * BLOCK))
        .for_each(|(k, p)| {
            for (k, c) in k.iter_mut().zip(p.chunks_exact(3)) {
                *k = domain.finest_morton([c[0], c[1], c[2]]);
            }
        });
    let (keys, perm) = bucket_sort(&keys);
    let mut coords = vec![0.0; points.len()];
    coords
        .par_chunks_mut(3 * BLOCK)
        .zip(perm.par_chunks(BLOCK))
        .for_each(|(c, idx)| {
            for (c, &i) in c.chunks_exact_mut(3).zip(idx) {
                c.copy_from_slice(&points[3 * i..3 * i + 3]);
            }
        });
    SortedPoints { keys, perm, coords }
}

/// Sorts `(keys[i], i)` pairs, returned as sorted keys and the permutation:
/// a counting pass on the top bits of the key (the Morton code of a coarse
/// level, chosen so that buckets hold a few dozen points when the points are
/// spread out), a scatter into buckets that keeps index order, then the
/// buckets sorted in parallel (`sort_unstable`, or `par_sort_unstable` for a
/// large bucket, as with clustered points). Ties are ordered by index.
fn bucket_sort(keys: &[u64]) -> (Vec<u64>, Vec<usize>) {
    let n = keys.len();
    let mut level = 0;
    while level < 7 && (n >> (3 * level)) > 32 {
        level += 1;
    }
    let shift = 3 * (DEEPEST_LEVEL - level);
    let n_buckets = 1usize << (3 * level);
    let mut start = vec![0usize; n_buckets + 1];
    for &k in keys {
        start[(k >> shift) as usize + 1] += 1;
    }
    for b in 0..n_buckets {
        start[b + 1] += start[b];
    }
    let mut next = start.clone();
    let mut sorted = vec![0u64; n];
    let mut perm = vec![0usize; n];
    for (i, &k) in keys.iter().enumerate() {
        let b = (k >> shift) as usize;
        sorted[next[b]] = k;
        perm[next[b]] = i;
        next[b] += 1;
    }
    let mut buckets: Vec<(&mut [u64], &mut [usize])> = Vec::new();
    let (mut rest_k, mut rest_p): (&mut [u64], &mut [usize]) = (&mut sorted, &mut perm);
    for b in 0..n_buckets {
        let len = start[b + 1] - start[b];
        let (hk, tk) = rest_k.split_at_mut(len);
        let (hp, tp) = rest_p.split_at_mut(len);
        if len > 1 {
            buckets.push((hk, hp));
        }
        rest_k = tk;
        rest_p = tp;
    }
    buckets.into_par_iter().for_each(|(k, p)| {
        // Scattering kept index order, so sorted keys mean a sorted bucket.
        if k.windows(2).all(|w| w[0] <= w[1]) {
            return;
        }
        let mut pairs: Vec<(u64, usize)> = k.iter().copied().zip(p.iter().copied()).collect();
        if pairs.len() > 1 << 16 {
            pairs.par_sort_unstable();
        } else {
            pairs.sort_unstable();
        }
        for ((k, p), (key, index)) in k.iter_mut().zip(p.iter_mut()).zip(pairs) {
            *k = key;
            *p = index;
        }
    });
    (sorted, perm)
}

/// A box while the tree is being built: its key, its point ranges in the
/// sorted sources and targets, and whether it is (for now) a leaf.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Node {
    pub key: MortonKey,
    pub src: [usize; 2],
    pub tgt: [usize; 2],
    pub leaf: bool,
}

impl Node {
    /// Points counted for refinement: `max(#sources, #targets)`.
    fn size(&self) -> usize {
        (self.src[1] - self.src[0]).max(self.tgt[1] - self.tgt[0])
    }
}

/// The sorted finest codes of sources and targets (`same`: they are one set,
/// `tgt` equals `src`).
pub(crate) struct PointKeys<'a> {
    pub src: &'a [u64],
    pub tgt: &'a [u64],
    pub same: bool,
}

/// When to split a box during top-down refinement.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Refinement {
    /// Split while `max(#sources, #targets) > leaf_size` and above `max_level`.
    Adaptive { leaf_size: usize, max_level: u32 },
    /// Split every box above this level.
    Uniform(u32),
}

impl Refinement {
    fn splits(self, node: &Node) -> bool {
        let level = node.key.level();
        match self {
            Refinement::Adaptive {
                leaf_size,
                max_level,
            } => level < max_level && node.size() > leaf_size,
            Refinement::Uniform(depth) => level < depth,
        }
    }
}

/// Start of each octant's range inside `range` (9 boundaries).
fn octant_bounds(keys: &[u64], range: [usize; 2], key: MortonKey) -> [usize; 9] {
    let step = cells_in_box(key.level() + 1);
    let base = key.morton();
    let mut b = [range[1]; 9];
    b[0] = range[0];
    let mut lo = range[0];
    for (c, bound) in b.iter_mut().enumerate().take(8).skip(1) {
        let limit = base + c as u64 * step;
        lo += keys[lo..range[1]].partition_point(|&k| k < limit);
        *bound = lo;
    }
    b
}

/// The non-empty children of `node` (as leaves), in octant order.
pub(crate) fn split(node: &Node, pts: &PointKeys<'_>) -> Vec<Node> {
    let sb = octant_bounds(pts.src, node.src, node.key);
    let tb = if pts.same {
        sb
    } else {
        octant_bounds(pts.tgt, node.tgt, node.key)
    };
    node.key
        .children()
        .into_iter()
        .enumerate()
        .filter(|&(c, _)| sb[c] < sb[c + 1] || tb[c] < tb[c + 1])
        .map(|(c, key)| Node {
            key,
            src: [sb[c], sb[c + 1]],
            tgt: [tb[c], tb[c + 1]],
            leaf: true,
        })
        .collect()
}

/// Grows the tree from the root; returns the boxes of each level in Morton
/// order, with leaf flags set.
pub(crate) fn refine(pts: &PointKeys<'_>, rule: Refinement) -> Vec<Vec<Node>> {
    let root = Node {
        key: MortonKey::ROOT,
        src: [0, pts.src.len()],
        tgt: [0, pts.tgt.len()],
        leaf: true,
    };
    refine_from(pts, rule, vec![root])
}

/// Grows the subtrees below `roots` (disjoint boxes, any levels, each with
/// its point ranges); returns the boxes of each level in Morton order, with
/// leaf flags set. Level `l` of the result holds the roots of level `l` and
/// the children created from level `l - 1`. With the root alone this is the
/// whole tree ([`refine`]).
pub(crate) fn refine_from(
    pts: &PointKeys<'_>,
    rule: Refinement,
    mut roots: Vec<Node>,
) -> Vec<Vec<Node>> {
    roots.sort_unstable_by_key(|n| (n.key.level(), n.key));
    let deepest_root = roots.last().map_or(0, |n| n.key.level() as usize);
    let mut pending = vec![Vec::new(); deepest_root + 1];
    for n in roots {
        pending[n.key.level() as usize].push(n);
    }
    let mut pending = pending.into_iter();
    let mut levels = vec![pending.next().unwrap_or_default()];
    loop {
        let current = levels.last_mut().expect("at least one level");
        let mut next: Vec<Node> = current
            .par_iter_mut()
            .flat_map_iter(|node| {
                if rule.splits(node) {
                    node.leaf = false;
                    split(node, pts)
                } else {
                    Vec::new()
                }
            })
            .collect();
        match pending.next() {
            Some(mut more) if !more.is_empty() => {
                next.append(&mut more);
                next.sort_unstable_by_key(|n| n.key);
            }
            Some(_) => {}
            None if next.is_empty() => return levels,
            None => {}
        }
        levels.push(next);
    }
}
