//! Interaction lists of the adaptive FMM (Ying, Biros & Zorin 2004).
//!
//! # Definitions
//!
//! Two boxes are *adjacent* when they touch (share a face, edge or corner)
//! and neither contains the other ([`MortonKey::is_adjacent`]); the
//! *colleagues* of a box are the adjacent boxes of its own level. For a
//! **target box** `B` of level `l`:
//!
//! * **U(B)**, `B` a leaf: the leaves adjacent to `B`, and `B` itself.
//!   Direct evaluation (P2P).
//! * **V(B)**, any box: the children of the colleagues of `parent(B)` that are
//!   not adjacent to `B` — same-level, well-separated boxes (M2L). At most
//!   `6^3 - 3^3 = 189`.
//! * **W(B)**, `B` a leaf: the descendants `A` of `B`'s colleagues that are
//!   not adjacent to `B` while `parent(A)` is. `A`'s multipole expansion is
//!   evaluated at `B`'s targets (M2P).
//! * **X(B)**, any box: the dual of W, `A ∈ X(B)` iff `B ∈ W(A)`. `A` is
//!   then a leaf coarser than `B`, adjacent to `parent(B)` but not to `B`;
//!   its sources go into `B`'s local expansion (P2L).
//!
//! **Pruning.** Only boxes holding a source or a target exist, and an entry
//! `A` of a list of `B` is kept only if `A` holds at least one source and
//! `B` at least one target. Boxes without targets have empty lists.
//!
//! # Why every interaction is counted exactly once
//!
//! Take a target leaf `B` and a source leaf `A`. If they are equal or
//! adjacent, `A ∈ U(B)`. Otherwise look at their ancestors level by level:
//! they are equal at level 0, and once two same-level ancestors are not
//! adjacent, neither are their descendants. Let `m` be the first level where
//! they are neither equal nor adjacent.
//!
//! * If both have an ancestor at level `m` (`A'`, `B'`), then `A' ∈ V(B')`,
//!   because their parents are colleagues.
//! * If `B` is coarser than `m`, `A`'s ancestor at `B`'s level is a colleague
//!   of `B`; going down towards `A`, the first ancestor not adjacent to `B` is
//!   in `W(B)`.
//! * If `A` is coarser than `m`, symmetrically `A ∈ X(B')` for the first
//!   ancestor `B'` of `B` not adjacent to `A`.
//!
//! The three cases exclude each other and the entry in each is unique. So
//! the far field of `B` is: V lists of `B` and its ancestors (passed down by
//! L2L), X lists of `B` and its ancestors (likewise), and `W(B)`; the near
//! field is `U(B)`.
//!
//! # Periodic trees
//!
//! A tree built with periodic axes ([`TreeOptions::periodic`](crate::TreeOptions::periodic))
//! has the given domain, the *cell*, as its root, and stands for the
//! infinite tiling of the cell along those axes (open axes are as in free
//! space). The lists are the definitions above applied to that tiling:
//! adjacency, colleagues and the 2:1 balance ([`balance`](crate::balance))
//! wrap around the periodic faces.
//!
//! **Shifts.** An entry of a list of target box `B` is a pair (box `a`,
//! shift `s`), `s` in `{-1, 0, 1}^3` (0 on open axes): the source is the
//! image of `a` translated by `s[k] * domain.width` along axis `k`. The
//! shifts are a parallel array ([`Csr::shifts`], [`Csr::row_shifts`],
//! [`Octree::u_shifts`](crate::Octree::u_shifts) and the like); free-space
//! lists have none. Rows are ordered by (box, shift) and hold no pair twice,
//! but one box may appear several times with different shifts, at coarse
//! levels especially: a root that is a leaf has `U(root)` = the root with
//! all 27 shifts (fully periodic; 9 for a slab, 3 for a rod), and a box of
//! level 1 sees the other boxes of its level on both sides. A V entry of a
//! box of level `l` has the transfer vector
//! `key(a) - key(b) + s * 2^l` ([`MortonKey::shifted_transfer_vector`]), in
//! `-3..=3` with a component of magnitude `>= 2`, as in free space. The
//! target box is always the one in the cell (shift 0).
//!
//! **Exactly once.** Take a target leaf `B` and an image `A + s` of a
//! source leaf, `|s| <= 1` per axis. Their ancestors at level 0 are the
//! root and its image `root + s`: equal if `s = 0`, adjacent otherwise. So
//! the first level `m` where the ancestors are neither equal nor adjacent
//! is at least 1, and the argument above, run in the tiling, puts `A + s`
//! in exactly one of `U(B)`, `W(B)`, `V(B')` or `X(B')` for `B'` = `B` or
//! an ancestor of level `>= 1`. Every entry derives from a colleague of a
//! box at level `>= 0` (offsets in `-1..=1`), so shifts never exceed one
//! cell: images with `|s|_inf >= 2` — the far field of the root, well
//! separated from the whole cell — are never reached, and the root's V and
//! X lists stay empty. That far field (a lattice sum acting on the root's
//! multipole expansion) is the driver's business.
//!
//! # Sizes
//!
//! With the balance condition of [`balance`](crate::balance), internal boxes
//! adjacent to a leaf of level `l` are at level `<= l`, so W entries are
//! children of colleagues: at most `6·4 + 12·6 + 8·7 = 152` (the children of
//! a face, edge or corner colleague that do not touch `B`), attained when all
//! 26 colleagues are split into 8 children. X entries are leaves of level
//! `l - 1` adjacent to `parent(B)` but not to `B`: at most `26 - 7 = 19`. U
//! entries are `B` plus leaves covering the 56 cells of level `l + 1` around
//! `B`: at most 57.
//!
//! # Storage and order
//!
//! Each list is a [`Csr`]: row `b` is `indices[offsets[b]..offsets[b + 1]]`,
//! ascending box indices (so by level, then Morton order). Lists are built in
//! parallel over boxes from the [colleague table](crate::Octree::colleague),
//! without any search.
//!
//! # Notes for an FMM driver
//!
//! * U and W rows exist only for leaves; V and X rows for any box with
//!   targets. V rows are empty at levels 0 and 1 (the root has no
//!   colleagues), X rows at levels 0 and 1 as well.
//! * U(B) contains B itself (when B holds sources): P2P over U is the whole
//!   near field, self-interaction included.
//! * V, W and X entries of a box are all at least one box width (of the
//!   smaller box) away from it; V entries are at the box's own level, W
//!   entries one level finer (children of colleagues), X entries one level
//!   coarser — guaranteed by the 2:1 balance.
//! * The transfer vector of a V entry `a` of `b` is
//!   `key(b).transfer_vector(key(a))`, with components in `-3..=3` and at
//!   least one of magnitude `>= 2` (316 possible vectors); in a periodic
//!   tree, `key(b).shifted_transfer_vector(key(a), s)` with the entry's
//!   shift `s` (same 316 vectors).
//! * In a periodic tree, translate each entry's sources by its shift
//!   (times the cell width) before evaluating: P2P over U, M2L over V (the
//!   shifted transfer vector), M2P over W and P2L over X.

