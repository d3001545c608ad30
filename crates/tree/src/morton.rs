//! Morton (Z-order) keys for the boxes of an octree.
//!
//! # Boxes, levels and anchors
//!
//! The domain (a cube, see [`Domain`]) is the box of level 0. A box of level
//! `l` is split into 8 children of level `l + 1`, each half as wide. At the
//! deepest level [`DEEPEST_LEVEL`] = `D` the domain is a grid of
//! `2^D x 2^D x 2^D` *finest cells*. A box of level `l` is `2^(D - l)`
//! finest cells wide, and its **anchor** is the integer position (in finest
//! cells) of its lower corner; an anchor of level `l` is a multiple of
//! `2^(D - l)` on every axis.
//!
//! # Key layout
//!
//! A [`MortonKey`] packs a box into one `u64`:
//!
//! ```text
//!   bit 63 | bits 62 ..= 5                                   | bits 4 ..= 0
//!     0    | Morton code m: z_D-1 y_D-1 x_D-1 ... z_0 y_0 x_0 | level l
//! ```
//!
//! The Morton code interleaves the anchor bits (bit `i` of `x` lands on bit
//! `3i`, of `y` on `3i + 1`, of `z` on `3i + 2`). Because an anchor of level
//! `l` has its low `D - l` bits clear, the box's code `m` is the smallest
//! code of all finest cells inside it, and those cells are exactly the codes
//! `m .. m + 8^(D - l)`.
//!
//! # Order
//!
//! Keys compare as their raw `u64`, i.e. by Morton code first and level
//! second. A parent has the same code as its first child and a lower level,
//! so it sorts before it, and every descendant of a box sorts before the box
//! that follows it at its own level: **sorting keys gives the depth-first
//! (pre-order) traversal of the octree**, children visited in octant order.
//!
//! # Octants
//!
//! The child number ([`MortonKey::octant`]) is the next three Morton bits:
//! bit 0 (value 1) is set when the child is in the upper half along `x`,
//! bit 1 (value 2) along `y`, bit 2 (value 4) along `z`.
//!
//! # Encoding
//!
//! Encoding a point (or an anchor) spreads each 19-bit coordinate with two
//! lookups in a 1024-entry table (computed at compile time) instead of a
//! bit-by-bit loop; decoding uses the usual shift-and-mask compaction.

use crate::domain::Domain;

/// The deepest level a [`MortonKey`] can hold: `3 * 19 = 57` bits of Morton
/// code plus 5 bits of level fit in a `u64`.
///
/// At this level the domain is a `2^19`-per-axis grid (about `5.2e5` cells
/// per axis, `1.4e17` in all); points closer than `width / 2^19` on every
/// axis cannot be separated and share a deepest-level leaf.
pub const DEEPEST_LEVEL: u32 = 19;

/// Number of finest cells per axis (`2^DEEPEST_LEVEL`).
pub const FINEST_GRID: u32 = 1 << DEEPEST_LEVEL;

const LEVEL_BITS: u32 = 5;
const LEVEL_MASK: u64 = (1 << LEVEL_BITS) - 1;

/// `SPREAD[v]` has bit `i` of `v` at bit `3 i` (for the 10 bits of `v`).
static SPREAD: [u32; 1024] = spread_table();

const fn spread_table() -> [u32; 1024] {
    let mut table = [0u32; 1024];
    let mut v = 0;
    while v < 1024 {
        let mut spread = 0u32;
        let mut bit = 0;
        while bit < 10 {
            if (v >> bit) & 1 == 1 {
                spread |= 1 << (3 * bit);
            }
            bit += 1;
        }
        table[v] = spread;
        v += 1;
    }
    table
}

/// Spreads the low 20 bits of `x` so that bit `i` lands on bit `3 i`.
#[inline(always)]
fn spread(x: u32) -> u64 {
    SPREAD[(x & 1023) as usize] as u64 | (SPREAD[((x >> 10) & 1023) as usize] as u64) << 30
}

