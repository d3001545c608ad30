//! What a cached [`SvdM2l`](super::SvdM2l) holds and where each operator
//! lies in it.
//!
//! Per set, column-major: `U_k` (`n x k`), `V_k^T` (`k x n`), then for each
//! of the 316 transfer vectors either `C_v` (`k x k`, `r_v = k`) or its
//! factors `A_v` (`k x r_v`) and `B_v^T` (`r_v x k`): `2 n k + sum_v
//! len_v` values with `len_v = k^2` or `2 k r_v` ([`SvdSetInfo::len`]). A
//! vector not computed has `r_v = 0` and no values.

use crate::N_TRANSFER_VECTORS;
use crate::cache::StoreLayout;

/// Per-set compression summary.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct SvdSetInfo {
    /// Rank `k` of the bases.
    pub(super) rank: usize,
    /// `sigma_k / sigma_0` of the fat and tall stacks (first dropped value,
    /// 0 when nothing is dropped).
    pub(super) dropped_fat: f64,
    /// As `dropped_fat`, for the tall stack.
    pub(super) dropped_tall: f64,
    /// Rank `r_v` of each `C_v`; `r_v == rank` means `C_v` is stored whole.
    pub(super) vector_ranks: Vec<u32>,
}

impl SvdSetInfo {
    /// Values stored for transfer vector `v`: `k^2` whole, `2 k r_v`
    /// factored.
    pub(super) fn vector_len(&self, v: usize) -> usize {
        let (k, r) = (self.rank, self.vector_ranks[v] as usize);
        if r == k { k * k } else { 2 * k * r }
    }

    /// Values of the whole set: `U_k`, `V_k^T` and the 316 `C_v`.
    pub(super) fn len(&self, n: usize) -> usize {
        2 * n * self.rank
            + (0..N_TRANSFER_VECTORS)
                .map(|v| self.vector_len(v))
                .sum::<usize>()
    }

    /// Flops of one pair at transfer vector `v`.
    pub(super) fn pair_flops(&self, v: usize) -> f64 {
        let (k, r) = (self.rank as f64, self.vector_ranks[v] as f64);
        if self.vector_ranks[v] as usize == self.rank {
            2.0 * k * k
        } else {
            4.0 * k * r
        }
    }
}

/// Where one `C_v` lies in the store, and its rank.
#[derive(Clone, Copy, Debug)]
pub(super) struct VectorOp {
    /// First value of the operator in the store.
    pub(super) offset: usize,
    /// Its rank `r_v` (`k`: stored whole; 0: not computed).
    pub(super) rank: usize,
}

/// What a cached SVD scheme holds, set by set: `U_k` (`n x k`), `V_k^T`
/// (`k x n`), then per transfer vector either `C_v` (`k x k`) or its
/// factors `A_v` (`k x r_v`) and `B_v^T` (`r_v x k`), all column-major.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct SvdLayout {
    /// Surface points `n`.
    pub(super) n: usize,
    /// Ranks and truncation estimates of each set.
    pub(super) sets: Vec<SvdSetInfo>,
}

impl StoreLayout for SvdLayout {
    fn n_values(&self) -> Result<usize, String> {
        for s in &self.sets {
            if s.vector_ranks.len() != N_TRANSFER_VECTORS {
                return Err(format!(
                    "{} transfer-vector ranks, expected {N_TRANSFER_VECTORS}",
                    s.vector_ranks.len()
                ));
            }
            if s.rank == 0 || s.rank > self.n {
                return Err("rank outside 1..=n".into());
            }
            if s.vector_ranks
                .iter()
                .any(|&r| r == 0 || r as usize > s.rank)
            {
                return Err("transfer-vector rank outside 1..=k".into());
            }
        }
        Ok(self.sets.iter().map(|s| s.len(self.n)).sum())
    }
}

impl SvdLayout {
    /// Start of each set in the store and where its 316 operators lie.
    pub(super) fn operators(&self) -> Vec<(usize, Vec<VectorOp>)> {
        let mut start = 0;
        self.sets
            .iter()
            .map(|s| {
                let mut offset = start + 2 * self.n * s.rank;
                let ops = (0..N_TRANSFER_VECTORS)
                    .map(|v| {
                        let op = VectorOp {
                            offset,
                            rank: s.vector_ranks[v] as usize,
                        };
                        offset += s.vector_len(v);
                        op
                    })
                    .collect();
                let set_start = start;
                start += s.len(self.n);
                (set_start, ops)
            })
            .collect()
    }
}