use crate::MortonKey;
use crate::csr::{Csr, Entry, Shifted};
use crate::list_rules::near_field::{NearEntry, NearLists, NeighbourhoodView, walk_near_field};
use crate::list_rules::{colleague_indices, index_offset, v_children};
use crate::neighbours::level_coords;
use crate::octree::Octree;

/// The U, V, W and X lists of a tree (see the [module documentation](self)).
#[derive(Clone, Debug, Default)]
pub struct InteractionLists {
    /// Near field: adjacent leaves and the box itself (P2P).
    pub u: Csr,
    /// Same-level well-separated boxes (M2L).
    pub v: Csr,
    /// Finer well-separated boxes near a leaf (M2P).
    pub w: Csr,
    /// Coarser well-separated leaves (P2L).
    pub x: Csr,
}

impl InteractionLists {
    /// Lists with `n` empty rows (a tree built without 2:1 balance); with
    /// (empty) shift arrays when `periodic`.
    pub(crate) fn empty(n: usize, periodic: bool) -> Self {
        fn e<E: Entry>(n: usize) -> Csr {
            Csr::build::<E, _>(n, |_, _| {})
        }
        let e = |n| {
            if periodic {
                e::<Shifted>(n)
            } else {
                e::<usize>(n)
            }
        };
        InteractionLists {
            u: e(n),
            v: e(n),
            w: e(n),
            x: e(n),
        }
    }

    /// Builds all four lists for `tree` (its structure and colleague table
    /// must be complete); with shifts for a periodic tree.
    pub(crate) fn build(tree: &Octree) -> Self {
        if tree.is_periodic() {
            Self::build_with::<Shifted>(tree)
        } else {
            Self::build_with::<usize>(tree)
        }
    }

