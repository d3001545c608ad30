//! Compression of one operator set of [`SvdM2l`](super::SvdM2l)
//! (Fong–Darve), all in `f64`.
//!
//! With `K_v` the `n x n` M2L matrices of the set's transfer vectors:
//!
//! 1. **Bases.** `U_k`: the first `k` left singular vectors of the fat
//!    stack `[K_1 ... K_m]`; `V_k`: the first `k` right singular vectors
//!    of the tall stack `[K_1; ...; K_m]`. Both come from the `R` factor of
//!    a two-level TSQR (blocks of [`TSQR_BLOCK`] matrices factorised in
//!    parallel, then their stacked `R`s), so the stacks are never held:
//!    the right singular vectors of `R_tall` are `V`, those of `R_fat`
//!    (from the fat stack's transpose) are `U`. The rank `k` is the given
//!    one, or the smallest with `sigma_k / sigma_0 <= tol` for both stacks.
//! 2. **Cores.** `C_v = U_k^T K_v V_k` (`k x k`, [`project`]).
//! 3. **Recompression** (rank from the tolerance only). The SVD of each
//!    `C_v` keeps the `r_v` singular values above [`RECOMPRESSION_FACTOR`]
//!    `tol s_max` (`s_max` over all `C_v`): `C_v ≈ A_v B_v^T`,
//!    `A_v = U_r S_r`, `B_v = V_r`; kept whole when `2 r_v >= k`.
//!
//! Step 1 (two QRs of `m n x n` stacks) does not depend on the tolerance
//! or the working type: [`set_bases`] computes it once and the cache keeps
//! it in an entry of its own ([`SvdBasesLayout`]), from which
//! [`compress_with`] makes each truncation. It is most of the cost at
//! moderate ranks (order 10, f32: 7.1 of 9.7 s on 2 cores) and a third at
//! ranks near `n`, where step 3's SVDs of the cores dominate (order 10,
//! f64: 21.3 s in all).
//!
//! Progress is counted in units roughly proportional to time
//! ([`set_units`]).

use faer::{Mat, MatRef, Par};
use ferrofmm_kernels::Kernel;
use rayon::prelude::*;

use super::store::SvdSetInfo;
use crate::cache::{FlatStore, StoreLayout};
use crate::linalg::{col_major, householder_r_until, product, svd};
use crate::m2l::m2l_matrix;
use crate::monitor::Units;
use crate::threads::nested_par;
use crate::{FieldError, N_TRANSFER_VECTORS, OperatorParams, expansion_len, transfer_vectors};

/// Per-vector truncation of `C_v` relative to the set's tolerance: singular
/// values of `C_v` below `RECOMPRESSION_FACTOR * tolerance * s_max` (with
/// `s_max` the largest singular value of all 316 `C_v`) are dropped. The
/// per-vector ranks are 4.7-5.6x below `k` (p = 6: mean 18 of 94), and
/// dropping a third of the tolerance keeps the FMM error within a few
/// percent of the unfactored scheme's (`docs/algorithms.md`).
pub(super) const RECOMPRESSION_FACTOR: f64 = 0.3;

/// Matrices per TSQR block.
pub(super) const TSQR_BLOCK: usize = 16;

/// Progress units per transfer vector of the TSQR (two QRs of its rows),
/// of the bases (its share of the two SVDs), of its projection and of its
/// own SVD, so that units are roughly proportional to time.
const TSQR_UNITS: u64 = 6;
const BASES_UNITS: u64 = 1;

/// Progress units of a set of `m` vectors.
pub(super) fn set_units(m: usize, refactor: bool) -> u64 {
    if m == 0 {
        return 0;
    }
    m as u64 * (TSQR_UNITS + BASES_UNITS + 1 + u64::from(refactor))
}

/// The bases of one set (step 1): the right singular vectors and
/// singular values of the fat stack's transpose (`u`, `s_fat`: the fat
/// stack's left singular vectors) and of the tall stack (`v`, `s_tall`),
/// all `n` of them. They depend on the kernel, the order, the radii, the
/// half-width and the vectors only, not on the tolerance or the working
/// type, so one computation serves every truncation
/// ([`SvdBasesLayout`], cached apart from the sets).
pub(super) struct SetBases {
    /// Surface points `n`.
    pub(super) n: usize,
    /// `U` (`n x n`, column-major).
    pub(super) u: Vec<f64>,
    /// Singular values of the fat stack, non-increasing.
    pub(super) s_fat: Vec<f64>,
    /// `V` (`n x n`, column-major).
    pub(super) v: Vec<f64>,
    /// Singular values of the tall stack, non-increasing.
    pub(super) s_tall: Vec<f64>,
}

