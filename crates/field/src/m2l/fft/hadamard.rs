//! The pointwise (Hadamard) products of the FFT scheme, as `8 c x 8 c`
//! complex matrix-vector products per frequency on SIMD registers.
//!
//! # Layout
//!
//! Frequencies are taken in blocks of [`FREQ_BLOCK`] = 8 (one AVX-512
//! register of `f64`). One block of one quantity is `W = 16` values: the 8
//! real parts, then the 8 imaginary parts. A kernel with `c`
//! [components](ferrofmm_kernels::Kernel::components) has `c` spectra per
//! box (one per density or potential component) and `c^2` kernel spectra
//! per transfer vector (one per entry `K_ab` of its `c x c` block).
//!
//! * Kernel slab of a frequency block: `[vector 0..=316][a][b][W]` (vector
//!   316 is zero, the entry of adjacent children), `317 c^2 W` values.
//! * Source spectra of a sibling group: `[block][child 0..8][b][W]`, at
//!   the group's slot among the spectra of the run being applied
//!   ([`super::chunks`]).
//! * Target spectra of a sibling group: `[block][child 0..8][a][W]`.
//!
//! A quantity row `r = c ct + a` (target child `ct`, component `a`) and a
//! quantity column `q = c cs + b` make the `8 c x 8 c` block product below
//! the `8 x 8` one of a scalar kernel with `c x c` blocks for entries.
//!
//! # Products
//!
//! For target group `T`, frequency `f` and component `a`,
//!
//! ```text
//! y_T[ct, a](f) = sum_{blocks (S, d) of T}  sum_{cs, b}  That_{v(d, ct, cs), ab}(f) x_S[cs, b](f)
//!               + sum_{loose pairs (t, s, v) of T} sum_b  That_{v, ab}(f) x_{s/8}[s%8, b](f),
//! ```
//!
//! with `That_v = 0` for adjacent children. A block runs as a dense
//! product through its own table of slab entries ([`BlockTable`]: the zero
//! entry where the block has no pair; source children without pairs are
//! skipped): for each source quantity its two registers are loaded once
//! and multiplied into the accumulators of a pass of target rows, which
//! stay in registers over all of `T`'s blocks (`8` rows, `16` registers,
//! with AVX-512; with narrower registers the rows go four at a time). A
//! sparse block (as in adaptive trees, where a parent may have fewer than
//! eight children with points) whose pairs are fewer than two thirds of
//! the register products it would take goes pair by pair into memory
//! instead, as do loose pairs. Each complex multiply-add is four fused
//! multiply-adds: `re += kr xr - ki xi`, `im += kr xi + ki xr`.
//!
//! The component count is a type ([`Components`]): the scalar kernels run
//! the loops with `c = 1` known to the compiler (their code is that of a
//! scalar-only scheme), the others with `c` read at run time.

use ferrofmm_kernels::lanes::{Simd, SimdTask};

use crate::N_TRANSFER_VECTORS;
use crate::siblings::{N_PARENT_OFFSETS, SiblingBlocks, block_vector};

/// Frequencies per block.
pub(super) const FREQ_BLOCK: usize = 8;
/// Values per block of one complex quantity (real parts, imaginary parts).
pub(super) const W: usize = 2 * FREQ_BLOCK;
/// Kernel entries per slab: the 316 vectors and a zero entry.
pub(super) const SLAB_VECTORS: usize = N_TRANSFER_VECTORS + 1;
/// The zero entry of a slab.
const ZERO_VECTOR: u16 = N_TRANSFER_VECTORS as u16;

/// `[offset][cs][ct]`: the slab entry of each block entry (the zero entry
/// for adjacent children).
static BLOCK_ENTRIES: std::sync::LazyLock<[[[u16; 8]; 8]; N_PARENT_OFFSETS]> =
    std::sync::LazyLock::new(|| {
        std::array::from_fn(|d| {
            std::array::from_fn(|cs| {
                std::array::from_fn(|ct| block_vector(d, ct, cs).map_or(ZERO_VECTOR, |v| v as u16))
            })
        })
    });

/// How many components a kernel has: [`One`] for the scalar kernels (a
/// constant the compiler folds), [`Many`] otherwise.
pub(super) trait Components: Copy {
    /// The number `c` of components.
    fn get(self) -> usize;
}

/// One component (scalar kernels).
#[derive(Clone, Copy)]
pub(super) struct One;

impl Components for One {
    #[inline(always)]
    fn get(self) -> usize {
        1
    }
}

/// `c` components, known at run time.
#[derive(Clone, Copy)]
pub(super) struct Many(pub usize);

impl Components for Many {
    #[inline(always)]
    fn get(self) -> usize {
        self.0
    }
}