    fn build_with<E: Entry>(tree: &Octree) -> Self {
        let n = tree.n_boxes();
        let u = Csr::build(n, |b, out| u_row::<E>(tree, b, out));
        let v = Csr::build_counted(
            n,
            E::PERIODIC,
            |b| v_count(tree, b),
            |s, b, row, shifts| v_fill::<E>(tree, s, b, row, shifts),
        );
        let w = Csr::build(n, |b, out| w_row::<E>(tree, b, out));
        let x = Csr::build(n, |b, out| x_row::<E>(tree, b, out));
        InteractionLists { u, v, w, x }
    }
}

/// The U, V, W and X lists of the tree whose boxes are `boxes` (key and
/// whether it is a leaf of the tree) and all their ancestors, every box
/// counting as holding sources and targets (so nothing is pruned; in a tree
/// of one point set every existing box holds points). Returns the boxes in
/// the tree's order (by level, then Morton order) and the lists, whose
/// entries index that vector. A box flagged internal whose children are not
/// among `boxes` is internal all the same: it gets a placeholder child that
/// holds nothing and appears in no list (but in the returned boxes).
/// Duplicate keys are allowed.
///
/// The lists are computed by the same code as [`Octree::interaction_lists`]
/// and depend only on the boxes near each box: for a box `B` of level `l`,
/// the boxes of levels `l - 1 ..= l + 1` inside the colleagues of
/// `parent(B)`, their ancestors, and whether each is a leaf. So a piece of
/// a tree holding those boxes for `B` gives `B` the rows of the whole tree
/// (what a distributed tree uses to find the boxes it needs from other
/// processes).
///
/// ```
/// use ferrofmm_tree::{Octree, TreeOptions, lists::lists_of_boxes};
/// let pts: Vec<f64> = (0..3000).map(|i| (i as f64 * 0.618_034).fract()).collect();
/// let tree = Octree::new(&pts, None, &TreeOptions::adaptive(10)).unwrap();
/// let boxes: Vec<_> = (0..tree.n_boxes()).map(|b| (tree.key(b), tree.is_leaf(b))).collect();
/// let (keys, lists) = lists_of_boxes(&boxes);
/// assert_eq!(keys, tree.keys());
/// assert_eq!(lists.v.indices(), tree.interaction_lists().v.indices());
/// assert_eq!(lists.x.indices(), tree.interaction_lists().x.indices());
/// ```
pub fn lists_of_boxes(boxes: &[(MortonKey, bool)]) -> (Vec<MortonKey>, InteractionLists) {
    let tree = Octree::skeleton(boxes);
    let lists = InteractionLists::build(&tree);
    (tree.keys().to_vec(), lists)
}

/// The image shift of the box at level coordinates `c` (unwrapped) of
/// `level`: `floor(c / 2^level)` per axis (0 inside the domain).
#[inline]
fn image(c: [i64; 3], level: u32) -> [i8; 3] {
    c.map(|x| (x >> level) as i8)
}

/// Whether `a` translated by `s` and `b` are adjacent (`s` is ignored, and
/// zero, in free space).
#[inline]
fn adjacent<E: Entry>(a: MortonKey, s: [i8; 3], b: MortonKey) -> bool {
    if E::PERIODIC {
        a.is_adjacent_shifted(s, b)
    } else {
        a.is_adjacent(b)
    }
}

/// The shift of a box's colleague at table index `i` (`[0; 3]` in free
/// space); `own` and `level` are the box's level coordinates ([`coords`])
/// and level.
#[inline]
fn colleague_shift<E: Entry>(own: [i64; 3], level: u32, i: usize) -> [i8; 3] {
    if E::PERIODIC {
        let o = index_offset(i);
        image(std::array::from_fn(|a| own[a] + o[a] as i64), level)
    } else {
        [0; 3]
    }
}

/// The level coordinates of `b` when entries carry shifts (computed once
/// per row), else unused zeros.
#[inline]
fn coords<E: Entry>(tree: &Octree, b: usize) -> [i64; 3] {
    if E::PERIODIC {
        level_coords(tree, b)
    } else {
        [0; 3]
    }
}

/// The colleague of `b` at table index `i` with its shift; `own`:
/// [`coords`] of `b`.
#[inline]
fn colleague_of<E: Entry>(
    tree: &Octree,
    b: usize,
    own: [i64; 3],
    i: usize,
) -> Option<(usize, [i8; 3])> {
    let n = tree.colleague_at(b, i)?;
    Some((n, colleague_shift::<E>(own, tree.level(b), i)))
}

