//! Pre-pass: the work of the adaptive tree for any leaf size, counted on
//! its shape ([`ferrofmm_tree::TreeShape`]: the tree builder's own
//! refinement and 2:1 balance run on the sorted Morton codes), with the
//! interaction lists' own rules ([`ferrofmm_tree::list_rules`]: the
//! neighbourhood's offsets, the V-list candidates among a neighbour's
//! children, the children that touch a box).

use ferrofmm_tree::list_rules::near_field::{
    NearEntry, NearLists, NeighbourhoodView, walk_near_field,
};
use ferrofmm_tree::list_rules::{index_offset, offsets, v_children};
use ferrofmm_tree::{DEEPEST_LEVEL, Domain, MortonCodes, MortonKey, ShapeBox, TreeShape};
use rayon::prelude::*;

use super::work::WorkCounts;
use crate::FmmError;

/// One level of a balanced [`TreeShape`], as the work count reads it.
pub(super) struct CountLevel {
    pub(super) keys: Vec<MortonKey>,
    pub(super) sources: Vec<u32>,
    pub(super) targets: Vec<u32>,
    /// Octants of the existing children (0 for a leaf).
    pub(super) masks: Vec<u8>,
}

impl CountLevel {
    pub(super) fn find(&self, key: MortonKey) -> Option<usize> {
        self.keys.binary_search(&key).ok()
    }

    pub(super) fn n_sources(&self, i: usize) -> usize {
        self.sources[i] as usize
    }

    pub(super) fn n_targets(&self, i: usize) -> usize {
        self.targets[i] as usize
    }
}

/// The levels of a balanced shape with each box's child mask (children of
/// one parent follow each other in Morton order, so one merge per level
/// finds them).
pub(super) fn count_levels(shape: &TreeShape) -> Vec<CountLevel> {
    let mut levels: Vec<CountLevel> = (0..shape.n_levels())
        .map(|l| {
            let boxes: Vec<ShapeBox> = shape.level(l).collect();
            CountLevel {
                keys: boxes.iter().map(|b| b.key).collect(),
                sources: boxes.iter().map(|b| b.n_sources() as u32).collect(),
                targets: boxes.iter().map(|b| b.n_targets() as u32).collect(),
                masks: vec![0; boxes.len()],
            }
        })
        .collect();
    for l in 1..levels.len() {
        let (upper, lower) = levels.split_at_mut(l);
        let parents = &mut upper[l - 1];
        let mut j = 0;
        for k in &lower[0].keys {
            let parent = k.parent();
            while parents.keys[j] != parent {
                j += 1;
            }
            parents.masks[j] |= 1 << k.octant();
        }
    }
    levels
}

/// The box `key` in `levels`: `(level, index)`.
pub(super) fn count_find(levels: &[CountLevel], key: MortonKey) -> Option<(usize, usize)> {
    let l = key.level() as usize;
    levels.get(l)?.find(key).map(|i| (l, i))
}

/// Leaves (and split parents) per level whose work is counted exactly; a
/// level with more is estimated from an evenly spaced sample of this many
/// (in Morton order, so every region is represented).
pub(super) const MAX_SAMPLED_LEAVES: usize = 2048;

/// Items per rayon task in the simulation (small levels run on one thread).
pub(super) const MIN_PARALLEL: usize = 512;

/// The point distribution as sorted Morton codes: enough to find the
/// adaptive, 2:1-balanced tree of any leaf size ([`ferrofmm_tree::shape`])
/// and count its work ([`Occupancy::work`]) without building a tree, at a
/// fraction of the cost of building one.
///
/// ```
/// use ferrofmm_fmm::Geometry;
/// use ferrofmm_fmm::tuning::Occupancy;
/// let points: Vec<f64> = Geometry::Cube.points(20_000, 1);
/// let occ = Occupancy::new(&points, None, None, 19).unwrap();
/// let coarse = occ.work(400);
/// let fine = occ.work(32);
/// assert!(fine.n_boxes > coarse.n_boxes);
/// assert!(fine.p2p_pairs < coarse.p2p_pairs);
/// ```
pub struct Occupancy {
    codes: MortonCodes,
    max_level: u32,
}

impl Occupancy {
    /// Morton codes (deepest level) of the sources and, when different, the
    /// targets, in the bounding cube of both (or `domain`), sorted.
    /// `max_level` is the deepest level a box may have.
    ///
    /// # Errors
    /// Invalid points, or points outside `domain` ([`FmmError::Tree`]).
    pub fn new(
        sources: &[f64],
        targets: Option<&[f64]>,
        domain: Option<Domain>,
        max_level: u32,
    ) -> Result<Self, FmmError> {
        let domain = match domain {
            Some(d) => d,
            None => match targets {
                Some(t) => Domain::from_points(&[sources, t])?,
                None => Domain::from_points(&[sources])?,
            },
        };
        Ok(Occupancy {
            codes: MortonCodes::new(sources, targets, domain)?,
            max_level: max_level.min(DEEPEST_LEVEL),
        })
    }