/// The products of the target groups `first..first + n` for every
/// frequency block: `targets` (that many groups, zeroed) receives their
/// spectra.
pub(super) struct Products<'a, C: Components> {
    /// Components of the kernel.
    pub components: C,
    /// Kernel slabs of the level's operator set, `[block][SLAB_VECTORS][c][c][W]`.
    pub kernels: &'a [f64],
    /// Source spectra, `[slot][block][8][c][W]`: source group `s` at slot
    /// `source_slots[s]`.
    pub sources: &'a [f64],
    /// The slot in `sources` of each source group the groups read.
    pub source_slots: &'a [u32],
    /// The level's pairs.
    pub siblings: &'a SiblingBlocks,
    /// Slab entries of every block of the target groups `first..`
    /// ([`block_tables`]).
    pub tables: &'a [BlockTable],
    /// First target group.
    pub first: usize,
    /// Target spectra of the groups `first..`, `[group][block][8][c][W]`.
    pub targets: &'a mut [f64],
    /// Frequency blocks.
    pub blocks: usize,
}

impl<'a> Products<'a, One> {
    /// The same products for a kernel with `components`.
    pub(super) fn with_components<C: Components>(self, components: C) -> Products<'a, C> {
        Products {
            components,
            kernels: self.kernels,
            sources: self.sources,
            source_slots: self.source_slots,
            siblings: self.siblings,
            tables: self.tables,
            first: self.first,
            targets: self.targets,
            blocks: self.blocks,
        }
    }
}

impl<C: Components> SimdTask<f64> for Products<'_, C> {
    type Output = ();

    #[inline(always)]
    fn run<S: Simd<f64>>(self, s: S) {
        let c = self.components.get();
        let block_len = 8 * c * W;
        let group_len = self.blocks * block_len;
        let slab_len = SLAB_VECTORS * c * c * W;
        let n = self.targets.len() / group_len;
        let base = self.siblings.block_range(self.first).start;
        for b in 0..self.blocks {
            let slab = &self.kernels[b * slab_len..(b + 1) * slab_len];
            for g in 0..n {
                let group = self.first + g;
                let blocks = self.siblings.blocks(group);
                let range = self.siblings.block_range(group);
                let tables = &self.tables[range.start - base..range.end - base];
                let out = &mut self.targets[g * group_len + b * block_len..][..block_len];
                let at = Offsets {
                    components: self.components,
                    group_len,
                    block: b * block_len,
                };
                let slots = self.source_slots;
                dense_blocks(s, at, slab, self.sources, slots, blocks, tables, out);
                for (blk, table) in blocks.iter().zip(tables).filter(|(_, t)| !t.dense) {
                    let slot = slots[blk.source_group as usize] as usize;
                    let x = &self.sources[slot * group_len + at.block..];
                    let mut m = blk.mask;
                    while m != 0 {
                        let bit = m.trailing_zeros() as usize;
                        m &= m - 1;
                        let (ct, cs) = (bit / 8, bit % 8);
                        let k = table.entries[cs][ct] as usize;
                        block_multiply_add(s, self.components, slab, k, x, cs, out, ct);
                    }
                }
                for p in self.siblings.loose(group) {
                    let (ct, cs) = (p.target as usize % 8, p.source as usize % 8);
                    let slot = slots[p.source as usize / 8] as usize;
                    let x = &self.sources[slot * group_len + at.block..];
                    let k = p.vector as usize;
                    block_multiply_add(s, self.components, slab, k, x, cs, out, ct);
                }
            }
        }
    }
}

/// Where one frequency block of a sibling group lies in the spectra.
#[derive(Clone, Copy)]
struct Offsets<C: Components> {
    components: C,
    /// Values per sibling group.
    group_len: usize,
    /// Offset of the frequency block in a group.
    block: usize,
}

/// Slab entries of one block, `[cs][ct]` (the zero entry where the block
/// has no pair), the mask of source children with at least one pair, and
/// how the block is applied.
#[derive(Clone, Copy, Debug)]
pub(super) struct BlockTable {
    entries: [[u16; 8]; 8],
    sources: u8,
    /// In registers (`8` products per source child with a pair, zeros
    /// included) rather than pair by pair in memory (about 1.5x the
    /// cost of a register product each): whichever is cheaper.
    dense: bool,
}

/// The [`BlockTable`] of every block of the target groups `groups` of
/// `siblings`, in block order, into `out` (cleared first).
///
/// Made per task rather than for the whole level: a table is 130 bytes
/// and a uniform level has about 189 blocks per target group, so the
/// level's tables would take 16 bytes a point at 1e8 points (more than the
/// expansions of the level), while making them costs a few nanoseconds a
/// block against the block's `64 x` frequency-block products.
pub(super) fn block_tables(
    siblings: &SiblingBlocks,
    groups: std::ops::Range<usize>,
    out: &mut Vec<BlockTable>,
) {
    let full = &*BLOCK_ENTRIES;
    out.clear();
    out.extend(groups.flat_map(|g| siblings.blocks(g)).map(|blk| {
        let mut t = BlockTable {
            entries: [[ZERO_VECTOR; 8]; 8],
            sources: 0,
            dense: false,
        };
        for bit in (0..64).filter(|bit| blk.mask >> bit & 1 == 1) {
            let (ct, cs) = (bit / 8, bit % 8);
            t.entries[cs][ct] = full[blk.offset as usize][cs][ct];
            t.sources |= 1 << cs;
        }
        t.dense = 8 * t.sources.count_ones() * 2 <= 3 * blk.mask.count_ones();
        t
    }));
}

