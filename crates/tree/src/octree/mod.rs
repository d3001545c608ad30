//! The linear octree: plain data in flat arrays.
//!
//! # Layout
//!
//! Boxes are numbered `0 .. n_boxes()` in **(level, Morton)** order: the
//! root is box 0, then the boxes of level 1 in Morton order, and so on, so
//! every level is one contiguous range ([`Octree::level_range`]) and the
//! existing children of a box are contiguous in the next level
//! ([`Octree::children`]), in octant order. Only boxes holding at least one
//! source or target exist; all ancestors of an existing box exist.
//!
//! Points are stored sorted along the Morton curve of their finest cell, so
//! the points of any box — leaf or not — form one range
//! ([`Octree::source_range`], [`Octree::target_range`]). Every point lies in
//! exactly one leaf. [`Octree::source_permutation`] maps a sorted position to
//! the caller's index, [`Octree::source_inverse_permutation`] the other way,
//! so results can be returned in the caller's order.
//!
//! Interaction lists are CSR arrays indexed by box (see
//! [`lists`](crate::lists)).

use std::ops::Range;
use std::sync::OnceLock;

use crate::balance::balance;
use crate::build::{Node, PointKeys, Refinement, SortedPoints, refine, sort_points};
use crate::domain::{Domain, check_inside, check_periodic_faces, validate_sets};
use crate::error::TreeError;
use crate::list_rules::offset_index;
use crate::lists::InteractionLists;

mod build_step;
mod list_access;
use crate::morton::MortonKey;
use crate::neighbours::ColleagueTable;
use crate::options::TreeOptions;
pub use build_step::TreeBuildStep;

/// One point set in sorted order.
#[derive(Clone, Debug)]
struct Sorted {
    coords: Vec<f64>,
    perm: Vec<usize>,
    /// The inverse of `perm`, made when first asked for (the FMM never
    /// asks: 8 bytes a point saved).
    inverse: OnceLock<Vec<usize>>,
}

impl Sorted {
    fn new(s: SortedPoints) -> Self {
        Sorted {
            coords: s.coords,
            perm: s.perm,
            inverse: OnceLock::new(),
        }
    }

    fn inverse(&self) -> &[usize] {
        self.inverse.get_or_init(|| {
            let mut inverse = vec![0; self.perm.len()];
            for (k, &i) in self.perm.iter().enumerate() {
                inverse[i] = k;
            }
            inverse
        })
    }
}

/// A linear adaptive (or uniform) octree over sources and targets, 2:1
/// balanced, with its U, V, W and X interaction lists.
///
/// ```
/// use ferrofmm_tree::{Octree, TreeOptions};
/// // 1000 points on a helix, at most 20 per leaf.
/// let pts: Vec<f64> = (0..1000)
///     .flat_map(|i| {
///         let t = i as f64 * 0.01;
///         [t.cos(), t.sin(), 0.1 * t]
///     })
///     .collect();
/// let tree = Octree::new(&pts, None, &TreeOptions::adaptive(20)).unwrap();
/// let total: usize = tree.leaves().iter().map(|&b| tree.source_range(b).len()).sum();
/// assert_eq!(total, 1000);
/// for &b in tree.leaves() {
///     assert!(tree.u_list(b).contains(&b));
/// }
/// ```
#[derive(Clone, Debug)]
pub struct Octree {
    domain: Domain,
    keys: Vec<MortonKey>,
    level_offsets: Vec<usize>,
    parents: Vec<usize>,
    children: Vec<[usize; 2]>,
    child_masks: Vec<u8>,
    source_child_masks: Vec<u8>,
    leaves: Vec<usize>,
    src_ranges: Vec<[usize; 2]>,
    tgt_ranges: Vec<[usize; 2]>,
    sources: Sorted,
    targets: Option<Sorted>,
    colleagues: ColleagueTable,
    lists: InteractionLists,
    /// Whether the tree is 2:1 balanced (and has interaction lists).
    balanced: bool,
    /// Periodic axes.
    periodic: [bool; 3],
}

const NONE: usize = usize::MAX;