/// Inverse of [`spread`]: gathers bits `0, 3, 6, ...` into a 21-bit integer.
#[inline(always)]
fn compact(m: u64) -> u32 {
    let mut x = m & 0x1249_2492_4924_9249;
    x = (x ^ (x >> 2)) & 0x10c3_0c30_c30c_30c3;
    x = (x ^ (x >> 4)) & 0x100f_00f0_0f00_f00f;
    x = (x ^ (x >> 8)) & 0x001f_0000_ff00_00ff;
    x = (x ^ (x >> 16)) & 0x001f_0000_0000_ffff;
    x = (x ^ (x >> 32)) & 0x001f_ffff;
    x as u32
}

/// Interleaves an anchor (each coordinate `< 2^DEEPEST_LEVEL`) into a Morton
/// code.
#[inline(always)]
pub(crate) fn encode(anchor: [u32; 3]) -> u64 {
    spread(anchor[0]) | spread(anchor[1]) << 1 | spread(anchor[2]) << 2
}

/// Inverse of [`encode`].
#[inline(always)]
pub(crate) fn decode(morton: u64) -> [u32; 3] {
    [compact(morton), compact(morton >> 1), compact(morton >> 2)]
}

/// Width of a box of `level`, in finest cells.
#[inline(always)]
pub(crate) const fn width_in_cells(level: u32) -> u32 {
    1 << (DEEPEST_LEVEL - level)
}

/// Number of finest cells in a box of `level` (`8^(D - level)`): the span of
/// Morton codes it covers.
#[inline(always)]
pub(crate) const fn cells_in_box(level: u32) -> u64 {
    1 << (3 * (DEEPEST_LEVEL - level))
}

/// A box of the octree: Morton code of its anchor plus its level, in one
/// `u64` (see the [module documentation](self) for the layout and order).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct MortonKey(u64);

impl MortonKey {
    /// The root box (the whole domain, level 0).
    pub const ROOT: MortonKey = MortonKey(0);

    #[inline(always)]
    const fn pack(morton: u64, level: u32) -> Self {
        MortonKey(morton << LEVEL_BITS | level as u64)
    }

    /// The box of `level` containing the finest cell at `anchor` (in units of
    /// finest cells, see [`FINEST_GRID`]). Anchor bits below the level are
    /// ignored, so any finest cell inside the box gives the same key.
    ///
    /// # Panics
    /// If `level > DEEPEST_LEVEL` or a coordinate is `>= FINEST_GRID`.
    ///
    /// ```
    /// use ferrofmm_tree::{MortonKey, FINEST_GRID};
    /// let k = MortonKey::from_anchor([FINEST_GRID / 2, 0, 0], 1);
    /// assert_eq!(k.octant(), 1);
    /// assert_eq!(k.anchor(), [FINEST_GRID / 2, 0, 0]);
    /// ```
    pub fn from_anchor(anchor: [u32; 3], level: u32) -> Self {
        assert!(level <= DEEPEST_LEVEL, "level {level} > DEEPEST_LEVEL");
        assert!(
            anchor.iter().all(|&a| a < FINEST_GRID),
            "anchor {anchor:?} outside the finest grid"
        );
        Self::from_morton(encode(anchor), level)
    }

    /// The box of `level` containing the finest cell with Morton code
    /// `morton` (bits below the level are ignored).
    ///
    /// # Panics
    /// If `level > DEEPEST_LEVEL` or `morton >= 8^DEEPEST_LEVEL`.
    pub fn from_morton(morton: u64, level: u32) -> Self {
        assert!(level <= DEEPEST_LEVEL, "level {level} > DEEPEST_LEVEL");
        assert!(morton < cells_in_box(0), "Morton code out of range");
        Self::pack(morton & !(cells_in_box(level) - 1), level)
    }

