//! Sibling blocks: a level's V-list pairs regrouped by parent, for schemes
//! that apply M2L to the eight children of a parent at once (the FFT
//! scheme's `8 x 8` products).
//!
//! # The regrouping
//!
//! A level's boxes in Morton order put the children of one parent in
//! consecutive columns. Each column has a **slot** `8 g + o`: child `o` of
//! sibling group `g` (the parent). The slots come from
//! [`M2lInteractions::with_sibling_slots`] (the FMM driver gives them: a
//! tree that leaves out empty boxes has fewer than eight children per
//! parent); without them column `c` is slot `c`, right for complete levels.
//! Child `o` sits at offset [`octant_bits`]`(o) = (o & 1, o >> 1 & 1,
//! o >> 2 & 1)` (in child widths, `x`, `y`, `z`) from its parent's first
//! child. The transfer vector of target child `ct` of group `T` and source
//! child `cs` of group `S` is therefore
//!
//! ```text
//! v = 2 d + octant_bits(cs) - octant_bits(ct),    d = parent(S) - parent(T),
//! ```
//!
//! and for V-list pairs (whose parents are neighbours) the **parent
//! offset** `d` lies in `[-1, 1]^3` without `0` (siblings are adjacent,
//! never in each other's V list): 26 offsets. So all pairs between the
//! children of two neighbouring parents form one `8 x 8` block, whose entry
//! `(ct, cs)` uses the operator of `v(d, ct, cs)`
//! ([`block_vector`]); the entries where `v` is not a V-list vector
//! (adjacent children) are never pairs.
//!
//! [`SiblingBlocks::new`] reads the pairs `(t, s, v)` of an
//! [`M2lInteractions`], takes the slots `T` of `t` and `S` of `s`, and files
//! each pair under target group `T / 8`, source group `S / 8`, parent
//! offset `d = (v - octant_bits(S % 8) + octant_bits(T % 8)) / 2` and bit
//! `8 (T % 8) + S % 8` of the block's mask. This uses only the pair itself,
//! so the regrouping is exact for any interactions and slots: a pair whose
//! `d` is not an integer offset in `[-1, 1]^3`, or whose `(target group,
//! d)` already holds another source group, or that repeats a filed pair, is
//! kept as a [`LoosePair`] to be applied on its own. A tree level with its
//! slots leaves no loose pairs.
//!
//! [`M2lInteractions::sibling_blocks`] builds this once per set of
//! interactions and keeps it.

use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

use rayon::prelude::*;

use crate::interactions::ChunkView;
use crate::{M2lInteractions, transfer_vector_index, transfer_vectors};

/// Number of parent offsets in `[-1, 1]^3` (the centre, `0`, included so
/// that offsets index a flat table; it never holds pairs).
pub const N_PARENT_OFFSETS: usize = 27;

/// Offset of child `o` (`0..8`) from its parent's first child, in child
/// widths: bit 0 of `o` is `x`, bit 1 `y`, bit 2 `z` (the order of
/// `ferrofmm_tree::MortonKey::octant`).
pub const fn octant_bits(o: usize) -> [i32; 3] {
    [(o & 1) as i32, ((o >> 1) & 1) as i32, ((o >> 2) & 1) as i32]
}

/// Parent offset `d` (in `[-1, 1]^3`) of flat index `(d_x + 1) 9 + (d_y
/// + 1) 3 + (d_z + 1)`.
pub const fn parent_offset(index: usize) -> [i32; 3] {
    [
        (index / 9) as i32 - 1,
        ((index / 3) % 3) as i32 - 1,
        (index % 3) as i32 - 1,
    ]
}

/// Index (into [`transfer_vectors`]) of the transfer vector of target
/// child `ct` and source child `cs` of parents at offset index `offset`,
/// `None` where the two children are adjacent (no V-list pair).
pub fn block_vector(offset: usize, ct: usize, cs: usize) -> Option<usize> {
    let d = parent_offset(offset);
    let (a, b) = (octant_bits(ct), octant_bits(cs));
    transfer_vector_index(std::array::from_fn(|i| 2 * d[i] + b[i] - a[i]))
}