impl Octree {
    /// Builds the tree: validates the points, computes the domain (unless
    /// given), sorts the points along the Morton curve, refines (adaptive or
    /// uniform, see [`TreeOptions`]), 2:1 balances adaptive trees and builds
    /// the interaction lists.
    ///
    /// Sources and targets are interleaved `xyz` (`f64`). `targets == None`
    /// means the targets are the sources.
    ///
    /// # Errors
    /// Invalid options ([`TreeOptions::validate`]); a length that is not a
    /// multiple of 3; a NaN or infinite coordinate; no sources, or an empty
    /// target set; a point outside a given domain; periodic axes without a
    /// given domain, or a point on the upper face of a periodic axis. See
    /// [`TreeError`].
    ///
    /// With periodic axes ([`TreeOptions::periodic`]) the root box is the
    /// periodic cell, and the balance, the colleague table and the lists
    /// wrap around it (see [`lists`](crate::lists)).
    pub fn new(
        sources: &[f64],
        targets: Option<&[f64]>,
        options: &TreeOptions,
    ) -> Result<Self, TreeError> {
        Self::new_reporting(sources, targets, options, &|_| {})
    }

    /// [`Octree::new`], calling `report` as each step of the build ends
    /// (see [`TreeBuildStep`]), so that a caller can show a bar with the
    /// time left for a tree of many millions of points.
    ///
    /// ```
    /// use std::sync::Mutex;
    /// use ferrofmm_tree::{Octree, TreeBuildStep, TreeOptions};
    /// let pts: Vec<f64> = (0..3000).map(|i| ((i * 7919) % 1000) as f64 * 1e-3).collect();
    /// let seen = Mutex::new(Vec::new());
    /// let tree = Octree::new_reporting(&pts, None, &TreeOptions::adaptive(20), &|s| {
    ///     seen.lock().unwrap().push(s)
    /// })
    /// .unwrap();
    /// assert_eq!(*seen.lock().unwrap(), TreeBuildStep::ALL);
    /// assert_eq!(TreeBuildStep::Lists.done_share(), 1.0);
    /// # let _ = tree;
    /// ```
    ///
    /// # Errors
    /// As [`Octree::new`] (nothing is reported after an error).
    pub fn new_reporting(
        sources: &[f64],
        targets: Option<&[f64]>,
        options: &TreeOptions,
        report: &(dyn Fn(TreeBuildStep) + Sync),
    ) -> Result<Self, TreeError> {
        options.validate()?;
        let sets = validate_sets(sources, targets)?;
        let domain = match options.domain {
            Some(d) => {
                for &(set, p) in &sets {
                    check_inside(set, p, &d)?;
                    if options.is_periodic() {
                        check_periodic_faces(set, p, &d, options.periodic)?;
                    }
                }
                d
            }
            None => Domain::bounding(&sets)?,
        };
        report(TreeBuildStep::Checked);
        let (src, tgt) = rayon::join(
            || sort_points(sources, &domain),
            || targets.map(|t| sort_points(t, &domain)),
        );
        let pts = PointKeys {
            src: &src.keys,
            tgt: tgt.as_ref().map_or(&src.keys, |t| &t.keys),
            same: tgt.is_none(),
        };
        let rule = match options.uniform_depth {
            Some(d) => Refinement::Uniform(d),
            None => Refinement::Adaptive {
                leaf_size: options.leaf_size,
                max_level: options.max_level,
            },
        };
        report(TreeBuildStep::Sorted);
        let mut levels = refine(&pts, rule);
        report(TreeBuildStep::Refined);
        let adaptive = matches!(rule, Refinement::Adaptive { .. });
        if adaptive && options.balance {
            balance(&mut levels, &pts, options.periodic);
        }
        report(TreeBuildStep::Balanced);
        let mut tree = Self::flatten(domain, &levels);
        tree.periodic = options.periodic;
        tree.sources = Sorted::new(src);
        tree.targets = tgt.map(Sorted::new);
        tree.colleagues = ColleagueTable::build(&tree);
        report(TreeBuildStep::Colleagues);
        tree.lists = if adaptive && !options.balance {
            InteractionLists::empty(tree.n_boxes(), tree.is_periodic())
        } else {
            InteractionLists::build(&tree)
        };
        tree.balanced = !adaptive || options.balance;
        report(TreeBuildStep::Lists);
        Ok(tree)
    }