    /// The box of `level` containing point `p` of `domain`.
    ///
    /// The point is scaled to the finest grid, `floor((p - origin) / width *
    /// 2^D)`, and encoded with table lookups. Points outside the domain are
    /// clamped to the nearest boundary box (a NaN coordinate maps to 0), so
    /// points on the upper faces land in the last box.
    ///
    /// # Panics
    /// If `level > DEEPEST_LEVEL`.
    ///
    /// ```
    /// use ferrofmm_tree::{Domain, MortonKey};
    /// let d = Domain::new([0.0; 3], 1.0).unwrap();
    /// let k = MortonKey::from_point([0.75, 0.25, 0.75], &d, 1);
    /// assert_eq!(k.octant(), 1 + 4);
    /// assert_eq!(k.center(&d), [0.75, 0.25, 0.75]);
    /// ```
    pub fn from_point(p: [f64; 3], domain: &Domain, level: u32) -> Self {
        assert!(level <= DEEPEST_LEVEL, "level {level} > DEEPEST_LEVEL");
        Self::pack(domain.finest_morton(p) & !(cells_in_box(level) - 1), level)
    }

    /// Level of the box (0 for the root).
    #[inline]
    pub fn level(self) -> u32 {
        (self.0 & LEVEL_MASK) as u32
    }

    /// Morton code of the anchor (the key without its level bits).
    #[inline]
    pub fn morton(self) -> u64 {
        self.0 >> LEVEL_BITS
    }

    /// Anchor (lower corner) of the box in finest cells.
    #[inline]
    pub fn anchor(self) -> [u32; 3] {
        decode(self.morton())
    }

    /// The packed key (see the [module documentation](self)).
    #[inline]
    pub fn raw(self) -> u64 {
        self.0
    }

    /// Rebuilds a key from [`raw`](Self::raw), or `None` if the bits do not
    /// describe a box (level too deep, code out of range, or anchor not
    /// aligned to the level).
    pub fn from_raw(raw: u64) -> Option<Self> {
        let level = (raw & LEVEL_MASK) as u32;
        let morton = raw >> LEVEL_BITS;
        (level <= DEEPEST_LEVEL
            && morton < cells_in_box(0)
            && morton & (cells_in_box(level) - 1) == 0)
            .then_some(MortonKey(raw))
    }

    /// Width of the box in finest cells (`2^(DEEPEST_LEVEL - level)`).
    #[inline]
    pub fn width_in_cells(self) -> u32 {
        width_in_cells(self.level())
    }

    /// The parent box.
    ///
    /// # Panics
    /// If `self` is the root.
    #[inline]
    pub fn parent(self) -> Self {
        let level = self.level();
        assert!(level > 0, "the root has no parent");
        Self::pack(self.morton() & !(cells_in_box(level - 1) - 1), level - 1)
    }

    /// The ancestor-or-self of this box at `level` (`level <= self.level()`).
    ///
    /// # Panics
    /// If `level > self.level()`.
    #[inline]
    pub fn ancestor(self, level: u32) -> Self {
        assert!(level <= self.level(), "ancestor level below the box");
        Self::pack(self.morton() & !(cells_in_box(level) - 1), level)
    }

    /// The 8 children, in octant (and key) order.
    ///
    /// # Panics
    /// If the box is at [`DEEPEST_LEVEL`].
    #[inline]
    pub fn children(self) -> [Self; 8] {
        let level = self.level();
        assert!(level < DEEPEST_LEVEL, "a deepest-level box has no children");
        let step = cells_in_box(level + 1);
        let m = self.morton();
        std::array::from_fn(|c| Self::pack(m + c as u64 * step, level + 1))
    }

    /// Which child of its parent this box is, `0..8`: bit 0 (1) set for the
    /// upper half in `x`, bit 1 (2) in `y`, bit 2 (4) in `z`. The root
    /// returns 0.
    #[inline]
    pub fn octant(self) -> usize {
        let level = self.level();
        if level == 0 {
            return 0;
        }
        ((self.morton() >> (3 * (DEEPEST_LEVEL - level))) & 7) as usize
    }

    /// The strict ancestors, nearest first: parent, grandparent, ..., root.
    /// `self` is **not** included; the root yields nothing.
    ///
    /// ```
    /// use ferrofmm_tree::MortonKey;
    /// let k = MortonKey::ROOT.children()[3].children()[5];
    /// let a: Vec<_> = k.ancestors().collect();
    /// assert_eq!(a, vec![MortonKey::ROOT.children()[3], MortonKey::ROOT]);
    /// ```
    pub fn ancestors(self) -> impl Iterator<Item = Self> {
        let level = self.level();
        (0..level).rev().map(move |l| self.ancestor(l))
    }