/// The mask of every V-list entry of the block at offset index `offset`
/// (bit `8 ct + cs`).
pub fn full_mask(offset: usize) -> u64 {
    (0..64)
        .filter(|&bit| block_vector(offset, bit / 8, bit % 8).is_some())
        .fold(0u64, |m, bit| m | 1 << bit)
}

/// The offset index of pair `(t, s)` with transfer vector `v`, `None` when
/// the pair fits no block.
fn offset_of(t: usize, s: usize, v: [i32; 3]) -> Option<usize> {
    let (a, b) = (octant_bits(t % 8), octant_bits(s % 8));
    let mut index = 0;
    for i in 0..3 {
        let twice = v[i] - b[i] + a[i];
        if twice % 2 != 0 || !(-2..=2).contains(&twice) {
            return None;
        }
        index = 3 * index + (twice / 2 + 1) as usize;
    }
    Some(index)
}

/// The pairs `(target column, source column, vector index)` of a chunk.
fn pairs_of(c: ChunkView<'_>) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
    let first = c.first_target();
    c.groups().flat_map(move |g| {
        g.sources
            .iter()
            .zip(g.targets)
            .map(move |(&s, &t)| (first + t as usize, s as usize, g.vector))
    })
}

/// The pairs between the children of one target group and one source
/// group at one parent offset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SiblingBlock {
    /// The source group (source columns `8 g .. 8 g + 8`).
    pub source_group: u32,
    /// Parent offset index ([`parent_offset`]).
    pub offset: u8,
    /// Bit `8 ct + cs` set for each pair of target child `ct` and source
    /// child `cs`.
    pub mask: u64,
}

impl SiblingBlock {
    /// True when the block holds every V-list pair of its offset
    /// ([`full_mask`]).
    pub fn is_full(&self) -> bool {
        self.mask == FULL_MASKS[self.offset as usize]
    }
}

/// [`full_mask`] of every offset.
static FULL_MASKS: std::sync::LazyLock<[u64; N_PARENT_OFFSETS]> =
    std::sync::LazyLock::new(|| std::array::from_fn(full_mask));

/// A pair that fits no block, applied on its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct LoosePair {
    /// Target slot.
    pub target: u32,
    /// Source slot.
    pub source: u32,
    /// Index of the transfer vector in [`transfer_vectors`].
    pub vector: u16,
}

/// A level's pairs as [`SiblingBlock`]s and [`LoosePair`]s per target
/// group: a pair `(t, s, v)` with slots `T`, `S` goes to target group
/// `T / 8`, source group `S / 8`, parent offset `d = (v - octant_bits(S %
/// 8) + octant_bits(T % 8)) / 2` and mask bit `8 (T % 8) + S % 8`, or is
/// kept loose when `d` is not in `[-1, 1]^3` or its block is taken (the
/// derivation is in the source module `siblings`).
#[derive(Clone, Debug, Default)]
pub struct SiblingBlocks {
    n_target_groups: usize,
    n_source_groups: usize,
    /// Column of each target slot (`NO_COLUMN` when absent).
    target_columns: Vec<u32>,
    /// Column of each source slot.
    source_columns: Vec<u32>,
    /// First target column of each target group (`n_target_groups + 1`).
    group_starts: Vec<u32>,
    block_starts: Vec<u32>,
    blocks: Vec<SiblingBlock>,
    loose_starts: Vec<u32>,
    loose: Vec<LoosePair>,
    /// Whether any pair uses each transfer vector (indexed as
    /// [`transfer_vectors`]).
    used_vectors: Vec<bool>,
}

const UNCLAIMED: u32 = u32::MAX;
const NO_COLUMN: u32 = u32::MAX;