    /// A tree of the boxes `boxes` (key, leaf flag) and all their ancestors,
    /// without points: every box counts as holding sources and targets
    /// (ranges `0..1`, no coordinates), with its colleague table but no
    /// lists. A box flagged internal that has no child among the boxes gets
    /// a placeholder child holding nothing (ranges `0..0`), so that it is
    /// internal in the tree while the lists, which keep only boxes with
    /// sources, never reference the placeholder. Only for
    /// [`lists_of_boxes`](crate::lists::lists_of_boxes).
    pub(crate) fn skeleton(boxes: &[(MortonKey, bool)]) -> Self {
        let mut all: Vec<(MortonKey, bool)> = boxes
            .iter()
            .flat_map(|&(k, _)| std::iter::once(k).chain(k.ancestors()))
            .chain(std::iter::once(MortonKey::ROOT))
            .map(|k| (k, true))
            .collect();
        let has_child = |all: &[(MortonKey, bool)], k: MortonKey| {
            k.level() < crate::DEEPEST_LEVEL
                && k.children()
                    .iter()
                    .any(|c| all.binary_search_by_key(c, |&(x, _)| x).is_ok())
        };
        all.sort_unstable();
        all.dedup_by_key(|b| b.0);
        let placeholders: Vec<(MortonKey, bool)> = boxes
            .iter()
            .filter(|&&(k, leaf)| !leaf && !has_child(&all, k))
            .filter(|&&(k, _)| k.level() < crate::DEEPEST_LEVEL)
            .map(|&(k, _)| (k.children()[0], false))
            .collect();
        all.extend(placeholders);
        all.sort_unstable_by_key(|&(k, real)| (k.level(), k, !real));
        all.dedup_by_key(|b| b.0);
        let depth = all.last().map_or(0, |b| b.0.level() as usize);
        let mut levels: Vec<Vec<Node>> = vec![Vec::new(); depth + 1];
        for (key, real) in all {
            let r = [0, usize::from(real)];
            levels[key.level() as usize].push(Node {
                key,
                src: r,
                tgt: r,
                leaf: false,
            });
        }
        let domain = Domain {
            origin: [0.0; 3],
            width: 1.0,
        };
        let mut tree = Self::flatten(domain, &levels);
        tree.colleagues = ColleagueTable::build(&tree);
        tree
    }

    /// A tree from parts computed elsewhere: the domain, the boxes with the
    /// ranges of their points (`(key, sources, targets)`, sorted by level,
    /// then Morton order, the root first, every box's parent among them)
    /// and the four interaction lists (one row per box, entries indexing
    /// `boxes`). The ranges index the caller's own point arrays, sorted
    /// along the Morton curve so that each box's points are contiguous; no
    /// coordinates or permutations are stored ([`Octree::sorted_sources`]
    /// and [`Octree::source_permutation`] are empty, and
    /// [`Octree::n_sources`] is 0).
    ///
    /// What it is for: one process of a distributed FMM holds a piece of
    /// the global tree (its own boxes, the coarse tree above them and the
    /// ghost boxes its lists reference), with lists it chose itself (for
    /// instance only the rows of its own boxes), and runs the
    /// single-machine passes on it.
    ///
    /// A box with no child among `boxes` is a leaf of this tree.
    ///
    /// ```
    /// use ferrofmm_tree::{Octree, TreeOptions};
    /// let pts: Vec<f64> = (0..600).map(|i| (i as f64 * 0.618_034).fract()).collect();
    /// let tree = Octree::new(&pts, None, &TreeOptions::adaptive(10)).unwrap();
    /// let boxes: Vec<_> = (0..tree.n_boxes())
    ///     .map(|b| (tree.key(b), tree.source_range(b), tree.target_range(b)))
    ///     .collect();
    /// let copy = Octree::from_parts(*tree.domain(), &boxes, tree.interaction_lists().clone()).unwrap();
    /// assert_eq!(copy.keys(), tree.keys());
    /// assert_eq!(copy.leaves(), tree.leaves());
    /// assert_eq!(copy.v_list(5), tree.v_list(5));
    /// ```
    ///
    /// # Errors
    /// [`TreeError::InvalidParts`]: no boxes, boxes out of order or
    /// repeated, a box whose parent is missing, a reversed range, or lists
    /// whose row count or entries do not match the boxes, or lists with
    /// image shifts (the tree is a free-space one).
    pub fn from_parts(
        domain: Domain,
        boxes: &[(MortonKey, Range<usize>, Range<usize>)],
        lists: InteractionLists,
    ) -> Result<Self, TreeError> {
        let bad = |reason| Err(TreeError::InvalidParts { reason });
        if boxes.first().map(|b| b.0) != Some(MortonKey::ROOT) {
            return bad("the first box must be the root");
        }
        let order = |k: MortonKey| (k.level(), k);
        if boxes.windows(2).any(|w| order(w[0].0) >= order(w[1].0)) {
            return bad("boxes not sorted by (level, key) or repeated");
        }
        if boxes
            .iter()
            .any(|b| b.1.start > b.1.end || b.2.start > b.2.end)
        {
            return bad("a reversed point range");
        }
        let n = boxes.len();
        let present = |k: MortonKey| {
            boxes
                .binary_search_by_key(&order(k), |b| order(b.0))
                .is_ok()
        };
        if boxes[1..].iter().any(|b| !present(b.0.parent())) {
            return bad("a box whose parent is missing");
        }
        for csr in [&lists.u, &lists.v, &lists.w, &lists.x] {
            if csr.n_rows() != n {
                return bad("lists do not have one row per box");
            }
            if csr.indices().iter().any(|&a| a >= n) {
                return bad("a list entry out of range");
            }
            if csr.shifts().is_some() {
                return bad("lists with image shifts (periodic) in a free-space tree");
            }
        }
        let depth = boxes[n - 1].0.level() as usize;
        let mut levels: Vec<Vec<Node>> = vec![Vec::new(); depth + 1];
        for (key, s, t) in boxes {
            levels[key.level() as usize].push(Node {
                key: *key,
                src: [s.start, s.end],
                tgt: [t.start, t.end],
                leaf: false,
            });
        }
        let mut tree = Self::flatten(domain, &levels);
        tree.colleagues = ColleagueTable::build(&tree);
        tree.lists = lists;
        Ok(tree)
    }