    /// The 8 children of the parent (`self` included, at index
    /// [`octant`](Self::octant)).
    ///
    /// # Panics
    /// If `self` is the root.
    #[inline]
    pub fn siblings(self) -> [Self; 8] {
        self.parent().children()
    }

    /// The same-level box at `offset` (in box widths), or `None` if it would
    /// lie outside the domain.
    #[inline]
    pub fn neighbour(self, offset: [i32; 3]) -> Option<Self> {
        let level = self.level();
        let n = 1i64 << level;
        let a = self.anchor();
        let shift = DEEPEST_LEVEL - level;
        let mut out = [0u32; 3];
        for i in 0..3 {
            let c = (a[i] >> shift) as i64 + offset[i] as i64;
            if c < 0 || c >= n {
                return None;
            }
            out[i] = (c as u32) << shift;
        }
        Some(Self::pack(encode(out), level))
    }

    /// The same-level box at `offset` (in box widths) in a domain that is
    /// periodic along the axes flagged in `periodic`: along those axes the
    /// position wraps around, and the box is returned with the image shift
    /// `s` (in `-1..=1` per axis, in units of the domain width) such that
    /// the neighbour is the returned box translated by `s` cells. `None` if
    /// it leaves the domain along an open axis. With `offset` in
    /// `-1..=1` per axis, the shift is in `-1..=1`; at level 0 the
    /// neighbour is the root itself, shifted.
    ///
    /// ```
    /// use ferrofmm_tree::MortonKey;
    /// let c = MortonKey::ROOT.children();
    /// // Left of the child at x = 0 lies the child at x = 1, one cell to the left.
    /// assert_eq!(c[0].neighbour_periodic([-1, 0, 0], [true; 3]), Some((c[1], [-1, 0, 0])));
    /// assert_eq!(c[0].neighbour_periodic([-1, 0, 0], [false, true, true]), None);
    /// assert_eq!(c[0].neighbour_periodic([1, 0, 0], [true; 3]), Some((c[1], [0, 0, 0])));
    /// ```
    pub fn neighbour_periodic(
        self,
        offset: [i32; 3],
        periodic: [bool; 3],
    ) -> Option<(Self, [i8; 3])> {
        let level = self.level();
        let n = 1i64 << level;
        let a = self.anchor();
        let shift = DEEPEST_LEVEL - level;
        let mut out = [0u32; 3];
        let mut image = [0i8; 3];
        for i in 0..3 {
            let c = (a[i] >> shift) as i64 + offset[i] as i64;
            // `n` is a power of two: wrap and floor-divide with bit operations.
            let w = c & (n - 1);
            if w != c && !periodic[i] {
                return None;
            }
            image[i] = (c >> level) as i8;
            out[i] = (w as u32) << shift;
        }
        Some((Self::pack(encode(out), level), image))
    }

