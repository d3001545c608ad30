//! [`SvdM2l`]: Fong–Darve compression of all 316 M2L operators with one
//! pair of bases.

use faer::{Accum, Mat, MatRef, Par};
use ferrofmm_kernels::{Kernel, Precision, Real};
use rayon::prelude::*;

use super::{
    FIRST_M2L_LEVEL, M2lScheme, check_lengths, for_each_chunk, for_each_vector_group, m2l_matrix,
    planned_sets,
};
use crate::cache::{CacheKey, CacheStatus, FlatStore, StoreLayout, load_or_compute};
use crate::estimate::seconds_for;
use crate::levels::LevelMap;
use crate::linalg::{col_major, householder_r_until, round_to, svd};
use crate::monitor::Units;
use crate::threads::{effective_threads, nested_par};
use crate::{
    FieldError, M2lInteractions, M2lUsage, N_TRANSFER_VECTORS, OperatorParams, PrecomputeEstimate,
    Update, expansion_len, gemm, gemm_scaled, transfer_vectors,
};

/// Configuration of [`SvdM2l`].
///
/// The rank `k` is `rank` when given (clamped to `n`); otherwise the
/// smallest `k` with `sigma_k / sigma_0 <= tolerance` for both stacked
/// matrices (0-based singular values, so `k` values are kept). A
/// `tolerance <= 0` (the default) selects [`default_svd_tolerance`] for the
/// float type and order.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SvdConfig {
    /// Fixed rank, overriding the tolerance.
    pub rank: Option<usize>,
    /// Relative singular-value cutoff; `<= 0` means automatic.
    pub tolerance: f64,
}

/// Default compression tolerance for a float type and order:
/// `tol(p) = max(10^-(0.9 p + 0.7), floor)` with floor `1e-13` (`f64`) or
/// `F32_FLOOR` (`f32`, whose FMM error floor is a few `1e-7` on zero-mean
/// charges).
///
/// Chosen so that compression costs almost nothing in accuracy: on
/// zero-mean charges (uniform in `[-0.5, 0.5)`; all-positive charges hide
/// most of the M2L error behind a smooth mean) the dropped singular values
/// add about `0.9 tol` to the relative potential error, against the dense
/// scheme's `E_p` of `1.3e-3` (p = 3) falling about 8x per order. With the
/// offset 0.7 the measured error is at most 1.1x the dense scheme's at every
/// order 3..=12, on seven geometries, for the potential and the gradient, in
/// `f32` and `f64` (`examples/error_model.rs`, `docs/algorithms.md`; the
/// test `svd_truncation` in `ferrofmm-fmm` holds it to 1.3x). The rank, and
/// so the M2L work, still drops well below `n` (p = 6: `k = 120` of 152).
///
/// ```
/// use ferrofmm_field::default_svd_tolerance;
/// use ferrofmm_kernels::Precision;
/// assert!(default_svd_tolerance(Precision::F64, 10) < default_svd_tolerance(Precision::F64, 4));
/// assert_eq!(default_svd_tolerance(Precision::F32, 10), 1e-7);
/// ```
pub fn default_svd_tolerance(precision: Precision, order: usize) -> f64 {
    let floor = match precision {
        Precision::F64 => 1e-13,
        Precision::F32 => F32_FLOOR,
    };
    10f64
        .powf(-(0.9 * order as f64 + DEFAULT_TOLERANCE_OFFSET))
        .max(floor)
}

/// The offset `c` of the default tolerance `10^-(0.9 p + c)`.
const DEFAULT_TOLERANCE_OFFSET: f64 = 0.7;

/// Tightest default tolerance in `f32`.
const F32_FLOOR: f64 = 1e-7;