/// Column of each slot `0..8 groups` (`NO_COLUMN` for a missing child),
/// and the number of groups.
fn columns_of_slots(cols: usize, slot: impl Fn(usize) -> usize) -> (Vec<u32>, usize) {
    let groups = if cols == 0 { 0 } else { slot(cols - 1) / 8 + 1 };
    let mut out = vec![NO_COLUMN; 8 * groups];
    for c in 0..cols {
        out[slot(c)] = c as u32;
    }
    (out, groups)
}

impl SiblingBlocks {
    /// Regroup the pairs of `inter` (in parallel; deterministic).
    pub fn new(inter: &M2lInteractions) -> Self {
        let (target_columns, n_target_groups) =
            columns_of_slots(inter.n_target_cols(), |t| inter.target_slot(t));
        let (source_columns, n_source_groups) =
            columns_of_slots(inter.n_source_cols(), |s| inter.source_slot(s));
        let mut group_starts = vec![0u32; n_target_groups + 1];
        for t in 0..inter.n_target_cols() {
            group_starts[inter.target_slot(t) / 8 + 1] += 1;
        }
        for g in 0..n_target_groups {
            group_starts[g + 1] += group_starts[g];
        }
        let slots = n_target_groups * N_PARENT_OFFSETS;
        let source: Vec<AtomicU32> = (0..slots).map(|_| AtomicU32::new(UNCLAIMED)).collect();
        let mask: Vec<AtomicU64> = (0..slots).map(|_| AtomicU64::new(0)).collect();
        let vectors = transfer_vectors();
        let chunks: Vec<_> = inter.chunk_views().collect();
        let mut used_vectors = vec![false; vectors.len()];
        for g in chunks.iter().flat_map(|c| c.groups()) {
            used_vectors[g.vector] = true;
        }
        // Pass 1: each (target group, offset) slot goes to its smallest
        // source group (deterministic whatever the thread timing).
        let slots =
            |(t, s, vi): (usize, usize, usize)| (inter.target_slot(t), inter.source_slot(s), vi);
        chunks.par_iter().for_each(|c| {
            for (t, s, vi) in pairs_of(*c).map(slots) {
                if let Some(d) = offset_of(t, s, vectors[vi]) {
                    source[(t / 8) * N_PARENT_OFFSETS + d]
                        .fetch_min((s / 8) as u32, Ordering::Relaxed);
                }
            }
        });
        // Pass 2: file the pairs of the slot's source group; the rest (and
        // repeats of a filed pair) stay loose.
        let mut loose: Vec<LoosePair> = chunks
            .par_iter()
            .flat_map_iter(|c| {
                let mut out = Vec::new();
                for (t, s, vi) in pairs_of(*c).map(slots) {
                    if let Some(d) = offset_of(t, s, vectors[vi]) {
                        let slot = (t / 8) * N_PARENT_OFFSETS + d;
                        if source[slot].load(Ordering::Relaxed) == (s / 8) as u32 {
                            let bit = 1u64 << (8 * (t % 8) + s % 8);
                            if mask[slot].fetch_or(bit, Ordering::Relaxed) & bit == 0 {
                                continue;
                            }
                        }
                    }
                    out.push(LoosePair {
                        target: t as u32,
                        source: s as u32,
                        vector: vi as u16,
                    });
                }
                out
            })
            .collect();
        loose.par_sort_unstable();
        let mut block_starts = Vec::with_capacity(n_target_groups + 1);
        let mut blocks = Vec::new();
        block_starts.push(0);
        for g in 0..n_target_groups {
            for d in 0..N_PARENT_OFFSETS {
                let slot = g * N_PARENT_OFFSETS + d;
                let m = mask[slot].load(Ordering::Relaxed);
                if m != 0 {
                    blocks.push(SiblingBlock {
                        source_group: source[slot].load(Ordering::Relaxed),
                        offset: d as u8,
                        mask: m,
                    });
                }
            }
            block_starts.push(blocks.len() as u32);
        }
        let mut loose_starts = vec![0u32; n_target_groups + 1];
        for p in &loose {
            loose_starts[p.target as usize / 8 + 1] += 1;
        }
        for g in 0..n_target_groups {
            loose_starts[g + 1] += loose_starts[g];
        }
        SiblingBlocks {
            n_target_groups,
            n_source_groups,
            target_columns,
            source_columns,
            group_starts,
            block_starts,
            blocks,
            loose_starts,
            loose,
            used_vectors,
        }
    }

