//! The near field of a leaf, walked once for every reader: the tree's U
//! and W lists ([`lists`](crate::lists)) and a simulation that counts the
//! work of a tree it has not built (a parameter chooser) follow the same
//! walk, through [`NeighbourhoodView`].
//!
//! # The walk
//!
//! For a leaf `B` and each of its 26 colleague regions (index `i`, see the
//! [module docs](super)), the view says what covers the region
//! ([`NeighbourhoodView::colleague`], [`NeighbourhoodView::coarse_leaf`]):
//!
//! * **a same-level box `N` that is a leaf**: `N` is adjacent to `B`, an
//!   entry of `U(B)`;
//! * **a same-level internal box `N`**: its children that do not touch `B`
//!   ([`touching_children`]`(i)` clears them) are `W(B)` entries; those that
//!   touch `B` are walked down: a leaf among them, or among their
//!   descendants adjacent to `B`, is a `U(B)` entry, and a descendant not
//!   adjacent to `B` (its parent being adjacent) is a `W(B)` entry. With
//!   2:1 balance the touching children are leaves already;
//! * **no box, but a coarser leaf `M` covering the region**: `M` is
//!   adjacent to `B`, a `U(B)` entry (reported once, although it may cover
//!   several regions);
//! * **nothing** (no point there, or outside an open domain).
//!
//! `B` itself, also in `U(B)`, is left to the caller. Pruning (keeping only
//! entries with sources, rows only for boxes with targets) is the caller's
//! too: the walk reports every existing box.
//!
//! A W entry is reported as (parent, octant) without looking the child up,
//! so that a reader that only counts entries pays nothing for it.

use super::{colleague_indices, touching_children};

/// Which of a leaf's near-field lists a walk reports (a walk for one of
/// them skips the lookups only the other needs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NearLists {
    /// The U list (adjacent leaves) only.
    U,
    /// The W list (separated children of adjacent boxes) only.
    W,
    /// Both.
    Both,
}

impl NearLists {
    fn u(self) -> bool {
        self != NearLists::W
    }

    fn w(self) -> bool {
        self != NearLists::U
    }
}

/// An entry of a leaf's near field (see the [module docs](self)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NearEntry<B> {
    /// A leaf adjacent to the walked leaf: a U-list entry.
    Adjacent(B),
    /// The child of octant `octant` of `parent`, not adjacent to the walked
    /// leaf while `parent` is: a W-list entry.
    Separated {
        /// The child's parent (adjacent to the walked leaf).
        parent: B,
        /// The child's octant.
        octant: usize,
    },
}

/// A tree as the near-field walk reads it. In a periodic tree a box is
/// reached through one image of the cell: `Box` then carries that image's
/// shift, which its descendants share.
pub trait NeighbourhoodView {
    /// A box (with its image shift where the tree is periodic).
    type Box: Copy + PartialEq;

    /// The colleague of `leaf` at neighbourhood index `i` (never
    /// [`SELF_INDEX`](super::SELF_INDEX)), if that box exists.
    fn colleague(&self, leaf: Self::Box, i: usize) -> Option<Self::Box>;

    /// Where the colleague of `leaf` at index `i` does not exist: the
    /// coarser leaf covering its region, if there is one (else the region
    /// holds no point or lies outside the domain).
    fn coarse_leaf(&self, leaf: Self::Box, i: usize) -> Option<Self::Box>;

    /// Whether `b` is a leaf.
    fn is_leaf(&self, b: Self::Box) -> bool;

    /// The octants of `b`'s existing children (bit `c` for octant `c`).
    fn child_mask(&self, b: Self::Box) -> u8;

    /// The existing child of octant `octant` of `b` (its bit is set in
    /// [`NeighbourhoodView::child_mask`]).
    fn child(&self, b: Self::Box, octant: usize) -> Option<Self::Box>;

    /// Whether `a` (a descendant of a colleague of `leaf`) is adjacent to
    /// `leaf`.
    fn is_adjacent(&self, a: Self::Box, leaf: Self::Box) -> bool;
}

/// Walks the near field of `leaf` (see the [module docs](self)), calling
/// `visit` for every entry of its U list but itself and of its W list
/// (those of `lists`), each once. `stack` is scratch space (kept by the
/// caller to reuse its allocation).
pub fn walk_near_field<V: NeighbourhoodView>(
    view: &V,
    leaf: V::Box,
    lists: NearLists,
    stack: &mut Vec<V::Box>,
    mut visit: impl FnMut(NearEntry<V::Box>),
) {
    // A coarse leaf covers up to 7 of the 26 regions: report it once.
    let mut coarse: [Option<V::Box>; 26] = [None; 26];
    let mut n_coarse = 0;
    for i in colleague_indices() {
        let Some(n) = view.colleague(leaf, i) else {
            if lists.u()
                && let Some(m) = view.coarse_leaf(leaf, i)
                && !coarse[..n_coarse].contains(&Some(m))
            {
                coarse[n_coarse] = Some(m);
                n_coarse += 1;
                visit(NearEntry::Adjacent(m));
            }
            continue;
        };
        if view.is_leaf(n) {
            if lists.u() {
                visit(NearEntry::Adjacent(n));
            }
            continue;
        }
        let mask = view.child_mask(n);
        let touching = touching_children(i);
        if lists.w() {
            for octant in octants(mask & !touching) {
                visit(NearEntry::Separated { parent: n, octant });
            }
        }
        stack.clear();
        stack.extend(octants(mask & touching).filter_map(|c| view.child(n, c)));
        while let Some(a) = stack.pop() {
            if view.is_leaf(a) {
                if lists.u() {
                    visit(NearEntry::Adjacent(a));
                }
                continue;
            }
            // Not balanced (or a coarse tree): deeper boxes touch `leaf`.
            for octant in octants(view.child_mask(a)) {
                let Some(c) = view.child(a, octant) else {
                    continue;
                };
                if view.is_adjacent(c, leaf) {
                    stack.push(c);
                } else if lists.w() {
                    visit(NearEntry::Separated { parent: a, octant });
                }
            }
        }
    }
}

