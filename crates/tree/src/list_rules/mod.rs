//! The rules of the interaction lists ([`lists`](crate::lists)) over a
//! box's neighbourhood, as small tables: what the tree's list building uses
//! and what a simulation of the lists (a parameter chooser counting the
//! work of a tree it has not built) needs to count the same entries.
//!
//! # The neighbourhood
//!
//! The 27 same-level boxes around a box `B` (`B` included) are numbered by
//! their offset `o` in `{-1, 0, 1}^3` (in units of `B`'s width):
//!
//! ```text
//! index(o) = (o_x + 1) + 3 (o_y + 1) + 9 (o_z + 1)
//! ```
//!
//! so `B` itself is [`SELF_INDEX`] = 13 and its 26 possible colleagues are
//! the other indices ([`colleague_indices`]). This is the order of the rows
//! of [`Octree::colleague`](crate::Octree::colleague)'s table.
//!
//! # Children of a neighbour
//!
//! A child of octant `c` (bit `a` of `c` is its half along axis `a`: 0 for
//! x, 1 for y, 2 for z, as [`MortonKey::children`](crate::MortonKey::children)
//! orders them) of the box at offset `o` from `B` lies at `2 o + bits(c)`
//! in units of the children's width, relative to `B`'s first child. Two
//! same-level boxes are adjacent when every coordinate differs by at most
//! 1, and a box touches `B` (twice its width) when every coordinate is in
//! `-1..=2`. Hence the two masks (bit `c` for child `c`):
//!
//! * [`v_children`]`(o, b)`: the children of the parent's neighbour at
//!   offset `o` that are **not** adjacent to the parent's child `b`: that
//!   child's V-list candidates (`|2 o_a + c_a - b_a| >= 2` on some axis).
//!   Over the 27 offsets they number `6^3 - 3^3 = 189`.
//! * [`touching_children`]`(o)`: the children of `B`'s neighbour at offset
//!   `o` that touch `B`. Of an internal colleague of a leaf `B`, those
//!   children are walked further for `U(B)` (with 2:1 balance they are
//!   leaves), the others are `W(B)` entries.
//!
//! # The walk
//!
//! [`near_field::walk_near_field`] applies these rules to a leaf's whole
//! neighbourhood (its U and W lists) over any tree that answers a few
//! questions ([`near_field::NeighbourhoodView`]): the tree's own lists and
//! a simulation of them walk the same code.

pub mod near_field;

/// Boxes in a neighbourhood: `3^3`.
pub const NEIGHBOURHOOD: usize = 27;

/// The index of the box itself in its neighbourhood (offset `[0, 0, 0]`).
pub const SELF_INDEX: usize = 13;

/// Index of `offset` (components in `-1..=1`) in a neighbourhood:
/// `(o_x + 1) + 3 (o_y + 1) + 9 (o_z + 1)`.
///
/// ```
/// use ferrofmm_tree::list_rules::{SELF_INDEX, index_offset, offset_index};
/// assert_eq!(offset_index([0, 0, 0]), SELF_INDEX);
/// assert_eq!(offset_index([1, -1, 1]), 20);
/// assert_eq!(index_offset(20), [1, -1, 1]);
/// ```
///
/// # Panics
/// If a component is outside `-1..=1`.
pub fn offset_index(offset: [i32; 3]) -> usize {
    assert!(
        offset.iter().all(|o| (-1..=1).contains(o)),
        "colleague offset {offset:?} outside -1..=1"
    );
    ((offset[0] + 1) + 3 * (offset[1] + 1) + 9 * (offset[2] + 1)) as usize
}

/// Offset of neighbourhood index `i` (`0..27`; the inverse of
/// [`offset_index`]).
pub const fn index_offset(i: usize) -> [i32; 3] {
    let i = i as i32;
    [i % 3 - 1, (i / 3) % 3 - 1, i / 9 - 1]
}

/// The 27 offsets of a neighbourhood, in index order (the box itself at
/// [`SELF_INDEX`]).
pub fn offsets() -> impl Iterator<Item = [i32; 3]> {
    (0..NEIGHBOURHOOD).map(index_offset)
}

/// The indices of the 26 colleagues (every index but [`SELF_INDEX`]).
pub fn colleague_indices() -> impl Iterator<Item = usize> {
    (0..NEIGHBOURHOOD).filter(|&i| i != SELF_INDEX)
}

/// The children of the parent's neighbour at index `o` that are not
/// adjacent to the parent's child of octant `b`: the V-list candidates of
/// that child (bit `c` for octant `c`; see the [module docs](self)).
///
/// ```
/// use ferrofmm_tree::list_rules::{NEIGHBOURHOOD, SELF_INDEX, v_children};
/// // Siblings are all adjacent; 189 candidates in all.
/// assert_eq!(v_children(SELF_INDEX, 0), 0);
/// let n: u32 = (0..NEIGHBOURHOOD).map(|o| v_children(o, 5).count_ones()).sum();
/// assert_eq!(n, 189);
/// ```
#[inline]
pub fn v_children(o: usize, b: usize) -> u8 {
    V_CHILDREN[o][b]
}

