//! The colleague table: for every box, its existing same-level neighbours.
//!
//! Row `b` holds 27 entries, one per offset `o` in `{-1, 0, 1}^3`, at index
//! `(o_x + 1) + 3 (o_y + 1) + 9 (o_z + 1)` ([`offset_index`]; entry 13 is `b`
//! itself): the index
//! of the box of `b`'s level at that offset, or none if it is outside the
//! domain or does not exist (holds no point).
//!
//! The table is filled top-down, level by level, without any search: the
//! neighbour at offset `o` of a box with level coordinates `i` has
//! coordinates `c = i + o`; its parent `c / 2` is the parent of `b` or one of
//! that parent's neighbours (offset `c / 2 - i / 2`, again in `{-1, 0, 1}^3`),
//! already in the table, and the neighbour is that box's child of octant
//! `c mod 2`, found among at most 8 contiguous children.
//!
//! In a periodic tree the offsets wrap around the periodic axes: `c` is
//! taken modulo `2^l` there (floor division and the low bit work on the
//! unwrapped `c` as well), so the root is its own neighbour at every offset
//! along periodic axes, and at level 1 a box may be the neighbour of
//! another at two offsets. The shift of the neighbour at offset `o` is
//! `floor((i + o) / 2^l)` per axis and is not stored.

use rayon::prelude::*;

use crate::list_rules::{NEIGHBOURHOOD, SELF_INDEX, index_offset, offset_index};
use crate::morton::DEEPEST_LEVEL;
use crate::octree::Octree;

const NONE: u32 = u32::MAX;

/// Integer coordinates of a box in units of its own width.
pub(crate) fn level_coords(tree: &Octree, b: usize) -> [i64; 3] {
    let key = tree.key(b);
    let shift = DEEPEST_LEVEL - key.level();
    key.anchor().map(|a| (a >> shift) as i64)
}

/// Existing same-level neighbours of every box.
#[derive(Clone, Debug, Default)]
pub(crate) struct ColleagueTable {
    rows: Vec<[u32; NEIGHBOURHOOD]>,
}

impl ColleagueTable {
    /// Fills the table for `tree` (keys, parents and children must be set).
    pub(crate) fn build(tree: &Octree) -> Self {
        let n = tree.n_boxes();
        assert!(n < NONE as usize, "too many boxes for the colleague table");
        let periodic = tree.periodic_axes();
        let mut rows = vec![[NONE; NEIGHBOURHOOD]; n];
        rows[0][SELF_INDEX] = 0;
        // The root's images along periodic axes.
        for (oi, entry) in rows[0].iter_mut().enumerate() {
            let o = index_offset(oi);
            if (0..3).all(|a| o[a] == 0 || periodic[a]) {
                *entry = 0;
            }
        }
        for level in 1..=tree.depth() {
            let range = tree.level_range(level);
            let (done, rest) = rows.split_at_mut(range.start);
            let done: &[[u32; NEIGHBOURHOOD]] = done;
            let size = 1i64 << level;
            rest[..range.len()]
                .par_iter_mut()
                .enumerate()
                .for_each(|(k, row)| {
                    let b = range.start + k;
                    let parent = tree.parent(b).expect("non-root box has a parent");
                    let prow = &done[parent];
                    let i = level_coords(tree, b);
                    for (oi, entry) in row.iter_mut().enumerate() {
                        let o = index_offset(oi);
                        let c: [i64; 3] = std::array::from_fn(|a| i[a] + o[a] as i64);
                        if (0..3).any(|a| !periodic[a] && (c[a] < 0 || c[a] >= size)) {
                            continue;
                        }
                        let po: [i32; 3] =
                            std::array::from_fn(|a| ((c[a] >> 1) - (i[a] >> 1)) as i32);
                        let p = prow[offset_index(po)];
                        if p == NONE {
                            continue;
                        }
                        let octant = (c[0] & 1) | (c[1] & 1) << 1 | (c[2] & 1) << 2;
                        if let Some(child) = tree.child(p as usize, octant as usize) {
                            *entry = child as u32;
                        }
                    }
                });
        }
        ColleagueTable { rows }
    }

    /// The neighbour of `b` at table index `i`, if it exists.
    #[inline]
    pub(crate) fn get(&self, b: usize, i: usize) -> Option<usize> {
        let v = self.rows[b][i];
        (v != NONE).then_some(v as usize)
    }
}