/// The octants whose bits are set in `mask`, ascending.
#[inline]
fn octants(mut mask: u8) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let c = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            c
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MortonKey;
    use crate::list_rules::index_offset;
    use std::collections::BTreeSet;

    #[test]
    fn octants_lists_the_set_bits() {
        assert_eq!(octants(0b1010_0101).collect::<Vec<_>>(), [0, 2, 5, 7]);
        assert_eq!(octants(0).count(), 0);
        assert_eq!(octants(0xff).count(), 8);
    }

    /// A tree given as its set of keys (every ancestor of a key present).
    struct Keys(BTreeSet<MortonKey>);

    impl Keys {
        fn coarse_cover(&self, key: MortonKey) -> Option<MortonKey> {
            (0..key.level())
                .rev()
                .map(|l| key.ancestor(l))
                .find(|a| self.0.contains(a))
        }
    }

    impl NeighbourhoodView for Keys {
        type Box = MortonKey;
        fn colleague(&self, b: MortonKey, i: usize) -> Option<MortonKey> {
            b.neighbour(index_offset(i)).filter(|n| self.0.contains(n))
        }
        fn coarse_leaf(&self, b: MortonKey, i: usize) -> Option<MortonKey> {
            let a = self.coarse_cover(b.neighbour(index_offset(i))?)?;
            self.is_leaf(a).then_some(a)
        }
        fn is_leaf(&self, b: MortonKey) -> bool {
            self.child_mask(b) == 0
        }
        fn child_mask(&self, b: MortonKey) -> u8 {
            let mut mask = 0;
            for (c, k) in b.children().into_iter().enumerate() {
                if b.level() < crate::DEEPEST_LEVEL && self.0.contains(&k) {
                    mask |= 1 << c;
                }
            }
            mask
        }
        fn child(&self, b: MortonKey, octant: usize) -> Option<MortonKey> {
            Some(b.children()[octant]).filter(|k| self.0.contains(k))
        }
        fn is_adjacent(&self, a: MortonKey, leaf: MortonKey) -> bool {
            a.is_adjacent(leaf)
        }
    }

    /// On unbalanced trees (leaves next to leaves four levels finer, so
    /// that the walk goes deeper than the touching children), the walk
    /// gives each leaf the lists of their definitions, found by brute
    /// force over all boxes: U = the adjacent leaves, W = the boxes not
    /// adjacent to the leaf whose parent is an adjacent descendant of a
    /// colleague; each entry once; and a walk for one list gives that list.
    #[test]
    fn walk_gives_the_defined_lists_on_unbalanced_trees() {
        let mut seed = 7u64;
        let mut next = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
            (seed >> 33) as u32
        };
        // U entries two or more levels finer than their leaf: the walk
        // beyond the touching children ran.
        let mut deep = 0;
        for _ in 0..4 {
            // Refine at random, more often near one corner (deep there).
            let mut keys = BTreeSet::from([MortonKey::ROOT]);
            let mut frontier = vec![MortonKey::ROOT];
            while let Some(k) = frontier.pop() {
                let corner = k.anchor().iter().all(|&a| a < crate::FINEST_GRID / 8);
                if k.level() < 6
                    && (k.level() < 2 || next() % 3 == 0 || (corner && next() % 4 != 0))
                {
                    for c in k.children() {
                        if next() % 5 != 0 || k.level() == 0 {
                            keys.insert(c);
                            frontier.push(c);
                        }
                    }
                }
            }
            let view = Keys(keys);
            let leaves: Vec<MortonKey> = view
                .0
                .iter()
                .copied()
                .filter(|&k| view.is_leaf(k))
                .collect();
            for &leaf in &leaves {
                let mut u = Vec::new();
                let mut w = Vec::new();
                walk_near_field(&view, leaf, NearLists::Both, &mut Vec::new(), |e| match e {
                    NearEntry::Adjacent(a) => u.push(a),
                    NearEntry::Separated { parent, octant } => w.push(parent.children()[octant]),
                });
                let mut want_u: Vec<MortonKey> = leaves
                    .iter()
                    .copied()
                    .filter(|&a| a.is_adjacent(leaf))
                    .collect();
                let mut want_w: Vec<MortonKey> = view
                    .0
                    .iter()
                    .copied()
                    .filter(|&a| {
                        a.level() > leaf.level()
                            && !a.is_adjacent(leaf)
                            && a.parent().is_adjacent(leaf)
                    })
                    .collect();
                for v in [&mut u, &mut w, &mut want_u, &mut want_w] {
                    v.sort_unstable();
                }
                assert_eq!(u, want_u, "U of {leaf}");
                deep += u.iter().filter(|a| a.level() >= leaf.level() + 2).count();
                assert_eq!(w, want_w, "W of {leaf}");
                for (lists, want) in [(NearLists::U, &want_u), (NearLists::W, &want_w)] {
                    let mut got = Vec::new();
                    walk_near_field(&view, leaf, lists, &mut Vec::new(), |e| match e {
                        NearEntry::Adjacent(a) => got.push(a),
                        NearEntry::Separated { parent, octant } => {
                            got.push(parent.children()[octant])
                        }
                    });
                    got.sort_unstable();
                    assert_eq!(&got, want, "{lists:?} of {leaf}");
                }
            }
        }
        assert!(deep > 0, "no deep walk");
    }
}