/// Where the colleague of `b` at table index `i` does not exist: the
/// coarser leaf covering its region, with the region's shift, if any (the
/// region may hold no point or lie outside the domain). `own`: [`coords`]
/// of `b`.
fn coarse_leaf<E: Entry>(
    tree: &Octree,
    b: usize,
    own: [i64; 3],
    i: usize,
) -> Option<(usize, [i8; 3])> {
    let level = tree.level(b);
    let o = index_offset(i);
    let own = if E::PERIODIC {
        own
    } else {
        level_coords(tree, b)
    };
    let c: [i64; 3] = std::array::from_fn(|a| own[a] + o[a] as i64);
    let s = if E::PERIODIC { image(c, level) } else { [0; 3] };
    let size = 1i64 << level;
    let periodic = tree.periodic_axes();
    if (0..3).any(|a| (!E::PERIODIC || !periodic[a]) && (c[a] < 0 || c[a] >= size)) {
        return None;
    }
    // Coarser boxes at the region, found from the colleague tables of
    // `b`'s ancestors; along periodic axes `c` is unwrapped, the tables
    // wrap, and the shift of the region is that of any box covering it.
    let mut ancestor = b;
    for up in 1..=level {
        ancestor = tree.parent(ancestor).expect("ancestor above the root");
        let off: [i32; 3] = std::array::from_fn(|a| ((c[a] >> up) - (own[a] >> up)) as i32);
        if off == [0; 3] {
            // Inside an ancestor of `b`: an internal box with no child there.
            return None;
        }
        if let Some(m) = tree.colleague(ancestor, off) {
            return tree.is_leaf(m).then_some((m, s));
        }
    }
    None
}

/// The tree as the near-field walk ([`walk_near_field`]) reads it for
/// the rows of one box: boxes with the image shift of the region they were
/// reached through (`[0; 3]` in free space).
struct TreeView<'a, E> {
    tree: &'a Octree,
    /// [`coords`] of the walked box.
    own: [i64; 3],
    entry: std::marker::PhantomData<E>,
}

impl<'a, E: Entry> TreeView<'a, E> {
    fn of(tree: &'a Octree, b: usize) -> Self {
        TreeView {
            tree,
            own: coords::<E>(tree, b),
            entry: std::marker::PhantomData,
        }
    }
}

impl<E: Entry> NeighbourhoodView for TreeView<'_, E> {
    type Box = (usize, [i8; 3]);

    fn colleague(&self, leaf: Self::Box, i: usize) -> Option<Self::Box> {
        colleague_of::<E>(self.tree, leaf.0, self.own, i)
    }

    fn coarse_leaf(&self, leaf: Self::Box, i: usize) -> Option<Self::Box> {
        coarse_leaf::<E>(self.tree, leaf.0, self.own, i)
    }

    fn is_leaf(&self, b: Self::Box) -> bool {
        self.tree.is_leaf(b.0)
    }

    fn child_mask(&self, b: Self::Box) -> u8 {
        self.tree.child_mask(b.0)
    }

    /// Descendants of one neighbour share its shift.
    fn child(&self, b: Self::Box, octant: usize) -> Option<Self::Box> {
        Some((child_index(self.tree, b.0, octant), b.1))
    }

    fn is_adjacent(&self, a: Self::Box, leaf: Self::Box) -> bool {
        adjacent::<E>(self.tree.key(a.0), a.1, self.tree.key(leaf.0))
    }
}

/// The index of the existing child of octant `octant` of `c`.
#[inline]
fn child_index(tree: &Octree, c: usize, octant: usize) -> usize {
    let below = tree.child_mask(c) & ((1u8 << octant) - 1);
    tree.children(c).start + below.count_ones() as usize
}

/// Appends every existing leaf adjacent to `b` (`b` excluded, unpruned),
/// with its shift.
pub(crate) fn adjacent_leaves<E: Entry>(tree: &Octree, b: usize, out: &mut Vec<E>) {
    let view = TreeView::<E>::of(tree, b);
    walk_near_field(&view, (b, [0; 3]), NearLists::U, &mut Vec::new(), |entry| {
        if let NearEntry::Adjacent((a, s)) = entry {
            out.push(E::new(a, s));
        }
    });
}