/// What a cached [`SetBases`] holds: `U`, `V` (`n x n` each), then the
/// `n` singular values of the fat and of the tall stack.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct SvdBasesLayout {
    /// Surface points `n`.
    pub(super) n: usize,
}

impl StoreLayout for SvdBasesLayout {
    fn n_values(&self) -> Result<usize, String> {
        Ok(2 * self.n * self.n + 2 * self.n)
    }
}

impl SetBases {
    /// As a cache payload: `[U, V, s_fat, s_tall]`.
    pub(super) fn into_store(self) -> FlatStore<SvdBasesLayout, f64> {
        let mut data = self.u;
        data.extend(self.v);
        data.extend(self.s_fat);
        data.extend(self.s_tall);
        FlatStore {
            layout: SvdBasesLayout { n: self.n },
            data,
        }
    }

    /// Back from a cache payload (its length already checked).
    pub(super) fn from_store(store: FlatStore<SvdBasesLayout, f64>) -> Self {
        let n = store.layout.n;
        let mut data = store.data;
        let s_tall = data.split_off(2 * n * n + n);
        let s_fat = data.split_off(2 * n * n);
        let v = data.split_off(n * n);
        SetBases {
            n,
            u: data,
            s_fat,
            v,
            s_tall,
        }
    }
}

/// Step 1 for one set at half-width `h`: the two-level TSQR of both stacks
/// and the SVDs of their `R` factors.
pub(super) fn set_bases<K: Kernel>(
    kernel: &K,
    params: &OperatorParams,
    h: f64,
    used: &[usize],
    units: &Units<'_>,
) -> Result<SetBases, FieldError> {
    let p = params.order;
    let n = expansion_len(kernel, p);
    let all = transfer_vectors();
    let vectors: Vec<[i32; 3]> = used.iter().map(|&v| all[v]).collect();
    let stop = || units.cancelled();
    // First TSQR level: R factors of blocks of the tall stack [K_v] and of
    // the transposed fat stack [K_v^T].
    type RPair = Result<(Mat<f64>, Mat<f64>), FieldError>;
    let blocks: Vec<RPair> = vectors
        .par_chunks(TSQR_BLOCK)
        .map(|vs| {
            units.check()?;
            let rows = vs.len() * n;
            let mut tall = vec![0.0f64; rows * n];
            let mut fat_t = vec![0.0f64; rows * n];
            for (b, &v) in vs.iter().enumerate() {
                let k = m2l_matrix(kernel, p, &params.radii, h, v)?;
                for j in 0..n {
                    for i in 0..n {
                        tall[j * rows + b * n + i] = k[(i, j)];
                        fat_t[j * rows + b * n + i] = k[(j, i)];
                    }
                }
            }
            let rt = householder_r_until(&mut tall, rows, n, Par::Seq, &stop);
            units.check()?;
            let rf = householder_r_until(&mut fat_t, rows, n, Par::Seq, &stop);
            units.add(TSQR_UNITS * vs.len() as u64)?;
            Ok((rt, rf))
        })
        .collect();
    let mut r_tall = Vec::with_capacity(blocks.len());
    let mut r_fat = Vec::with_capacity(blocks.len());
    for b in blocks {
        let (t, f) = b?;
        r_tall.push(t);
        r_fat.push(f);
    }
    let reduce = |rs: &[Mat<f64>]| -> Mat<f64> {
        let rows = rs.len() * n;
        let mut stacked = vec![0.0f64; rows * n];
        for (b, r) in rs.iter().enumerate() {
            for j in 0..n {
                for i in 0..=j {
                    stacked[j * rows + b * n + i] = r[(i, j)];
                }
            }
        }
        householder_r_until(&mut stacked, rows, n, nested_par(), &stop)
    };
    let rt = reduce(&r_tall);
    units.check()?;
    let rf = reduce(&r_fat);
    units.check()?;
    // Right singular vectors of R_tall are V; of R_fat (from the fat
    // stack's transpose) they are the left singular vectors U of the fat
    // stack.
    let st = svd(rt.as_ref(), "the tall M2L stack")?;
    let sf = svd(rf.as_ref(), "the fat M2L stack")?;
    units.add(BASES_UNITS * vectors.len() as u64)?;
    Ok(SetBases {
        n,
        u: col_major(sf.v.as_ref()),
        s_fat: sf.s,
        v: col_major(st.v.as_ref()),
        s_tall: st.s,
    })
}

