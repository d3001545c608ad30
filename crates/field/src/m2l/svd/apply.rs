//! Application of [`SvdM2l`]: compress, translate in the compressed
//! space, expand.
//!
//! With the set's bases `U_k` (`n x k`), `V_k` (`n x k`) and the cores
//! `C_v ≈ A_v B_v^T`, for each chunk of target columns:
//!
//! ```text
//! m_s = V_k^T phi_s                       (every source column the chunk reads)
//! c_t = sum_{(t, s, v)} C_v m_s          (C_v whole: one k x k GEMM per group;
//!                                          factored: B_v^T, then A_v)
//! d_t += s U_k c_t                        (every target column of the chunk)
//! ```
//!
//! with `s = (h / h_ref)^d` for a kernel homogeneous of degree `d`. Flops:
//! `4 k r_v` (or `2 k^2`) per pair plus `2 n k` per source column read and
//! per target column, against `2 n^2` per pair for the dense scheme.
//!
//! Each chunk compresses the source columns it reads itself (runs of
//! consecutive columns straight from the multipoles), so no compressed copy
//! of a whole level is ever held: a column read by several chunks is
//! compressed once for each (on a uniform level of 256-column chunks about
//! 4.5 times, 10-15% more flops than the pairs' own), and the chunk's pairs
//! can come from the sibling blocks one chunk at a time
//! ([`M2lInteractions::with_chunk`]), so the SVD scheme keeps no pair lists
//! either ([`M2lScheme::reads_pair_lists`](crate::M2lScheme::reads_pair_lists)).

use ferrofmm_kernels::Real;
use rayon::prelude::*;

use super::SvdM2l;
use super::store::VectorOp;
use crate::interactions::ChunkView;
use crate::m2l::{M2lProgress, for_each_chunk_with_progress, for_each_vector_group_at, level_set};
use crate::{M2lInteractions, Update, gemm, gemm_scaled};

/// Columns per compression product.
const COMPRESS_COLS: usize = 256;

/// The source columns a chunk reads, sorted, without repeats.
fn chunk_sources(chunk: &ChunkView<'_>) -> Vec<u32> {
    let mut cols: Vec<u32> = chunk
        .groups()
        .flat_map(|g| g.sources.iter().copied())
        .collect();
    cols.sort_unstable();
    cols.dedup();
    cols
}

/// `out[:, i] = vt * multipoles[:, cols[i]]` (`k x cols.len()`), one GEMM
/// per run of consecutive columns (at most [`COMPRESS_COLS`] each).
fn compress_columns<T: Real>(
    k: usize,
    n: usize,
    vt: &[T],
    multipoles: &[T],
    cols: &[u32],
    out: &mut [T],
) {
    let mut i = 0;
    while i < cols.len() {
        let first = cols[i] as usize;
        let mut len = 1;
        while i + len < cols.len() && len < COMPRESS_COLS && cols[i + len] as usize == first + len {
            len += 1;
        }
        gemm(
            k,
            len,
            n,
            vt,
            &multipoles[first * n..(first + len) * n],
            &mut out[i * k..(i + len) * k],
            Update::Overwrite,
        );
        i += len;
    }
}

impl<T: Real> SvdM2l<T> {
    /// [`M2lScheme::apply_with_progress`](crate::M2lScheme::apply_with_progress):
    /// see the module docs.
    pub(super) fn apply_compressed(
        &self,
        level: u32,
        interactions: &M2lInteractions,
        multipoles: &[T],
        check: &mut [T],
        progress: M2lProgress<'_>,
    ) {
        let n = self.n;
        let Some((set, scale)) = level_set(&self.levels, level, n, interactions, multipoles, check)
        else {
            return;
        };
        let k = self.store.layout.sets[set].rank;
        let (start, ops) = &self.layout[set];
        let data = &self.store.data[*start..];
        let (u, rest) = data.split_at(n * k);
        let vt = &rest[..k * n];
        let store = &self.store.data;
        let max_rank = ops.iter().map(|o| o.rank).max().unwrap_or(k);
        for_each_chunk_with_progress(interactions, n, check, progress, |chunk, out| {
            // The chunk's source columns, compressed: mc = V_k^T M.
            let cols = chunk_sources(&chunk);
            let mut mc = vec![T::ZERO; k * cols.len()];
            compress_columns(k, n, vt, multipoles, &cols, &mut mc);
            let nt = chunk.n_targets();
            let mut acc = vec![T::ZERO; k * nt];
            let mut mid = vec![T::ZERO; max_rank * chunk.max_group_len()];
            let column = |s: u32| {
                cols.binary_search(&s)
                    .expect("every source of the chunk was compressed")
            };
            for_each_vector_group_at(&chunk, &mc, column, k, &mut acc, k, |v, src, dst| {
                let len = src.len() / k;
                let VectorOp { offset, rank: r } = ops[v];
                assert!(
                    r > 0,
                    "M2L operator of transfer vector {v} was not precomputed: \
                     the interactions differ from the usage given to precompute_for"
                );
                if r == k {
                    let cv = &store[offset..offset + k * k];
                    gemm(k, len, k, cv, src, dst, Update::Overwrite);
                } else {
                    // C_v = A_v B_v^T: mid = B_v^T src, dst = A_v mid.
                    let (av, bt) = store[offset..offset + 2 * k * r].split_at(k * r);
                    let mid = &mut mid[..r * len];
                    gemm(r, len, k, bt, src, mid, Update::Overwrite);
                    gemm(k, len, r, av, mid, dst, Update::Overwrite);
                }
            });
            gemm_scaled(n, nt, k, scale, u, &acc, out, Update::Accumulate);
        });
    }

    /// Flops of one apply: `4 k r_v` (or `2 k^2`) per pair plus `2 n k` per
    /// source column a chunk reads and per target column.
    pub(super) fn apply_flops(&self, interactions: &M2lInteractions) -> f64 {
        // Assumes the first set; ranks are equal or close across sets.
        let Some(set) = self.store.layout.sets.first() else {
            return 0.0;
        };
        let k = set.rank as f64;
        let n = self.n as f64;
        let (pairs, read): (f64, usize) = (0..interactions.n_chunks())
            .into_par_iter()
            .map(|c| {
                interactions.with_chunk(c, |chunk| {
                    let pairs = chunk
                        .groups()
                        .map(|g| g.sources.len() as f64 * set.pair_flops(g.vector))
                        .sum::<f64>();
                    (pairs, chunk_sources(&chunk).len())
                })
            })
            .reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        pairs + 2.0 * n * k * (read + interactions.n_target_cols()) as f64
    }
}
