//! The pointwise (Hadamard) products of the FFT scheme, as `8 x 8` complex
//! matrix-vector products per frequency on SIMD registers.
//!
//! # Layout
//!
//! Frequencies are taken in blocks of [`FREQ_BLOCK`] = 8 (one AVX-512
//! register of `f64`). One block of one quantity is `W = 16` values: the 8
//! real parts, then the 8 imaginary parts.
//!
//! * Kernel slab of a frequency block: `[vector 0..=316][W]` (vector 316 is
//!   zero, the entry of adjacent children), `317 W` values.
//! * Source spectra of a sibling group: `[block][child 0..8][W]`.
//! * Target spectra of a sibling group: the same.
//!
//! # Products
//!
//! For target group `T` and frequency `f`,
//!
//! ```text
//! y_T[ct](f) = sum_{blocks (S, d) of T}  sum_cs  That_{v(d, ct, cs)}(f) x_S[cs](f)
//!            + sum_{loose pairs (t, s, v) of T}   That_v(f) x_{s/8}[s%8](f),
//! ```
//!
//! with `That_v = 0` for adjacent children. A block runs as a dense `8 x 8`
//! product through its own table of slab entries ([`BlockTable`]: the zero
//! entry where the block has no pair; source children without pairs are
//! skipped): for each source child its two registers are loaded once and
//! multiplied into the eight target children's accumulators, which stay in
//! registers over all of `T`'s blocks (`16` registers with AVX-512; with
//! narrower registers the targets go four at a time). A sparse block (as
//! in adaptive trees, where a parent may have fewer than eight children
//! with points) whose pairs are fewer than two thirds of the register
//! products it would take goes pair by pair into memory instead, as do
//! loose pairs. Each complex multiply-add is four fused
//! multiply-adds: `re += kr xr - ki xi`, `im += kr xi + ki xr`.

use ferrofmm_kernels::lanes::{Simd, SimdTask};
use rayon::prelude::*;

use crate::N_TRANSFER_VECTORS;
use crate::plumbing::{N_PARENT_OFFSETS, SiblingBlocks, block_vector};

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

/// The products of the target groups `first..first + n` for every
/// frequency block: `targets` (that many groups, zeroed) receives their
/// spectra.
pub(super) struct Products<'a> {
    /// Kernel slabs of the level's operator set, `[block][SLAB_VECTORS][W]`.
    pub kernels: &'a [f64],
    /// Source spectra, `[group][block][8][W]`.
    pub sources: &'a [f64],
    /// The level's pairs.
    pub siblings: &'a SiblingBlocks,
    /// Slab entries of every block of the level ([`block_tables`]).
    pub tables: &'a [BlockTable],
    /// First target group.
    pub first: usize,
    /// Target spectra of the groups `first..`, `[group][block][8][W]`.
    pub targets: &'a mut [f64],
    /// Frequency blocks.
    pub blocks: usize,
}

impl SimdTask<f64> for Products<'_> {
    type Output = ();

    #[inline(always)]
    fn run<S: Simd<f64>>(self, s: S) {
        let group_len = self.blocks * 8 * W;
        let n = self.targets.len() / group_len;
        for b in 0..self.blocks {
            let slab = &self.kernels[b * SLAB_VECTORS * W..(b + 1) * SLAB_VECTORS * W];
            for g in 0..n {
                let group = self.first + g;
                let blocks = self.siblings.blocks(group);
                let tables = &self.tables[self.siblings.block_range(group)];
                let out = &mut self.targets[g * group_len + b * 8 * W..][..8 * W];
                dense_blocks(s, slab, self.sources, group_len, b, blocks, tables, out);
                for (blk, table) in blocks.iter().zip(tables).filter(|(_, t)| !t.dense) {
                    let x = &self.sources[blk.source_group as usize * group_len + b * 8 * W..];
                    let mut m = blk.mask;
                    while m != 0 {
                        let bit = m.trailing_zeros() as usize;
                        m &= m - 1;
                        let (ct, cs) = (bit / 8, bit % 8);
                        let k = table.entries[cs][ct] as usize;
                        multiply_add(s, &slab[k * W..], &x[cs * W..], &mut out[ct * W..]);
                    }
                }
                for p in self.siblings.loose(group) {
                    let (ct, cs) = (p.target as usize % 8, p.source as usize % 8);
                    let x = &self.sources[(p.source as usize / 8) * group_len + b * 8 * W..];
                    let k = p.vector as usize;
                    multiply_add(s, &slab[k * W..], &x[cs * W..], &mut out[ct * W..]);
                }
            }
        }
    }
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

/// The [`BlockTable`] of every block of `siblings`, in block order (in
/// parallel over target groups).
pub(super) fn block_tables(siblings: &SiblingBlocks) -> Vec<BlockTable> {
    let full = &*BLOCK_ENTRIES;
    (0..siblings.n_target_groups())
        .into_par_iter()
        .flat_map_iter(|g| siblings.blocks(g))
        .map(|blk| {
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
        })
        .collect()
}

/// The register-applied blocks of one target group at one frequency
/// block, written (not added) to `out` (`8 W` values; zeros when there are
/// none). Source children without pairs are skipped; a missing pair
/// multiplies by the zero entry.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn dense_blocks<S: Simd<f64>>(
    s: S,
    slab: &[f64],
    sources: &[f64],
    group_len: usize,
    b: usize,
    blocks: &[crate::plumbing::SiblingBlock],
    tables: &[BlockTable],
    out: &mut [f64],
) {
    let l = S::LANES;
    // Targets per pass: all eight with 8 lanes (16 accumulators), four with
    // fewer (so that accumulators and operands fit the register file).
    let per_pass = if l >= FREQ_BLOCK { 8 } else { 4 };
    let zero = s.splat(0.0);
    for lane0 in (0..FREQ_BLOCK).step_by(l) {
        for t0 in (0..8).step_by(per_pass) {
            let mut acc = [[zero; 2]; 8];
            for (blk, table) in blocks.iter().zip(tables).filter(|(_, t)| t.dense) {
                let x = &sources[blk.source_group as usize * group_len + b * 8 * W..][..8 * W];
                for cs in (0..8).filter(|cs| table.sources >> cs & 1 == 1) {
                    let xr = s.load(&x[cs * W + lane0..]);
                    let xi = s.load(&x[cs * W + FREQ_BLOCK + lane0..]);
                    let nxi = s.sub(zero, xi);
                    for (ct, a) in acc.iter_mut().enumerate().skip(t0).take(per_pass) {
                        let k = &slab[table.entries[cs][ct] as usize * W..][..W];
                        let kr = s.load(&k[lane0..]);
                        let ki = s.load(&k[FREQ_BLOCK + lane0..]);
                        a[0] = s.mul_add(ki, nxi, s.mul_add(kr, xr, a[0]));
                        a[1] = s.mul_add(ki, xr, s.mul_add(kr, xi, a[1]));
                    }
                }
            }
            for (ct, a) in acc.iter().enumerate().skip(t0).take(per_pass) {
                s.store(a[0], &mut out[ct * W + lane0..]);
                s.store(a[1], &mut out[ct * W + FREQ_BLOCK + lane0..]);
            }
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
