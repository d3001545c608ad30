//! Application of [`SvdM2l`]: compress, translate in the compressed
//! space, expand.
//!
//! With the set's bases `U_k` (`n x k`), `V_k` (`n x k`) and the cores
//! `C_v ≈ A_v B_v^T`:
//!
//! ```text
//! m_s = V_k^T phi_s                       (every source column, once)
//! c_t = sum_{(t, s, v)} C_v m_s          (C_v whole: one k x k GEMM per group;
//!                                          factored: B_v^T, then A_v)
//! d_t += s U_k c_t                        (every target column of a chunk, once)
//! ```
//!
//! with `s = (h / h_ref)^d` for a kernel homogeneous of degree `d`. Flops:
//! `4 k r_v` (or `2 k^2`) per pair plus `2 n k` per source and target
//! column, against `2 n^2` per pair for the dense scheme.

use ferrofmm_kernels::Real;
use rayon::prelude::*;

use super::SvdM2l;
use super::store::VectorOp;
use crate::m2l::{M2lProgress, for_each_chunk_with_progress, for_each_vector_group, level_set};
use crate::{M2lInteractions, Update, gemm, gemm_scaled};

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
        // Compress all multipoles: mc = V_k^T M (k x n_source_cols).
        let ns = interactions.n_source_cols();
        let mut mc = vec![T::ZERO; k * ns];
        const COLS: usize = 256;
        mc.par_chunks_mut(k * COLS)
            .zip(multipoles.par_chunks(n * COLS))
            .for_each(|(out, m)| gemm(k, m.len() / n, n, vt, m, out, Update::Overwrite));
        let mc = &mc;
        let store = &self.store.data;
        let max_rank = ops.iter().map(|o| o.rank).max().unwrap_or(k);
        for_each_chunk_with_progress(interactions, n, check, progress, |chunk, out| {
            let nt = chunk.n_targets();
            let mut acc = vec![T::ZERO; k * nt];
            let mut mid = vec![T::ZERO; max_rank * chunk.max_group_len()];
            for_each_vector_group(&chunk, mc, k, &mut acc, k, |v, src, dst| {
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
    /// source and target column.
    pub(super) fn apply_flops(&self, interactions: &M2lInteractions) -> f64 {
        // Assumes the first set; ranks are equal or close across sets.
        let Some(set) = self.store.layout.sets.first() else {
            return 0.0;
        };
        let k = set.rank as f64;
        let n = self.n as f64;
        let pairs: f64 = interactions
            .chunk_views()
            .flat_map(|c| c.groups())
            .map(|g| g.sources.len() as f64 * set.pair_flops(g.vector))
            .sum();
        pairs + 2.0 * n * k * (interactions.n_source_cols() + interactions.n_target_cols()) as f64
    }
}