    /// The cube the codes are taken in.
    pub fn domain(&self) -> &Domain {
        self.codes.domain()
    }

    /// Number of sources.
    pub fn n_sources(&self) -> usize {
        self.codes.n_sources()
    }

    /// Number of targets.
    pub fn n_targets(&self) -> usize {
        self.codes.n_targets()
    }

    /// The adaptive refinement for `leaf_size`, before balancing (the tree
    /// builder's own, [`MortonCodes::refine`]).
    pub fn refine(&self, leaf_size: usize) -> TreeShape {
        self.codes.refine(leaf_size.max(1), self.max_level)
    }

    /// Estimated [`WorkCounts`] of the tree built with `leaf_size`, counted
    /// on the simulated 2:1-balanced tree: U-, W- and X-list work by walking
    /// each leaf's neighbourhood as the interaction lists do, V-list pairs
    /// from the child masks of adjacent parents, both with the tree's own
    /// list rules ([`ferrofmm_tree::list_rules`]). Close to the real tree's
    /// counts (within a few percent for uniform points, within about 20% for
    /// strongly clustered ones; the differences come from boxes holding
    /// only sources or only targets and from balancing details).
    pub fn work(&self, leaf_size: usize) -> WorkCounts {
        self.work_of(self.refine(leaf_size.max(1)))
    }