/// Sorts and deduplicates `out[start..]`.
fn sort_dedup_tail<E: Entry>(out: &mut Vec<E>, start: usize) {
    out[start..].sort_unstable();
    let mut w = start;
    for r in start..out.len() {
        if w == start || out[r] != out[w - 1] {
            out[w] = out[r];
            w += 1;
        }
    }
    out.truncate(w);
}

fn u_row<E: Entry>(tree: &Octree, b: usize, out: &mut Vec<E>) {
    if !tree.is_leaf(b) || !tree.has_targets(b) {
        return;
    }
    let start = out.len();
    adjacent_leaves(tree, b, out);
    out.push(E::new(b, [0; 3]));
    out.retain_tail(start, |&a| tree.has_sources(a.index()));
    sort_dedup_tail(out, start);
}

/// The existing colleagues of `parent` as (box, table index).
fn parent_colleagues(tree: &Octree, parent: usize) -> ([(usize, usize); 26], usize) {
    let mut colleagues = [(usize::MAX, 0usize); 26];
    let mut n = 0;
    for i in colleague_indices() {
        if let Some(c) = tree.colleague_at(parent, i) {
            colleagues[n] = (c, i);
            n += 1;
        }
    }
    (colleagues, n)
}

fn v_count(tree: &Octree, b: usize) -> usize {
    let Some(parent) = tree.parent(b) else {
        return 0;
    };
    if !tree.has_targets(b) {
        return 0;
    }
    let ob = tree.key(b).octant();
    let (colleagues, n) = parent_colleagues(tree, parent);
    colleagues[..n]
        .iter()
        .map(|&(c, i)| (v_children(i, ob) & tree.source_child_mask(c)).count_ones() as usize)
        .sum()
}

/// The last parent seen, its colleagues (box, table index) sorted by box
/// index and their shifts (siblings are consecutive boxes, so this is
/// computed once per parent).
struct VScratch {
    parent: usize,
    colleagues: [(usize, usize); 26],
    shifts: [[i8; 3]; 26],
    n: usize,
}

impl Default for VScratch {
    fn default() -> Self {
        VScratch {
            parent: usize::MAX,
            colleagues: [(0, 0); 26],
            shifts: [[0; 3]; 26],
            n: 0,
        }
    }
}

/// Fills the V row of `b` (and, periodic, its shifts: `shifts` is then
/// parallel to `row`, else empty).
fn v_fill<E: Entry>(
    tree: &Octree,
    scratch: &mut VScratch,
    b: usize,
    row: &mut [usize],
    shifts: &mut [[i8; 3]],
) {
    if row.is_empty() {
        return;
    }
    let parent = tree.parent(b).expect("a box with a V list has a parent");
    if scratch.parent != parent {
        let (mut colleagues, n) = parent_colleagues(tree, parent);
        colleagues[..n].sort_unstable();
        let mut s = [[0; 3]; 26];
        let (own, level) = (coords::<E>(tree, parent), tree.level(parent));
        if E::PERIODIC {
            for (s, &(_, i)) in s.iter_mut().zip(&colleagues[..n]) {
                *s = colleague_shift::<E>(own, level, i);
            }
        }
        *scratch = VScratch {
            parent,
            colleagues,
            shifts: s,
            n,
        };
    }
    let ob = tree.key(b).octant();
    let mut k = 0;
    for (j, &(c, i)) in scratch.colleagues[..scratch.n].iter().enumerate() {
        let mut bits = v_children(i, ob) & tree.source_child_mask(c);
        if bits == 0 {
            continue;
        }
        while bits != 0 {
            let octant = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            row[k] = child_index(tree, c, octant);
            if E::PERIODIC {
                // The children of an image of `c` are images with its shift.
                shifts[k] = scratch.shifts[j];
            }
            k += 1;
        }
    }
    debug_assert_eq!(k, row.len());
    // Below level 2 a periodic parent may see one box as several colleagues
    // (images with different shifts), whose children interleave: order the
    // row by (box, shift). Deeper, colleagues are distinct boxes.
    if E::PERIODIC && tree.level(parent) <= 1 {
        let mut pairs: Vec<(usize, [i8; 3])> =
            row.iter().copied().zip(shifts.iter().copied()).collect();
        pairs.sort_unstable();
        for ((r, s), (a, t)) in row.iter_mut().zip(shifts.iter_mut()).zip(pairs) {
            *r = a;
            *s = t;
        }
    }
}