    /// Flat arrays from the per-level boxes.
    fn flatten(domain: Domain, levels: &[Vec<Node>]) -> Self {
        let n: usize = levels.iter().map(Vec::len).sum();
        let mut level_offsets = Vec::with_capacity(levels.len() + 1);
        let mut keys = Vec::with_capacity(n);
        let mut src_ranges = Vec::with_capacity(n);
        let mut tgt_ranges = Vec::with_capacity(n);
        for lv in levels {
            level_offsets.push(keys.len());
            for node in lv {
                keys.push(node.key);
                src_ranges.push(node.src);
                tgt_ranges.push(node.tgt);
            }
        }
        level_offsets.push(n);

        // Parents and children: walk each level alongside the next one.
        let mut parents = vec![NONE; n];
        let mut children = vec![[0usize; 2]; n];
        for l in 0..levels.len() {
            let (start, end) = (level_offsets[l], level_offsets[l + 1]);
            let next_end = level_offsets.get(l + 2).copied().unwrap_or(end);
            let mut c = end;
            for p in start..end {
                let first = c;
                while c < next_end && keys[c].parent() == keys[p] {
                    parents[c] = p;
                    c += 1;
                }
                children[p] = [first, c];
            }
            debug_assert_eq!(c, next_end, "every box has a parent");
        }
        let leaves = (0..n)
            .filter(|&b| children[b][0] == children[b][1])
            .collect();
        // Octant masks of the existing children, and of those with sources.
        let mut child_masks = vec![0u8; n];
        let mut source_child_masks = vec![0u8; n];
        for c in 1..n {
            let p = parents[c];
            let bit = 1u8 << keys[c].octant();
            child_masks[p] |= bit;
            if src_ranges[c][0] < src_ranges[c][1] {
                source_child_masks[p] |= bit;
            }
        }
        Octree {
            domain,
            keys,
            level_offsets,
            parents,
            children,
            child_masks,
            source_child_masks,
            leaves,
            src_ranges,
            tgt_ranges,
            sources: Sorted {
                coords: Vec::new(),
                perm: Vec::new(),
                inverse: OnceLock::new(),
            },
            targets: None,
            colleagues: ColleagueTable::default(),
            lists: InteractionLists::default(),
            balanced: true,
            periodic: [false; 3],
        }
    }

    /// The root cube.
    pub fn domain(&self) -> &Domain {
        &self.domain
    }

    /// The periodic axes (x, y, z) the tree was built with
    /// ([`TreeOptions::periodic`]); all `false` in free space.
    pub fn periodic_axes(&self) -> [bool; 3] {
        self.periodic
    }

    /// `true` if some axis is periodic: the colleague table and the lists
    /// wrap around the domain, and the lists carry image shifts
    /// ([`u_shifts`](Self::u_shifts) and the like).
    pub fn is_periodic(&self) -> bool {
        self.periodic.iter().any(|&p| p)
    }