    /// Whether some pair uses transfer vector `v` (its index in
    /// [`transfer_vectors`]).
    pub fn uses_vector(&self, v: usize) -> bool {
        self.used_vectors.get(v).copied().unwrap_or(false)
    }

    /// Bytes held by the regrouped pairs.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(&self.target_columns[..])
            + size_of_val(&self.source_columns[..])
            + size_of_val(&self.group_starts[..])
            + size_of_val(&self.block_starts[..])
            + size_of_val(&self.blocks[..])
            + size_of_val(&self.loose_starts[..])
            + size_of_val(&self.loose[..])
            + size_of_val(&self.used_vectors[..])
    }

    /// Number of target groups (the last target slot's group, plus one).
    pub fn n_target_groups(&self) -> usize {
        self.n_target_groups
    }

    /// Number of source groups.
    pub fn n_source_groups(&self) -> usize {
        self.n_source_groups
    }

    /// The target column of target slot `slot`, `None` for a missing child.
    pub fn target_column(&self, slot: usize) -> Option<usize> {
        let c = self.target_columns[slot];
        (c != NO_COLUMN).then_some(c as usize)
    }

    /// The source column of source slot `slot`, `None` for a missing child.
    pub fn source_column(&self, slot: usize) -> Option<usize> {
        let c = self.source_columns[slot];
        (c != NO_COLUMN).then_some(c as usize)
    }

    /// The target columns of target groups `groups` (consecutive: slots
    /// increase with the column).
    pub fn group_columns(&self, groups: std::ops::Range<usize>) -> std::ops::Range<usize> {
        self.group_starts[groups.start] as usize..self.group_starts[groups.end] as usize
    }

    /// The blocks of target group `g`, in ascending offset.
    pub fn blocks(&self, g: usize) -> &[SiblingBlock] {
        &self.blocks[self.block_starts[g] as usize..self.block_starts[g + 1] as usize]
    }

    /// The indices of the blocks of target group `g` among all blocks (in
    /// target-group order).
    pub fn block_range(&self, g: usize) -> std::ops::Range<usize> {
        self.block_starts[g] as usize..self.block_starts[g + 1] as usize
    }

    /// The loose pairs of target group `g` (target slots `8 g .. 8 g +
    /// 8`), sorted.
    pub fn loose(&self, g: usize) -> &[LoosePair] {
        &self.loose[self.loose_starts[g] as usize..self.loose_starts[g + 1] as usize]
    }

    /// Total number of blocks.
    pub fn n_blocks(&self) -> usize {
        self.blocks.len()
    }

    /// Total number of loose pairs.
    pub fn n_loose(&self) -> usize {
        self.loose.len()
    }

    /// The source groups target group `g` reads (those of its blocks, then
    /// those of its loose pairs; a group may repeat).
    pub fn source_groups(&self, g: usize) -> impl Iterator<Item = usize> + '_ {
        self.blocks(g)
            .iter()
            .map(|b| b.source_group as usize)
            .chain(self.loose(g).iter().map(|p| p.source as usize / 8))
    }

    /// Bit `ct` set for each child of target group `g` that receives a pair.
    pub fn targets_hit(&self, g: usize) -> u8 {
        let from_blocks = self.blocks(g).iter().fold(0u64, |m, b| m | b.mask);
        let mut hit = 0u8;
        for ct in 0..8 {
            if from_blocks >> (8 * ct) & 0xff != 0 {
                hit |= 1 << ct;
            }
        }
        self.loose(g)
            .iter()
            .fold(hit, |h, p| h | 1 << (p.target % 8))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_round_trip_and_full_masks() {
        for d in 0..N_PARENT_OFFSETS {
            let o = parent_offset(d);
            assert_eq!(((o[0] + 1) * 9 + (o[1] + 1) * 3 + (o[2] + 1)) as usize, d);
        }
        // The centre holds no pair; a face neighbour has 64 - 16 = 48
        // (children touching the shared face are adjacent in pairs of
        // rows), a corner neighbour 63.
        assert_eq!(full_mask(13), 0);
        assert_eq!(full_mask(22).count_ones(), 48); // d = (1, 0, 0)
        assert_eq!(full_mask(26).count_ones(), 63); // d = (1, 1, 1)
        // Over the 26 offsets each target child has 189 V-list sources.
        for ct in 0..8 {
            let n: u32 = (0..N_PARENT_OFFSETS)
                .map(|d| (full_mask(d) >> (8 * ct) & 0xff).count_ones())
                .sum();
            assert_eq!(n, 189);
        }
    }

    #[test]
    fn regrouping_keeps_every_pair_once() {
        let vs = transfer_vectors();
        // A 6 x 6 x 6 grid of children (3^3 parents) in Morton-like column
        // order, plus a misaligned pair and a repeated pair.
        let col = |p: [i32; 3]| slot(p) as usize;
        let mut pairs: Vec<_> = grid_v_pairs()
            .map(|(t, s, v)| (col(t), col(s), v))
            .collect();
        let aligned = pairs.len();
        pairs.push((3, 200, [3, 3, 3])); // columns unrelated to v
        pairs.push(pairs[0]);
        let inter = M2lInteractions::with_chunk_size(216, 216, &pairs, 12).unwrap();
        let sib = SiblingBlocks::new(&inter);
        assert_eq!(sib.n_loose(), 2);
        let mut got = Vec::new();
        for g in 0..sib.n_target_groups() {
            for b in sib.blocks(g) {
                for bit in 0..64 {
                    if b.mask >> bit & 1 == 1 {
                        let (ct, cs) = (bit / 8, bit % 8);
                        let vi = block_vector(b.offset as usize, ct, cs).expect("a V pair");
                        got.push((8 * g + ct, 8 * b.source_group as usize + cs, vs[vi]));
                    }
                }
            }
            for p in sib.loose(g) {
                assert_eq!(p.target as usize / 8, g);
                got.push((p.target as usize, p.source as usize, vs[p.vector as usize]));
            }
        }
        got.sort();
        pairs.sort();
        assert_eq!(got, pairs);
        let full = (0..sib.n_target_groups())
            .flat_map(|g| sib.blocks(g))
            .filter(|b| b.is_full())
            .count();
        assert!(full > 0 && aligned > 0);
    }

    /// Boxes left out (as a tree leaves out empty ones): with the sibling
    /// slots every pair still lands in a block; without them most go loose.
    #[test]
    fn slots_find_the_blocks_of_a_sparse_level() {
        let kept: Vec<u32> = (0..216u32).filter(|m| m % 3 != 1).collect();
        let column = |m: u32| kept.iter().position(|&k| k == m);
        let pairs: Vec<_> = grid_v_pairs()
            .filter_map(|(t, s, v)| Some((column(slot(t))?, column(slot(s))?, v)))
            .collect();
        let n = kept.len();
        let plain = M2lInteractions::with_chunk_size(n, n, &pairs, 16).unwrap();
        assert!(SiblingBlocks::new(&plain).n_loose() > pairs.len() / 2);
        let slotted = plain
            .with_sibling_slots(kept.clone(), kept.clone())
            .unwrap();
        let sib = slotted.sibling_blocks();
        assert_eq!(sib.n_loose(), 0);
        let filed: u32 = (0..sib.n_target_groups())
            .flat_map(|g| sib.blocks(g))
            .map(|b| b.mask.count_ones())
            .sum();
        assert_eq!(filed as usize, pairs.len());
        assert_eq!(sib.group_columns(0..sib.n_target_groups()), 0..n);
        for (c, &m) in kept.iter().enumerate() {
            assert_eq!(sib.target_column(m as usize), Some(c));
            assert_eq!(sib.source_column(m as usize), Some(c));
        }
        assert_eq!(sib.target_column(1), None);
        // Slots that do not increase are refused.
        let bad = M2lInteractions::with_chunk_size(2, 2, &[], 16).unwrap();
        assert!(bad.with_sibling_slots(vec![3, 3], vec![0, 1]).is_err());
    }

    fn itertools(n: i32) -> impl Iterator<Item = (i32, i32, i32)> {
        (0..n).flat_map(move |x| (0..n).flat_map(move |y| (0..n).map(move |z| (x, y, z))))
    }

    /// The V-list pairs `(target, source, v)` of a 6 x 6 x 6 grid of
    /// children (3^3 parents): parents neighbours, `v` a transfer vector.
    fn grid_v_pairs() -> impl Iterator<Item = ([i32; 3], [i32; 3], [i32; 3])> {
        itertools(6).flat_map(|(x, y, z)| {
            itertools(6).filter_map(move |(a, b, c)| {
                let v = [a - x, b - y, c - z];
                let near = (x / 2 - a / 2).abs() <= 1
                    && (y / 2 - b / 2).abs() <= 1
                    && (z / 2 - c / 2).abs() <= 1;
                (near && transfer_vector_index(v).is_some()).then_some(([x, y, z], [a, b, c], v))
            })
        })
    }

    /// Pair lists released to the sibling blocks come back exactly as they
    /// were grouped: the same chunks, groups and pairs in the same order,
    /// with loose pairs (a misaligned and a repeated one), on a sparse
    /// level with slots and on a plain one.
    #[test]
    fn released_pair_lists_come_back_as_they_were() {
        let kept: Vec<u32> = (0..216u32).filter(|m| m % 5 != 2).collect();
        let column = |m: u32| kept.iter().position(|&k| k == m);
        let mut pairs: Vec<_> = grid_v_pairs()
            .filter_map(|(t, s, v)| Some((column(slot(t))?, column(slot(s))?, v)))
            .collect();
        pairs.push((3, 150, [3, 3, 3]));
        pairs.push(pairs[7]);
        let n = kept.len();
        let plain = M2lInteractions::with_chunk_size(n, n, &pairs, 16).unwrap();
        let slotted = plain
            .clone()
            .with_sibling_slots(kept.clone(), kept.clone())
            .unwrap();
        let lists = |inter: &M2lInteractions| {
            inter
                .chunk_views()
                .map(|c| {
                    let groups: Vec<_> = c
                        .groups()
                        .map(|g| (g.vector, g.sources.to_vec(), g.targets.to_vec()))
                        .collect();
                    (c.first_target(), c.n_targets(), groups)
                })
                .collect::<Vec<_>>()
        };
        for inter in [plain, slotted] {
            let before = lists(&inter);
            let bytes = inter.memory_bytes();
            let mut released = inter.clone();
            released.release_pairs();
            assert!(!released.holds_pair_lists());
            assert_eq!(released.len(), pairs.len());
            if released.sibling_blocks().n_loose() < 4 {
                assert!(released.memory_bytes() < bytes);
            }
            assert!(
                (0..crate::N_TRANSFER_VECTORS).any(|v| released.sibling_blocks().uses_vector(v))
            );
            assert_eq!(lists(&released), before);
            assert!(released.holds_pair_lists());
            // New slots after a release: the pairs are still all there.
            let mut again = inter.clone();
            again.release_pairs();
            let reslotted = again
                .with_sibling_slots(kept.clone(), kept.clone())
                .unwrap();
            assert_eq!(lists(&reslotted), before);
        }
    }

    /// Morton-like slot of a child of the grid: `8 parent + octant`.
    fn slot([x, y, z]: [i32; 3]) -> u32 {
        let g = ((x / 2) * 9 + (y / 2) * 3 + z / 2) as u32;
        8 * g + ((x % 2) + 2 * (y % 2) + 4 * (z % 2)) as u32
    }
}