/// Progress units of step 1 for `m` vectors (added at once when the bases
/// come from the cache).
pub(super) fn bases_units(m: usize) -> u64 {
    m as u64 * (TSQR_UNITS + BASES_UNITS)
}

/// Steps 2 and 3 for one set at half-width `h` from its `bases`: returns
/// the summary and `[U_k, V_k^T, C_1 .. C_316]` (column-major, `f64`).
#[allow(clippy::too_many_arguments)]
pub(super) fn compress_with<K: Kernel>(
    kernel: &K,
    params: &OperatorParams,
    h: f64,
    used: &[usize],
    bases: &SetBases,
    rank: Option<usize>,
    tolerance: f64,
    units: &Units<'_>,
) -> Result<(SvdSetInfo, Vec<f64>), FieldError> {
    let p = params.order;
    let n = bases.n;
    let all = transfer_vectors();
    let vectors: Vec<[i32; 3]> = used.iter().map(|&v| all[v]).collect();
    let (sf_s, st_s) = (&bases.s_fat, &bases.s_tall);
    let count = |s: &[f64]| {
        s.iter()
            .take_while(|&&x| x > tolerance * s[0])
            .count()
            .max(1)
    };
    let k = match rank {
        Some(r) => r.min(n),
        None => count(sf_s).max(count(st_s)),
    };
    let dropped = |s: &[f64]| {
        if k < s.len() && s[0] > 0.0 {
            s[k] / s[0]
        } else {
            0.0
        }
    };
    let uk = MatRef::from_column_major_slice(&bases.u[..n * k], n, k);
    let vk = MatRef::from_column_major_slice(&bases.v[..n * k], n, k);
    // C_v = U_k^T K_v V_k.
    let cs: Vec<Result<Vec<f64>, FieldError>> = vectors
        .par_iter()
        .map(|&v| {
            units.check()?;
            let kv = m2l_matrix(kernel, p, &params.radii, h, v)?;
            let c = project(uk, kv.as_ref(), vk);
            units.add(1)?;
            Ok(c)
        })
        .collect();
    let cs = cs.into_iter().collect::<Result<Vec<_>, _>>()?;
    // Factor each C_v at its own rank (only when the rank was chosen by
    // tolerance: a fixed rank is kept as asked).
    let factored: Vec<Option<(usize, Vec<f64>)>> = if rank.is_some() {
        vec![None; cs.len()]
    } else {
        let svds = cs
            .par_iter()
            .map(|c| {
                units.check()?;
                let d = svd(
                    MatRef::from_column_major_slice(c, k, k),
                    "a compressed M2L operator",
                )?;
                units.add(1)?;
                Ok(d)
            })
            .collect::<Result<Vec<_>, _>>()?;
        let s_max = svds.iter().map(|d| d.s[0]).fold(0.0, f64::max);
        let cutoff = RECOMPRESSION_FACTOR * tolerance * s_max;
        svds.iter()
            .map(|d| {
                let r = d.s.iter().take_while(|&&x| x > cutoff).count().max(1);
                (2 * r < k).then(|| {
                    let mut f = Vec::with_capacity(2 * k * r);
                    for j in 0..r {
                        f.extend((0..k).map(|i| d.u[(i, j)] * d.s[j]));
                    }
                    for i in 0..k {
                        f.extend((0..r).map(|j| d.v[(i, j)]));
                    }
                    (r, f)
                })
            })
            .collect()
    };
    let info = SvdSetInfo {
        rank: k,
        dropped_fat: dropped(sf_s),
        dropped_tall: dropped(st_s),
        vector_ranks: {
            let mut ranks = vec![0u32; N_TRANSFER_VECTORS];
            for (f, &v) in factored.iter().zip(used) {
                ranks[v] = f.as_ref().map_or(k, |(r, _)| *r) as u32;
            }
            ranks
        },
    };
    let mut out = Vec::with_capacity(info.len(n));
    out.extend(col_major(uk));
    out.extend(col_major(vk.transpose()));
    for (c, f) in cs.iter().zip(&factored) {
        match f {
            Some((_, f)) => out.extend_from_slice(f),
            None => out.extend_from_slice(c),
        }
    }
    debug_assert_eq!(out.len(), info.len(n));
    Ok((info, out))
}

/// `U^T K V` (column-major `k x k`).
fn project(u: MatRef<'_, f64>, kv: MatRef<'_, f64>, v: MatRef<'_, f64>) -> Vec<f64> {
    let kvv = product(kv, v, 1.0, Par::Seq);
    col_major(product(u.transpose(), kvv.as_ref(), 1.0, Par::Seq).as_ref())
}