/// Fong–Darve SVD-compressed M2L.
///
/// Precomputation per operator set (half-width `h`): with `K_v` the 316
/// kernel matrices (`n x n`, downward check <- upward equivalent), take the
/// left singular vectors `U` of the fat stack `[K_1 ... K_316]` and the
/// right singular vectors `V` of the tall stack `[K_1; ...; K_316]`, keep
/// `k` of each, and store `C_v = U_k^T K_v V_k` (`k x k`). Both SVDs are
/// computed from the `R` factor of a parallel TSQR of the stack (each of
/// 20 blocks of 16 matrices QR-factorised, then the stacked `R`s), so the
/// stack itself is never held in memory; all in `f64`.
///
/// Each `C_v` is then compressed again on its own (when the rank comes
/// from the tolerance): `C_v ≈ A_v B_v^T` with `A_v = U_r S_r` (`k x r_v`)
/// and `B_v = V_r` (`k x r_v`) from the SVD of `C_v`, keeping the singular
/// values above `0.3 tol s_max` (`s_max` the largest over all `C_v`). The
/// shared bases must serve the nearest transfer vectors; a far vector needs
/// far fewer directions (p = 6: `k = 94`, `r_v` 9 to 39, mean 18). A `C_v`
/// whose `r_v >= k / 2` is kept whole.
///
/// Application: compress all multipoles once (`V_k^T M`, one GEMM per
/// column block), then per target chunk and transfer vector one GEMM with
/// `C_v` (or two, `B_v^T` then `A_v`) over all pairs sharing it,
/// accumulated in the compressed check potentials of the chunk's targets,
/// which are expanded once (`U_k *`, one GEMM per chunk) and added to
/// `check`. Flops: `4 k r_v` (or `2 k^2`) per pair plus `2 n k` per source
/// and per target box, against `2 n^2` per pair for
/// [`DenseM2l`](crate::DenseM2l).
///
/// The approximation error of `K_v` is about `sigma_k / sigma_0` of the
/// stack (relative to its largest singular value).
///
/// ```
/// use ferrofmm_field::{M2lInteractions, M2lScheme, OperatorParams, SvdConfig, SvdM2l, n_surface_points};
/// use ferrofmm_kernels::Laplace3d;
/// let config = SvdConfig { rank: None, tolerance: 1e-4 };
/// let m2l = SvdM2l::<f64>::precompute(&Laplace3d, &OperatorParams::new(4), &config, 1.0, 3).unwrap();
/// let n = n_surface_points(4);
/// assert!(m2l.rank() < n);
/// let inter = M2lInteractions::new(1, 1, &[(0, 0, [0, -2, 3])]);
/// let mut check = vec![0.0; n];
/// m2l.apply(3, &inter, &vec![1.0; n], &mut check);
/// assert!(check.iter().all(|&x| x > 0.0));
/// ```
pub struct SvdM2l<T: Real> {
    n: usize,
    levels: LevelMap,
    store: FlatStore<SvdLayout, T>,
    /// Per set: start of the set in the store and the 316 operators.
    layout: Vec<(usize, Vec<VectorOp>)>,
    tolerance: f64,
    cache_status: CacheStatus,
}

/// Per-vector truncation of `C_v` relative to the set's tolerance: singular
/// values of `C_v` below `RECOMPRESSION_FACTOR * tolerance * s_max` (with
/// `s_max` the largest singular value of all 316 `C_v`) are dropped. The
/// per-vector ranks are 4.7-5.6x below `k` (p = 6: mean 18 of 94), and
/// dropping a third of the tolerance keeps the FMM error within a few
/// percent of the unfactored scheme's (`docs/algorithms.md`).
const RECOMPRESSION_FACTOR: f64 = 0.3;

/// Per-set compression summary.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct SvdSetInfo {
    rank: usize,
    /// `sigma_k / sigma_0` of the fat and tall stacks (first dropped value,
    /// 0 when nothing is dropped).
    dropped_fat: f64,
    dropped_tall: f64,
    /// Rank `r_v` of each `C_v`; `r_v == rank` means `C_v` is stored whole.
    vector_ranks: Vec<u32>,
}

impl SvdSetInfo {
    /// Values stored for transfer vector `v`: `k^2` whole, `2 k r_v`
    /// factored.
    fn vector_len(&self, v: usize) -> usize {
        let (k, r) = (self.rank, self.vector_ranks[v] as usize);
        if r == k { k * k } else { 2 * k * r }
    }