fn w_row<E: Entry>(tree: &Octree, b: usize, out: &mut Vec<E>) {
    if !tree.is_leaf(b) || !tree.has_targets(b) {
        return;
    }
    let start = out.len();
    let view = TreeView::<E>::of(tree, b);
    walk_near_field(&view, (b, [0; 3]), NearLists::W, &mut Vec::new(), |entry| {
        if let NearEntry::Separated {
            parent: (c, s),
            octant,
        } = entry
        {
            let a = child_index(tree, c, octant);
            if tree.has_sources(a) {
                out.push(E::new(a, s));
            }
        }
    });
    out[start..].sort_unstable();
}

fn x_row<E: Entry>(tree: &Octree, b: usize, out: &mut Vec<E>) {
    let Some(parent) = tree.parent(b) else {
        return;
    };
    if !tree.has_targets(b) {
        return;
    }
    let start = out.len();
    let key: MortonKey = tree.key(b);
    let own = coords::<E>(tree, parent);
    for i in colleague_indices() {
        let (a, s) = match colleague_of::<E>(tree, parent, own, i) {
            Some((n, s)) if tree.is_leaf(n) => (n, s),
            Some(_) => continue,
            None => match coarse_leaf::<E>(tree, parent, own, i) {
                Some(m) => m,
                None => continue,
            },
        };
        if tree.has_sources(a) && !adjacent::<E>(tree.key(a), s, key) {
            out.push(E::new(a, s));
        }
    }
    sort_dedup_tail(out, start);
}

/// `Vec::retain` restricted to a tail.
trait RetainTail<T> {
    fn retain_tail(&mut self, start: usize, keep: impl FnMut(&T) -> bool);
}

impl<T: Copy> RetainTail<T> for Vec<T> {
    fn retain_tail(&mut self, start: usize, mut keep: impl FnMut(&T) -> bool) {
        let mut w = start;
        for r in start..self.len() {
            if keep(&self[r]) {
                self[w] = self[r];
                w += 1;
            }
        }
        self.truncate(w);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Octree, TreeOptions};

    /// For each box `B` of a clustered tree, the boxes of levels
    /// `l - 1 ..= l + 1` inside `parent(B)` and its colleagues (with their
    /// leaf flags) and the existing ancestors of those regions give `B` its
    /// rows of the whole tree. Leaf flags matter: an ancestor of an empty
    /// region arrives without the children that make it internal.
    #[test]
    fn lists_of_a_neighbourhood_equal_the_tree_rows() {
        let pts: Vec<f64> = (0..4000)
            .flat_map(|i| {
                let t = i as f64 * 0.618_034;
                let s = if i % 3 == 0 { 1.0 } else { 1e-2 };
                [s * t.fract(), s * (3.7 * t).fract(), s * (7.1 * t).fract()]
            })
            .collect();
        let tree = Octree::new(&pts, None, &TreeOptions::adaptive(6)).unwrap();
        let all = tree.interaction_lists();
        for b in (1..tree.n_boxes()).step_by(7) {
            let key = tree.key(b);
            let l = key.level();
            let p = key.parent();
            let regions: Vec<MortonKey> = std::iter::once(p).chain(p.colleagues()).collect();
            // The existing ancestors of every region, as a process that
            // owns them sends them (without their other children).
            let boxes: Vec<(MortonKey, bool)> = (0..tree.n_boxes())
                .filter(|&a| {
                    let k = tree.key(a);
                    let inside = k.level() <= l + 1
                        && regions.iter().any(|r| *r == k || r.is_ancestor_of(k));
                    inside || regions.iter().any(|r| k.is_ancestor_of(*r))
                })
                .map(|a| (tree.key(a), tree.is_leaf(a)))
                .collect();
            let (keys, lists) = lists_of_boxes(&boxes);
            let s = keys.iter().position(|&k| k == key).unwrap();
            for (whole, part) in [
                (&all.u, &lists.u),
                (&all.v, &lists.v),
                (&all.w, &lists.w),
                (&all.x, &lists.x),
            ] {
                let mut want: Vec<MortonKey> = whole.get(b).iter().map(|&a| tree.key(a)).collect();
                let mut got: Vec<MortonKey> = part.get(s).iter().map(|&a| keys[a]).collect();
                want.sort_unstable();
                got.sort_unstable();
                assert_eq!(got, want, "box {key}");
            }
        }
    }
}
