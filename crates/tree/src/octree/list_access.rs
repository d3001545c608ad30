//! The interaction lists of a built [`Octree`]: the U, V, W and X list of
//! each box and their image shifts (see [`lists`](crate::lists) for the
//! rules), the leaves adjacent to a box, and handing the V lists over to a
//! caller that keeps them in a form of its own.

use super::Octree;
use crate::csr::Csr;
use crate::lists::InteractionLists;

impl Octree {
    /// Whether the interaction lists were built: `true` for every 2:1
    /// balanced tree (the default, and uniform trees), `false` for an
    /// adaptive tree built with [`TreeOptions::balance`](crate::TreeOptions::balance) off, whose lists
    /// are all empty.
    pub fn has_lists(&self) -> bool {
        self.balanced
    }

    /// All four interaction lists (empty rows when not [`Octree::has_lists`]).
    pub fn interaction_lists(&self) -> &InteractionLists {
        &self.lists
    }

    /// U list of `b` (near field, P2P): see [`lists`](crate::lists).
    pub fn u_list(&self, b: usize) -> &[usize] {
        self.lists.u.get(b)
    }

    /// Image shifts of the U list of `b`, parallel to
    /// [`u_list`](Self::u_list)`(b)`: `Some` in a periodic tree, `None` in
    /// free space. Entry `k` is box `u_list(b)[k]` translated by
    /// `u_shifts(b)[k][a]` domain widths along axis `a` (see
    /// [`lists`](crate::lists)).
    pub fn u_shifts(&self, b: usize) -> Option<&[[i8; 3]]> {
        self.lists.u.row_shifts(b)
    }

    /// Image shifts of the V list of `b`, parallel to
    /// [`v_list`](Self::v_list)`(b)` (see [`u_shifts`](Self::u_shifts));
    /// the transfer vector of a shifted entry is
    /// [`MortonKey::shifted_transfer_vector`](crate::MortonKey::shifted_transfer_vector).
    pub fn v_shifts(&self, b: usize) -> Option<&[[i8; 3]]> {
        self.lists.v.row_shifts(b)
    }

    /// Image shifts of the W list of `b`, parallel to
    /// [`w_list`](Self::w_list)`(b)` (see [`u_shifts`](Self::u_shifts)).
    pub fn w_shifts(&self, b: usize) -> Option<&[[i8; 3]]> {
        self.lists.w.row_shifts(b)
    }

    /// Image shifts of the X list of `b`, parallel to
    /// [`x_list`](Self::x_list)`(b)` (see [`u_shifts`](Self::u_shifts)).
    pub fn x_shifts(&self, b: usize) -> Option<&[[i8; 3]]> {
        self.lists.x.row_shifts(b)
    }

    /// V list of `b` (M2L): see [`lists`](crate::lists).
    pub fn v_list(&self, b: usize) -> &[usize] {
        self.lists.v.get(b)
    }

    /// W list of `b` (M2P): see [`lists`](crate::lists).
    pub fn w_list(&self, b: usize) -> &[usize] {
        self.lists.w.get(b)
    }

    /// X list of `b` (P2L): see [`lists`](crate::lists).
    pub fn x_list(&self, b: usize) -> &[usize] {
        self.lists.x.get(b)
    }

    /// All existing leaves adjacent to box `b` (any box, any levels; `b`
    /// excluded), ascending, whether or not they hold sources. In a
    /// periodic tree, leaves adjacent across periodic faces are included
    /// (each box once, whatever its images).
    pub fn adjacent_leaves(&self, b: usize) -> Vec<usize> {
        let mut out: Vec<usize> = if self.is_periodic() {
            let mut shifted = Vec::new();
            crate::lists::adjacent_leaves::<crate::csr::Shifted>(self, b, &mut shifted);
            // At level 0 the root's images are its neighbours.
            shifted
                .into_iter()
                .map(crate::csr::Entry::index)
                .filter(|&a| a != b)
                .collect()
        } else {
            let mut out = Vec::new();
            crate::lists::adjacent_leaves::<usize>(self, b, &mut out);
            out
        };
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Hand the V lists (and their image shifts) over to the caller,
    /// leaving every box's V list empty: for a caller that keeps them in
    /// a form of its own (the FMM groups each level's V entries by
    /// transfer vector for M2L) so that they are not held twice (8 bytes an
    /// entry: about 9 bytes a point in a uniform tree of 1e8 points, where
    /// a box has up to 189 V entries). The U, W and X lists and everything
    /// else are unchanged.
    pub fn take_v_lists(&mut self) -> Csr {
        let empty = InteractionLists::empty(self.n_boxes(), self.is_periodic()).v;
        std::mem::replace(&mut self.lists.v, empty)
    }
}