    /// The deepest level present (0 for a tree that is only the root).
    pub fn depth(&self) -> u32 {
        (self.level_offsets.len() - 2) as u32
    }

    /// Number of boxes (all levels).
    pub fn n_boxes(&self) -> usize {
        self.keys.len()
    }

    /// Keys of all boxes, sorted by (level, Morton code); box `b` is
    /// `keys()[b]`.
    pub fn keys(&self) -> &[MortonKey] {
        &self.keys
    }

    /// Key of box `b`.
    pub fn key(&self, b: usize) -> MortonKey {
        self.keys[b]
    }

    /// Level of box `b`.
    pub fn level(&self, b: usize) -> u32 {
        self.keys[b].level()
    }

    /// Box indices of `level` (an empty range if the tree has no such level).
    pub fn level_range(&self, level: u32) -> Range<usize> {
        let l = level as usize;
        if l + 1 < self.level_offsets.len() {
            self.level_offsets[l]..self.level_offsets[l + 1]
        } else {
            self.n_boxes()..self.n_boxes()
        }
    }

    /// Index of the box with `key`, if it exists (binary search within its
    /// level).
    pub fn index_of(&self, key: MortonKey) -> Option<usize> {
        let r = self.level_range(key.level());
        let start = r.start;
        self.keys[r].binary_search(&key).ok().map(|i| start + i)
    }

    /// Parent of box `b` (`None` for the root).
    pub fn parent(&self, b: usize) -> Option<usize> {
        let p = self.parents[b];
        (p != NONE).then_some(p)
    }

    /// The existing children of `b`: contiguous in the next level, in octant
    /// order (empty for leaves).
    pub fn children(&self, b: usize) -> Range<usize> {
        let [s, e] = self.children[b];
        s..e
    }

    /// Bit `o` is set if the child of octant `o` of box `b` exists.
    pub fn child_mask(&self, b: usize) -> u8 {
        self.child_masks[b]
    }

    /// Bit `o` is set if the child of octant `o` of box `b` holds sources.
    pub(crate) fn source_child_mask(&self, b: usize) -> u8 {
        self.source_child_masks[b]
    }

    /// The child of `b` in `octant`, if it exists.
    #[inline]
    pub fn child(&self, b: usize, octant: usize) -> Option<usize> {
        let mask = self.child_masks[b];
        (mask >> octant & 1 == 1)
            .then(|| self.children[b][0] + (mask & ((1u8 << octant) - 1)).count_ones() as usize)
    }

    /// `true` if `b` has no children.
    pub fn is_leaf(&self, b: usize) -> bool {
        let [s, e] = self.children[b];
        s == e
    }

    /// Leaf box indices, ascending (by level, then Morton code).
    pub fn leaves(&self) -> &[usize] {
        &self.leaves
    }

    /// The existing same-level neighbour of `b` at `offset` (each component
    /// in `-1..=1`; `[0, 0, 0]` gives `b`), from a precomputed table. In a
    /// periodic tree the offset wraps around periodic axes: the neighbour
    /// is the returned box translated by
    /// [`colleague_shift`](Self::colleague_shift)`(b, offset)` domain widths
    /// (at levels 0 and 1 one box may be the neighbour at several offsets).
    ///
    /// # Panics
    /// If a component of `offset` is outside `-1..=1`.
    pub fn colleague(&self, b: usize, offset: [i32; 3]) -> Option<usize> {
        self.colleagues.get(b, offset_index(offset))
    }

    /// The image shift of `b`'s neighbour at `offset` (see
    /// [`colleague`](Self::colleague)): per axis, `-1` or `1` where the
    /// offset crosses a periodic face of the domain, else 0 (always
    /// `[0; 3]` in free space).
    ///
    /// ```
    /// use ferrofmm_tree::{Domain, Octree, TreeOptions};
    /// let pts = [0.1, 0.1, 0.1, 0.9, 0.1, 0.1];
    /// let cell = Domain::new([0.0; 3], 1.0).unwrap();
    /// let opts = TreeOptions::adaptive(1).with_domain(cell).with_periodic([true, false, false]);
    /// let tree = Octree::new(&pts, None, &opts).unwrap();
    /// let (a, b) = (1, 2); // the two leaves of level 1, at x = 0 and x = 1
    /// assert_eq!(tree.colleague(a, [-1, 0, 0]), Some(b));
    /// assert_eq!(tree.colleague_shift(a, [-1, 0, 0]), [-1, 0, 0]);
    /// assert_eq!(tree.colleague(a, [1, 0, 0]), Some(b));
    /// assert_eq!(tree.colleague_shift(a, [1, 0, 0]), [0, 0, 0]);
    /// ```
    ///
    /// # Panics
    /// If a component of `offset` is outside `-1..=1`.
    pub fn colleague_shift(&self, b: usize, offset: [i32; 3]) -> [i8; 3] {
        // Checks the offset.
        offset_index(offset);
        if !self.is_periodic() {
            return [0; 3];
        }
        let own = crate::neighbours::level_coords(self, b);
        let level = self.level(b);
        std::array::from_fn(|a| ((own[a] + offset[a] as i64) >> level) as i8)
    }