    /// [`Occupancy::work`] of a refinement ([`Occupancy::refine`]),
    /// balanced first.
    pub fn work_of(&self, mut shape: TreeShape) -> WorkCounts {
        shape.balance(&self.codes);
        let levels = count_levels(&shape);
        let depth = (levels.len() - 1) as u32;
        let n_boxes: usize = levels.iter().map(|l| l.keys.len()).sum();
        let n_leaves: usize = levels
            .iter()
            .map(|l| l.masks.iter().filter(|&&m| m == 0).count())
            .sum();
        let m2l_boxes: usize = levels.iter().skip(2).map(|l| l.keys.len()).sum();

        // V-list pairs, counted from the parents' level.
        let mut m2l_pairs = 0.0;
        for parents in levels.iter().skip(1) {
            let split: Vec<usize> = (0..parents.keys.len())
                .filter(|&i| parents.masks[i] != 0)
                .collect();
            let stride = split.len().div_ceil(MAX_SAMPLED_LEAVES).max(1);
            let sampled: Vec<usize> = split.iter().step_by(stride).copied().collect();
            let scale = split.len() as f64 / sampled.len().max(1) as f64;
            m2l_pairs += scale
                * sampled
                    .par_iter()
                    .with_min_len(MIN_PARALLEL)
                    .map(|&i| {
                        let mp = parents.masks[i];
                        let mut pairs = 0u32;
                        for (oi, o) in offsets().enumerate() {
                            let Some(q) = parents.keys[i].neighbour(o) else {
                                continue;
                            };
                            let Some(j) = parents.find(q) else {
                                continue;
                            };
                            let mq = parents.masks[j];
                            if mq == 0 {
                                continue;
                            }
                            for c in 0..8 {
                                if mp & (1 << c) != 0 {
                                    pairs += (v_children(oi, c) & mq).count_ones();
                                }
                            }
                        }
                        pairs as f64
                    })
                    .sum::<f64>();
        }

        // U (P2P) and W/X (M2P/P2L) work, per leaf.
        let (mut p2p_pairs, mut far_points, mut u_entries) = (0.0, 0.0, 0.0);
        for (l, lv) in levels.iter().enumerate() {
            let leaves: Vec<usize> = (0..lv.keys.len()).filter(|&i| lv.masks[i] == 0).collect();
            // A level with many leaves is estimated from an evenly spaced
            // sample of them (Morton order, so all regions are represented).
            let stride = leaves.len().div_ceil(MAX_SAMPLED_LEAVES).max(1);
            let sampled: Vec<usize> = leaves.iter().step_by(stride).copied().collect();
            if sampled.is_empty() {
                continue;
            }
            let scale = leaves.len() as f64 / sampled.len() as f64;
            let (p, f, u) = sampled
                .par_iter()
                .with_min_len(MIN_PARALLEL)
                .map_init(Vec::new, |stack, &i| leaf_work(&levels, l, i, stack))
                .reduce(|| (0.0, 0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
            p2p_pairs += scale * p;
            far_points += scale * f;
            u_entries += scale * u;
        }

        WorkCounts {
            n_sources: self.n_sources(),
            n_targets: self.n_targets(),
            depth,
            n_boxes,
            n_leaves,
            m2l_boxes,
            p2p_pairs,
            m2l_pairs,
            far_points,
            u_entries,
            rounding_ratio: levels
                .iter()
                .flat_map(|lv| lv.keys.iter().zip(&lv.masks))
                .filter(|&(_, &m)| m == 0)
                .map(|(&k, _)| center_ratio(k, self.codes.domain()))
                .fold(0.0, f64::max),
        }
    }
}

/// `|center - o| / half-width` of a box, `o` the point the FMM makes its
/// coordinates relative to (`crate::coordinates::coordinate_origin`).
pub(super) fn center_ratio(key: MortonKey, domain: &Domain) -> f64 {
    let c = key.center(domain);
    let o = crate::coordinates::coordinate_origin(domain);
    let r = [c[0] - o[0], c[1] - o[1], c[2] - o[2]];
    (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt() / key.half_width(domain)
}

/// The simulated tree as the tree crate's near-field walk reads it
/// ([`walk_near_field`]): a box is `(level, index)`.
struct LevelsView<'a>(&'a [CountLevel]);

impl NeighbourhoodView for LevelsView<'_> {
    type Box = (usize, usize);

    fn colleague(&self, (l, i): Self::Box, o: usize) -> Option<Self::Box> {
        let nk = self.0[l].keys[i].neighbour(index_offset(o))?;
        self.0[l].find(nk).map(|j| (l, j))
    }

    /// The first existing ancestor of the region: a leaf covers it, an
    /// internal box has no child there (no point).
    fn coarse_leaf(&self, (l, i): Self::Box, o: usize) -> Option<Self::Box> {
        let levels = self.0;
        let nk = levels[l].keys[i].neighbour(index_offset(o))?;
        let (m, a) = (0..l)
            .rev()
            .find_map(|up| count_find(levels, nk.ancestor(up as u32)))?;
        (levels[m].masks[a] == 0).then_some((m, a))
    }

    fn is_leaf(&self, (l, i): Self::Box) -> bool {
        self.0[l].masks[i] == 0
    }

    fn child_mask(&self, (l, i): Self::Box) -> u8 {
        self.0[l].masks[i]
    }

    fn child(&self, (l, i): Self::Box, octant: usize) -> Option<Self::Box> {
        let key = self.0[l].keys[i].children()[octant];
        self.0.get(l + 1)?.find(key).map(|j| (l + 1, j))
    }

    fn is_adjacent(&self, (l, i): Self::Box, (m, j): Self::Box) -> bool {
        self.0[l].keys[i].is_adjacent(self.0[m].keys[j])
    }
}

/// `(P2P pairs, far points, U-list entries)` of leaf `(l, i)`: its
/// targets times the sources of its U list, for every W-list box `a` its
/// targets (M2P) plus, for the matching X-list entry of `a`, its sources
/// (P2L), and the length of its U list; the lists walked by the tree's own
/// walk ([`walk_near_field`]), unpruned.
pub(super) fn leaf_work(
    levels: &[CountLevel],
    l: usize,
    i: usize,
    stack: &mut Vec<(usize, usize)>,
) -> (f64, f64, f64) {
    let lv = &levels[l];
    let nt = lv.n_targets(i) as f64;
    let ns_self = lv.n_sources(i) as f64;
    let (mut u_sources, mut u_entries, mut w_boxes) = (ns_self, 1u32, 0u32);
    walk_near_field(
        &LevelsView(levels),
        (l, i),
        NearLists::Both,
        stack,
        |entry| match entry {
            NearEntry::Adjacent((m, a)) => {
                u_sources += levels[m].n_sources(a) as f64;
                u_entries += 1;
            }
            NearEntry::Separated { .. } => w_boxes += 1,
        },
    );
    (
        nt * u_sources,
        w_boxes as f64 * (nt + ns_self),
        u_entries as f64,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Geometry;
    use ferrofmm_tree::{Octree, TreeOptions};

    /// The shape is the tree builder's (boxes and leaves exactly); the
    /// list work is counted from child masks, without the lists' pruning
    /// of boxes that exchange nothing, so it is close, not equal.
    #[test]
    fn estimated_work_follows_the_real_tree() {
        for g in Geometry::ALL {
            let pts: Vec<f64> = g.points(20_000, 5);
            let occ = Occupancy::new(&pts, None, None, DEEPEST_LEVEL).unwrap();
            for leaf in [32, 150, 400] {
                let tree = Octree::new(&pts, None, &TreeOptions::adaptive(leaf)).unwrap();
                let real = WorkCounts::of_tree(&tree);
                let est = occ.work(leaf);
                let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 1.0 + a };
                let checks = [
                    ("boxes", ratio(est.n_boxes as f64, real.n_boxes as f64), 0.0),
                    (
                        "leaves",
                        ratio(est.n_leaves as f64, real.n_leaves as f64),
                        0.0,
                    ),
                    ("p2p", ratio(est.p2p_pairs, real.p2p_pairs), 0.05),
                    ("m2l", ratio(est.m2l_pairs, real.m2l_pairs), 0.05),
                    ("u", ratio(est.u_entries, real.u_entries), 0.05),
                    ("far", ratio(est.far_points, real.far_points), 0.1),
                    (
                        "ratio",
                        ratio(est.rounding_ratio, real.rounding_ratio),
                        0.01,
                    ),
                ];
                for (what, r, tol) in checks {
                    assert!((r - 1.0).abs() <= tol, "{g:?} leaf {leaf}: {what} {r}");
                }
                assert_eq!(est.depth, real.depth);
            }
        }
    }
}