    /// Values of the whole set: `U_k`, `V_k^T` and the 316 `C_v`.
    fn len(&self, n: usize) -> usize {
        2 * n * self.rank
            + (0..N_TRANSFER_VECTORS)
                .map(|v| self.vector_len(v))
                .sum::<usize>()
    }

    /// Flops of one pair at transfer vector `v`.
    fn pair_flops(&self, v: usize) -> f64 {
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
struct VectorOp {
    offset: usize,
    rank: usize,
}

/// What a cached SVD scheme holds, set by set: `U_k` (`n x k`), `V_k^T`
/// (`k x n`), then per transfer vector either `C_v` (`k x k`) or its
/// factors `A_v` (`k x r_v`) and `B_v^T` (`r_v x k`), all column-major.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct SvdLayout {
    /// Surface points `n`.
    n: usize,
    /// Ranks and truncation estimates of each set.
    sets: Vec<SvdSetInfo>,
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

impl<T: Real> SvdM2l<T> {
    /// Compression rank `k` (the largest over operator sets; a homogeneous
    /// kernel has one set).
    pub fn rank(&self) -> usize {
        self.store
            .layout
            .sets
            .iter()
            .map(|s| s.rank)
            .max()
            .unwrap_or(0)
    }

    /// Compression rank used at `level`.
    pub fn rank_at(&self, level: u32) -> usize {
        self.store.layout.sets[self.levels.lookup(level, 1.0).0].rank
    }

    /// Tolerance the rank was chosen with (resolved default, or the
    /// configured one; meaningless when a rank was given).
    pub fn tolerance(&self) -> f64 {
        self.tolerance
    }

    /// Largest `sigma_k / sigma_0` over both stacks and all sets: an
    /// estimate of the relative compression error.
    pub fn truncation_estimate(&self) -> f64 {
        self.store
            .layout
            .sets
            .iter()
            .map(|s| s.dropped_fat.max(s.dropped_tall))
            .fold(0.0, f64::max)
    }

    /// Mean rank `r_v` of the 316 per-vector operators `C_v` (largest over
    /// sets): the M2L work per pair is `4 k r_v` for a factored `C_v`,
    /// `2 k^2` for one stored whole.
    pub fn mean_vector_rank(&self) -> f64 {
        self.store
            .layout
            .sets
            .iter()
            .map(|s| {
                let used = s.vector_ranks.iter().filter(|&&r| r > 0).count().max(1);
                s.vector_ranks.iter().map(|&r| r as f64).sum::<f64>() / used as f64
            })
            .fold(0.0, f64::max)
    }

    /// Build the operators [`planned_sets`] gives for `usage`.
    fn build<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        config: &SvdConfig,
        domain_width: f64,
        depth: u32,
        usage: &M2lUsage,
    ) -> Result<Self, FieldError> {
        params.validate()?;
        if !config.tolerance.is_finite() || config.tolerance >= 1.0 {
            return Err(FieldError::InvalidParams(format!(
                "SVD tolerance must be finite and < 1, got {}",
                config.tolerance
            )));
        }
        if config.rank == Some(0) {
            return Err(FieldError::InvalidParams(
                "SVD rank must be positive".into(),
            ));
        }
        let levels = LevelMap::new(kernel.homogeneity(), domain_width, depth, FIRST_M2L_LEVEL)?;
        let n = expansion_len(kernel, params.order);
        let tolerance = if config.tolerance > 0.0 {
            config.tolerance
        } else {
            default_svd_tolerance(T::PRECISION, params.order)
        };
        let plan_sets = planned_sets(levels.homogeneity.is_some(), params, depth, usage);
        let full = plan_sets.iter().all(|s| s.len() == N_TRANSFER_VECTORS);
        let monitor = &params.monitor;
        monitor.check()?;
        let total: u64 = plan_sets
            .iter()
            .map(|vs| set_units(vs.len(), config.rank.is_none()))
            .sum();
        let units = monitor.units(total);
        let compute = || -> Result<FlatStore<SvdLayout, T>, FieldError> {
            let mut sets = Vec::new();
            let mut data = Vec::new();
            for (set, vs) in plan_sets.iter().enumerate() {
                if vs.is_empty() {
                    sets.push(SvdSetInfo {
                        rank: 0,
                        dropped_fat: 0.0,
                        dropped_tall: 0.0,
                        vector_ranks: vec![0; N_TRANSFER_VECTORS],
                    });
                    continue;
                }
                let h = levels.set_half_width(set);
                let (info, values) =
                    compress_set(kernel, params, h, vs, config.rank, tolerance, &units)?;
                sets.push(info);
                data.extend(round_to::<T>(&values));
            }
            Ok(FlatStore {
                layout: SvdLayout { n, sets },
                data,
            })
        };
        let (store, cache_status) = if full {
            let mut key =
                CacheKey::new::<K, T>("m2l-svd", kernel, params.order, params.radii.to_array())
                    .for_domain(domain_width, depth);
            key.scheme_config = format!(
                "rank={:?};tolerance={:?};recompression={RECOMPRESSION_FACTOR:?}",
                config.rank.map(|r| r.min(n)),
                tolerance
            );
            let accept = |l: &SvdLayout| {
                if l.n == n && l.sets.len() == levels.n_sets() {
                    Ok(())
                } else {
                    Err("layout disagrees with the parameters".to_string())
                }
            };
            load_or_compute(params.cache_dir.as_deref(), &key, accept, compute)?
        } else {
            (compute()?, CacheStatus::Disabled)
        };
        let layout = Self::layout_of(&store);
        Ok(SvdM2l {
            n,
            levels,
            store,
            layout,
            tolerance,
            cache_status,
        })
    }

    /// Number of transfer vectors with an operator, over all sets.
    pub fn n_vectors(&self) -> usize {
        self.store
            .layout
            .sets
            .iter()
            .map(|s| s.vector_ranks.iter().filter(|&&r| r > 0).count())
            .sum()
    }

    /// Start of each set in the store and where its 316 operators lie.
    fn layout_of(store: &FlatStore<SvdLayout, T>) -> Vec<(usize, Vec<VectorOp>)> {
        let mut start = 0;
        store
            .layout
            .sets
            .iter()
            .map(|s| {
                let mut offset = start + 2 * store.layout.n * s.rank;
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
                start += s.len(store.layout.n);
                (set_start, ops)
            })
            .collect()
    }
}

impl<T: Real> M2lScheme<T> for SvdM2l<T> {
    type Config = SvdConfig;
    const COST_SHAPE: super::M2lCostShape = super::M2lCostShape::Compressed;