/// The register-applied blocks of one target group at one frequency
/// block, written (not added) to `out` (`8 c W` values; zeros when there
/// are none). Source children without pairs are skipped; a missing pair
/// multiplies by the zero entry.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn dense_blocks<S: Simd<f64>, C: Components>(
    s: S,
    at: Offsets<C>,
    slab: &[f64],
    sources: &[f64],
    source_slots: &[u32],
    blocks: &[crate::siblings::SiblingBlock],
    tables: &[BlockTable],
    out: &mut [f64],
) {
    let c = at.components.get();
    let block_len = 8 * c * W;
    let l = S::LANES;
    // Target rows per pass: eight with 8 lanes (16 accumulators), four
    // with fewer (so that accumulators and operands fit the register file).
    // A constant of the instruction set, and a divisor of the `8 c` rows,
    // so every pass is full and its loops unroll.
    let per_pass = if l >= FREQ_BLOCK { 8 } else { 4 };
    let rows = 8 * c;
    let zero = s.splat(0.0);
    for lane0 in (0..FREQ_BLOCK).step_by(l) {
        for r0 in (0..rows).step_by(per_pass) {
            // Target child and component of each row of the pass.
            let child: [usize; 8] = std::array::from_fn(|i| (r0 + i) / c);
            let comp: [usize; 8] = std::array::from_fn(|i| (r0 + i) % c);
            let mut acc = [[zero; 2]; 8];
            for (blk, table) in blocks.iter().zip(tables).filter(|(_, t)| t.dense) {
                let slot = source_slots[blk.source_group as usize] as usize;
                let x = &sources[slot * at.group_len + at.block..][..block_len];
                for cs in (0..8).filter(|cs| table.sources >> cs & 1 == 1) {
                    for b in 0..c {
                        let q = (cs * c + b) * W;
                        let xr = s.load(&x[q + lane0..]);
                        let xi = s.load(&x[q + FREQ_BLOCK + lane0..]);
                        let nxi = s.sub(zero, xi);
                        for (i, a) in acc.iter_mut().enumerate().take(per_pass) {
                            let entry = table.entries[cs][child[i]] as usize;
                            let k = &slab[((entry * c + comp[i]) * c + b) * W..][..W];
                            let kr = s.load(&k[lane0..]);
                            let ki = s.load(&k[FREQ_BLOCK + lane0..]);
                            a[0] = s.mul_add(ki, nxi, s.mul_add(kr, xr, a[0]));
                            a[1] = s.mul_add(ki, xr, s.mul_add(kr, xi, a[1]));
                        }
                    }
                }
            }
            for (i, a) in acc.iter().enumerate().take(per_pass) {
                s.store(a[0], &mut out[(r0 + i) * W + lane0..]);
                s.store(a[1], &mut out[(r0 + i) * W + FREQ_BLOCK + lane0..]);
            }
        }
    }
}

/// `y[ct, a] += sum_b K_{k, ab} x[cs, b]` for one block of complex values
/// (`W` each): one pair in memory.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn block_multiply_add<S: Simd<f64>, C: Components>(
    s: S,
    components: C,
    slab: &[f64],
    k: usize,
    x: &[f64],
    cs: usize,
    out: &mut [f64],
    ct: usize,
) {
    let c = components.get();
    for a in 0..c {
        for b in 0..c {
            multiply_add(
                s,
                &slab[((k * c + a) * c + b) * W..],
                &x[(cs * c + b) * W..],
                &mut out[(ct * c + a) * W..],
            );
        }
    }
}

/// `y += k x` for one block of complex values (`W` each).
#[inline(always)]
fn multiply_add<S: Simd<f64>>(s: S, k: &[f64], x: &[f64], y: &mut [f64]) {
    let l = S::LANES;
    for lane0 in (0..FREQ_BLOCK).step_by(l) {
        let (kr, ki) = (s.load(&k[lane0..]), s.load(&k[FREQ_BLOCK + lane0..]));
        let (xr, xi) = (s.load(&x[lane0..]), s.load(&x[FREQ_BLOCK + lane0..]));
        let yr = s.load(&y[lane0..]);
        let yi = s.load(&y[FREQ_BLOCK + lane0..]);
        s.store(s.sub(s.mul_add(kr, xr, yr), s.mul(ki, xi)), &mut y[lane0..]);
        s.store(
            s.mul_add(ki, xr, s.mul_add(kr, xi, yi)),
            &mut y[FREQ_BLOCK + lane0..],
        );
    }
}