/// The children of the neighbour at index `o` of a box that touch the box
/// (bit `c` for octant `c`; see the [module docs](self)).
///
/// ```
/// use ferrofmm_tree::list_rules::{SELF_INDEX, offset_index, touching_children};
/// // A face neighbour's 4 children on the shared face, a corner's 1.
/// assert_eq!(touching_children(offset_index([1, 0, 0])).count_ones(), 4);
/// assert_eq!(touching_children(offset_index([-1, -1, -1])), 1 << 7);
/// assert_eq!(touching_children(SELF_INDEX), 0xff);
/// ```
#[inline]
pub fn touching_children(o: usize) -> u8 {
    TOUCHING_CHILDREN[o]
}

/// `V_CHILDREN[o][b]`, see [`v_children`].
static V_CHILDREN: [[u8; 8]; NEIGHBOURHOOD] = v_children_table();

/// `TOUCHING_CHILDREN[o]`, see [`touching_children`].
static TOUCHING_CHILDREN: [u8; NEIGHBOURHOOD] = touching_children_table();

/// Bit `a` of `octant` (0 or 1): its half along axis `a`.
const fn half(octant: usize, axis: usize) -> i32 {
    ((octant >> axis) & 1) as i32
}

const fn v_children_table() -> [[u8; 8]; NEIGHBOURHOOD] {
    let mut table = [[0u8; 8]; NEIGHBOURHOOD];
    let mut o = 0;
    while o < NEIGHBOURHOOD {
        let off = index_offset(o);
        let mut b = 0;
        while b < 8 {
            let mut c = 0;
            while c < 8 {
                let mut far = false;
                let mut axis = 0;
                while axis < 3 {
                    let d = 2 * off[axis] + half(c, axis) - half(b, axis);
                    far |= d > 1 || d < -1;
                    axis += 1;
                }
                if far {
                    table[o][b] |= 1 << c;
                }
                c += 1;
            }
            b += 1;
        }
        o += 1;
    }
    table
}

const fn touching_children_table() -> [u8; NEIGHBOURHOOD] {
    let mut table = [0u8; NEIGHBOURHOOD];
    let mut o = 0;
    while o < NEIGHBOURHOOD {
        let off = index_offset(o);
        let mut c = 0;
        while c < 8 {
            let mut touching = true;
            let mut axis = 0;
            while axis < 3 {
                let x = 2 * off[axis] + half(c, axis);
                touching &= x >= -1 && x <= 2;
                axis += 1;
            }
            if touching {
                table[o] |= 1 << c;
            }
            c += 1;
        }
        o += 1;
    }
    table
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{FINEST_GRID, MortonKey};

    #[test]
    fn indices_and_offsets_are_inverse() {
        for (i, o) in offsets().enumerate() {
            assert_eq!(offset_index(o), i);
        }
        assert_eq!(colleague_indices().count(), 26);
    }

    #[test]
    fn v_children_count_the_v_list() {
        // A child has 6^3 - 3^3 = 189 V-list candidates among the children
        // of its parent's 27 neighbourhood.
        for b in 0..8 {
            let total: u32 = (0..NEIGHBOURHOOD)
                .map(|o| v_children(o, b).count_ones())
                .sum();
            assert_eq!(total, 189, "child {b}");
        }
        // Its own parent's children are all adjacent to it.
        assert!((0..8).all(|b| v_children(SELF_INDEX, b) == 0));
    }

    /// The masks agree with [`MortonKey::is_adjacent`] on real keys.
    #[test]
    fn masks_follow_adjacency_of_keys() {
        let parent = MortonKey::ROOT.children()[0].children()[7];
        for (o, off) in offsets().enumerate() {
            let Some(n) = parent.neighbour(off) else {
                continue;
            };
            for (c, ck) in n.children().into_iter().enumerate() {
                let touching = o == SELF_INDEX || ck.is_adjacent(parent);
                assert_eq!(touching_children(o) >> c & 1 == 1, touching, "{off:?} {c}");
                for (b, bk) in parent.children().into_iter().enumerate() {
                    let far = ck != bk && !ck.is_adjacent(bk);
                    assert_eq!(v_children(o, b) >> c & 1 == 1, far, "{off:?} {b} {c}");
                }
            }
        }
    }

    /// Octant bit `a` is the half along axis `a` (x, y, z).
    #[test]
    fn octant_bits_match_the_keys() {
        for (i, k) in MortonKey::ROOT.children().iter().enumerate() {
            assert_eq!(k.octant(), i);
            let a = k.anchor();
            let h = FINEST_GRID / 2;
            assert_eq!(
                [a[0] / h, a[1] / h, a[2] / h],
                [(i & 1) as u32, ((i >> 1) & 1) as u32, ((i >> 2) & 1) as u32]
            );
        }
    }
}