    /// Same-level neighbours inside the domain (boxes sharing a face, edge or
    /// corner), `self` excluded: at most 26, in order of offset
    /// (`x` fastest, then `y`, then `z`, each from -1 to 1).
    pub fn colleagues(self) -> Vec<Self> {
        let mut out = Vec::with_capacity(26);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if (dx, dy, dz) != (0, 0, 0)
                        && let Some(k) = self.neighbour([dx, dy, dz])
                    {
                        out.push(k);
                    }
                }
            }
        }
        out
    }

    /// `true` if `self` is a **strict** ancestor of `other` (contains it and
    /// is coarser).
    #[inline]
    pub fn is_ancestor_of(self, other: Self) -> bool {
        self.level() < other.level() && other.ancestor(self.level()) == self
    }

    /// `true` if `self` is `other` or one of its ancestors (the box contains
    /// `other`).
    #[inline]
    pub fn contains(self, other: Self) -> bool {
        self.level() <= other.level() && other.ancestor(self.level()) == self
    }

    /// `true` if the two boxes (any levels) touch — share a face, an edge or
    /// a corner — and neither contains the other.
    ///
    /// Two octree boxes are either nested or have disjoint interiors, so this
    /// holds exactly when their closures intersect on every axis and they
    /// touch (one's upper face is the other's lower face) on at least one.
    ///
    /// ```
    /// use ferrofmm_tree::MortonKey;
    /// let c = MortonKey::ROOT.children();
    /// assert!(c[0].is_adjacent(c[7])); // corner contact
    /// assert!(!c[0].is_adjacent(MortonKey::ROOT)); // nested
    /// assert!(!c[0].is_adjacent(c[0]));
    /// ```
    #[inline]
    pub fn is_adjacent(self, other: Self) -> bool {
        let (a, b) = (self.anchor(), other.anchor());
        let (wa, wb) = (self.width_in_cells(), other.width_in_cells());
        let mut touching = false;
        for i in 0..3 {
            let (lo_a, hi_a, lo_b, hi_b) = (a[i], a[i] + wa, b[i], b[i] + wb);
            if lo_a > hi_b || lo_b > hi_a {
                return false;
            }
            touching |= hi_a == lo_b || hi_b == lo_a;
        }
        touching
    }

    /// `true` if the image of `self` translated by `shift` domain widths
    /// (see [`neighbour_periodic`](Self::neighbour_periodic)) and `other`
    /// touch and neither contains the other: [`is_adjacent`](Self::is_adjacent)
    /// in the periodic tiling of the domain. With `shift == [0; 3]` it is
    /// `is_adjacent`.
    ///
    /// ```
    /// use ferrofmm_tree::MortonKey;
    /// let c = MortonKey::ROOT.children();
    /// // Child 0 (x in [0, 1/2)) shifted one cell to the right touches child 1.
    /// assert!(c[0].is_adjacent_shifted([1, 0, 0], c[1]));
    /// assert!(!c[0].is_adjacent_shifted([2, 0, 0], c[1]));
    /// assert!(MortonKey::ROOT.is_adjacent_shifted([1, 1, 0], c[3]));
    /// assert!(!MortonKey::ROOT.is_adjacent_shifted([0, 0, 0], c[3]));
    /// ```
    #[inline]
    pub fn is_adjacent_shifted(self, shift: [i8; 3], other: Self) -> bool {
        if shift == [0; 3] {
            return self.is_adjacent(other);
        }
        let (a, b) = (self.anchor(), other.anchor());
        let (wa, wb) = (self.width_in_cells() as i64, other.width_in_cells() as i64);
        let mut touching = false;
        for i in 0..3 {
            let lo_a = a[i] as i64 + shift[i] as i64 * FINEST_GRID as i64;
            let (hi_a, lo_b) = (lo_a + wa, b[i] as i64);
            let hi_b = lo_b + wb;
            if lo_a > hi_b || lo_b > hi_a {
                return false;
            }
            touching |= hi_a == lo_b || hi_b == lo_a;
        }
        touching
    }

    /// Centre of the box in the coordinates of `domain`.
    #[inline]
    pub fn center(self, domain: &Domain) -> [f64; 3] {
        let a = self.anchor();
        let cell = domain.width / FINEST_GRID as f64;
        let half = 0.5 * self.width_in_cells() as f64;
        std::array::from_fn(|i| domain.origin[i] + (a[i] as f64 + half) * cell)
    }

    /// Lower corner of the box in the coordinates of `domain`.
    #[inline]
    pub fn lower_corner(self, domain: &Domain) -> [f64; 3] {
        let a = self.anchor();
        let cell = domain.width / FINEST_GRID as f64;
        std::array::from_fn(|i| domain.origin[i] + a[i] as f64 * cell)
    }

    /// Half the width of the box: `domain.width / 2^(level + 1)`.
    #[inline]
    pub fn half_width(self, domain: &Domain) -> f64 {
        domain.width / (1u64 << (self.level() + 1)) as f64
    }

    /// `(other.anchor - self.anchor) / box width`: the offset of `other` from
    /// `self` in box widths (the M2L transfer vector).
    ///
    /// # Panics
    /// If the two keys are at different levels.
    #[inline]
    pub fn transfer_vector(self, other: Self) -> [i32; 3] {
        assert_eq!(self.level(), other.level(), "transfer vector across levels");
        let shift = DEEPEST_LEVEL - self.level();
        let (a, b) = (self.anchor(), other.anchor());
        std::array::from_fn(|i| (b[i] >> shift) as i32 - (a[i] >> shift) as i32)
    }

    /// The M2L transfer vector of `other` translated by `shift` domain
    /// widths, seen from `self` (same level `l`): `self.transfer_vector(other)
    /// + shift * 2^l`, in units of the boxes' width. For an entry `a` of the
    /// V list of box `b` of a periodic tree with shift `s`
    /// ([`Octree::v_shifts`](crate::Octree::v_shifts)), it is
    /// `key(b).shifted_transfer_vector(key(a), s)`: components in `-3..=3`,
    /// at least one of magnitude `>= 2`, as in free space.
    ///
    /// ```
    /// use ferrofmm_tree::MortonKey;
    /// let c = MortonKey::ROOT.children();
    /// // Child 1 (x = 1) shifted one cell to the left lies at x = -1.
    /// assert_eq!(c[0].shifted_transfer_vector(c[1], [-1, 0, 0]), [-1, 0, 0]);
    /// assert_eq!(c[0].shifted_transfer_vector(c[1], [0; 3]), c[0].transfer_vector(c[1]));
    /// ```
    ///
    /// # Panics
    /// If the two keys are at different levels.
    #[inline]
    pub fn shifted_transfer_vector(self, other: Self, shift: [i8; 3]) -> [i32; 3] {
        let t = self.transfer_vector(other);
        let cells = 1i32 << self.level();
        std::array::from_fn(|i| t[i] + shift[i] as i32 * cells)
    }

    /// The deepest-level key of the first finest cell in the box (same anchor).
    #[inline]
    pub fn finest_first_descendant(self) -> Self {
        Self::pack(self.morton(), DEEPEST_LEVEL)
    }

    /// The deepest-level key of the last finest cell in the box (anchor plus
    /// width minus one on every axis). Every descendant key `k` satisfies
    /// `self <= k <= self.finest_last_descendant()`.
    #[inline]
    pub fn finest_last_descendant(self) -> Self {
        Self::pack(
            self.morton() + cells_in_box(self.level()) - 1,
            DEEPEST_LEVEL,
        )
    }

    /// The range of finest-cell Morton codes covered by the box.
    #[inline]
    pub fn morton_range(self) -> std::ops::Range<u64> {
        let m = self.morton();
        m..m + cells_in_box(self.level())
    }
}