    fn name(&self) -> &'static str {
        "svd"
    }

    fn precompute_for<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        config: &SvdConfig,
        domain_width: f64,
        depth: u32,
        usage: &M2lUsage,
    ) -> Result<Self, FieldError> {
        Self::build(kernel, params, config, domain_width, depth, usage)
    }

    /// Per set of `m` vectors (`n` points per surface, `t` threads): `t`
    /// TSQR blocks in flight (two `16 n x n` matrices each), `2 m / 16` `R`
    /// factors and their stack, and the `m` cores `C_v` with, when the rank
    /// comes from the tolerance, their SVDs (`3 n^2` values each at most);
    /// flops: two QRs of `m n x n` (`8 m n^3`) plus the projections and
    /// SVDs of the cores (about `30 m n^3` at full rank).
    fn estimate<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        config: &SvdConfig,
        depth: u32,
        usage: &M2lUsage,
    ) -> PrecomputeEstimate {
        let sets = planned_sets(kernel.homogeneity().is_some(), params, depth, usage);
        let n = expansion_len(kernel, params.order) as f64;
        let k = config.rank.map_or(n, |r| (r as f64).min(n));
        let threads = effective_threads() as f64;
        let per_core = if config.rank.is_some() { 1.0 } else { 4.0 };
        let mut peak: f64 = 0.0;
        let mut stored = 0.0;
        let mut flops = 0.0;
        let mut matrices = 0;
        for vs in &sets {
            let m = vs.len() as f64;
            if vs.is_empty() {
                continue;
            }
            matrices += vs.len();
            let blocks = (m / TSQR_BLOCK as f64).ceil();
            let tsqr = threads.min(blocks) * 2.0 * TSQR_BLOCK as f64 * n * n + 2.0 * blocks * n * n;
            let cores = m * per_core * k * k;
            peak = peak.max(stored * 8.0 + (tsqr.max(cores) + 2.0 * n * k) * 8.0);
            stored += 2.0 * n * k + m * k * k;
            flops += 8.0 * m * n * n * n
                + m * (2.0 * n * n * k + 2.0 * n * k * k)
                + if config.rank.is_some() {
                    0.0
                } else {
                    20.0 * m * k * k * k
                };
        }
        let size = std::mem::size_of::<T>() as f64;
        let peak_bytes = peak.max(stored * size);
        PrecomputeEstimate {
            matrices,
            peak_bytes: peak_bytes as u64,
            flops,
            seconds: seconds_for(flops),
        }
    }

    fn apply(&self, level: u32, interactions: &M2lInteractions, multipoles: &[T], check: &mut [T]) {
        let n = self.n;
        check_lengths(n, interactions, multipoles, check);
        if interactions.is_empty() {
            return;
        }
        let (set, scale) = self.levels.lookup(level, 1.0);
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
        for_each_chunk(interactions, n, check, |chunk, out| {
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

    fn memory_bytes(&self) -> usize {
        self.store.data.len() * std::mem::size_of::<T>()
    }

    fn flops(&self, interactions: &M2lInteractions) -> f64 {
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

    fn cache_status(&self) -> CacheStatus {
        self.cache_status.clone()
    }
}

/// Matrices per TSQR block.
const TSQR_BLOCK: usize = 16;

/// Progress units per transfer vector of the TSQR (two QRs of its rows),
/// of the bases (its share of the two SVDs), of its projection and of its
/// own SVD, so that units are roughly proportional to time.
const TSQR_UNITS: u64 = 6;
const BASES_UNITS: u64 = 1;

/// Progress units of a set of `m` vectors.
fn set_units(m: usize, refactor: bool) -> u64 {
    if m == 0 {
        return 0;
    }
    m as u64 * (TSQR_UNITS + BASES_UNITS + 1 + u64::from(refactor))
}

/// Compress the 316 operators of one set at half-width `h`: returns the
/// summary and `[U_k, V_k^T, C_1 .. C_316]` (column-major, `f64`).
fn compress_set<K: Kernel>(
    kernel: &K,
    params: &OperatorParams,
    h: f64,
    used: &[usize],
    rank: Option<usize>,
    tolerance: f64,
    units: &Units<'_>,
) -> Result<(SvdSetInfo, Vec<f64>), FieldError> {
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
    let count = |s: &[f64]| {
        s.iter()
            .take_while(|&&x| x > tolerance * s[0])
            .count()
            .max(1)
    };
    let k = match rank {
        Some(r) => r.min(n),
        None => count(&sf.s).max(count(&st.s)),
    };
    let dropped = |s: &[f64]| {
        if k < s.len() && s[0] > 0.0 {
            s[k] / s[0]
        } else {
            0.0
        }
    };
    let uk = sf.v.as_ref().subcols(0, k);
    let vk = st.v.as_ref().subcols(0, k);
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
        dropped_fat: dropped(&sf.s),
        dropped_tall: dropped(&st.s),
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
    let mut kvv = Mat::<f64>::zeros(kv.nrows(), v.ncols());
    faer::linalg::matmul::matmul(kvv.as_mut(), Accum::Replace, kv, v, 1.0, Par::Seq);
    let mut c = Mat::<f64>::zeros(u.ncols(), v.ncols());
    faer::linalg::matmul::matmul(
        c.as_mut(),
        Accum::Replace,
        u.transpose(),
        kvv.as_ref(),
        1.0,
        Par::Seq,
    );
    col_major(c.as_ref())
}