    /// Colleague at a table index (see [`crate::neighbours`]).
    #[inline]
    pub(crate) fn colleague_at(&self, b: usize, i: usize) -> Option<usize> {
        self.colleagues.get(b, i)
    }

    /// Number of sources.
    pub fn n_sources(&self) -> usize {
        self.sources.perm.len()
    }

    /// Number of targets.
    pub fn n_targets(&self) -> usize {
        self.target_set().perm.len()
    }

    /// The sources of box `b` (any box, descendants included) as a range of
    /// sorted positions.
    pub fn source_range(&self, b: usize) -> Range<usize> {
        let [s, e] = self.src_ranges[b];
        s..e
    }

    /// The targets of box `b` as a range of sorted positions.
    pub fn target_range(&self, b: usize) -> Range<usize> {
        let [s, e] = self.tgt_ranges[b];
        s..e
    }

    /// `true` if box `b` holds at least one source.
    pub fn has_sources(&self, b: usize) -> bool {
        let [s, e] = self.src_ranges[b];
        s < e
    }

    /// `true` if box `b` holds at least one target.
    pub fn has_targets(&self, b: usize) -> bool {
        let [s, e] = self.tgt_ranges[b];
        s < e
    }

    /// Source coordinates in sorted order (interleaved `xyz`): sorted point
    /// `k` is `sorted_sources()[3k..3k + 3]`.
    pub fn sorted_sources(&self) -> &[f64] {
        &self.sources.coords
    }

    /// Target coordinates in sorted order (the sources when
    /// [`sources_are_targets`](Self::sources_are_targets)).
    pub fn sorted_targets(&self) -> &[f64] {
        &self.target_set().coords
    }

    /// Sorted position `k` holds original source `source_permutation()[k]`.
    pub fn source_permutation(&self) -> &[usize] {
        &self.sources.perm
    }

    /// Sorted position `k` holds original target `target_permutation()[k]`.
    pub fn target_permutation(&self) -> &[usize] {
        &self.target_set().perm
    }

    /// Original source `i` is at sorted position
    /// `source_inverse_permutation()[i]`.
    /// Made (`8` bytes a point) when first asked for.
    pub fn source_inverse_permutation(&self) -> &[usize] {
        self.sources.inverse()
    }

    /// Original target `i` is at sorted position
    /// `target_inverse_permutation()[i]`.
    /// Made (`8` bytes a point) when first asked for.
    pub fn target_inverse_permutation(&self) -> &[usize] {
        self.target_set().inverse()
    }

    /// Hand the sorted coordinates over to the caller (sources, and targets
    /// unless [`sources_are_targets`](Self::sources_are_targets)), leaving
    /// [`sorted_sources`](Self::sorted_sources) and
    /// [`sorted_targets`](Self::sorted_targets) empty: for a caller that
    /// keeps its own copy of the points in tree order (the FMM keeps them
    /// relative to a centre, in its float type), so that they are not held
    /// twice (`24` bytes a point). Ranges, permutations, lists and
    /// everything else are unchanged.
    pub fn take_sorted_points(&mut self) -> (Vec<f64>, Option<Vec<f64>>) {
        let sources = std::mem::take(&mut self.sources.coords);
        let targets = self.targets.as_mut().map(|t| std::mem::take(&mut t.coords));
        (sources, targets)
    }

    /// `true` if the tree was built with `targets == None`: target ranges,
    /// permutations and coordinates are those of the sources.
    pub fn sources_are_targets(&self) -> bool {
        self.targets.is_none()
    }

    fn target_set(&self) -> &Sorted {
        self.targets.as_ref().unwrap_or(&self.sources)
    }
}