impl std::fmt::Display for MortonKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = DEEPEST_LEVEL - self.level();
        let a = self.anchor();
        write!(
            f,
            "L{}({}, {}, {})",
            self.level(),
            a[0] >> s,
            a[1] >> s,
            a[2] >> s
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encode_slow(a: [u32; 3]) -> u64 {
        let mut m = 0;
        for bit in 0..DEEPEST_LEVEL {
            for (axis, &c) in a.iter().enumerate() {
                m |= (((c >> bit) & 1) as u64) << (3 * bit + axis as u32);
            }
        }
        m
    }

    #[test]
    fn table_encode_matches_bitwise() {
        let samples = [0, 1, 2, 1023, 1024, 12345, FINEST_GRID / 3, FINEST_GRID - 1];
        for &x in &samples {
            for &y in &samples {
                for &z in &samples {
                    let m = encode([x, y, z]);
                    assert_eq!(m, encode_slow([x, y, z]));
                    assert_eq!(decode(m), [x, y, z]);
                }
            }
        }
    }

    #[test]
    fn key_fits_and_orders_depth_first() {
        let last = MortonKey::from_anchor([FINEST_GRID - 1; 3], DEEPEST_LEVEL);
        assert!(last.raw() < 1 << 63);
        let c = MortonKey::ROOT.children();
        assert!(MortonKey::ROOT < c[0]);
        assert!(c[0].children()[7].finest_last_descendant() < c[1]);
    }
}
