//! [`SvdM2l`]: Fong–Darve compression of all 316 M2L operators with one
//! pair of bases.
//!
//! The modules: `compress` (the bases, the cores and their recompression,
//! in `f64`), `store` (what a set holds and where, the cache layout),
//! `apply` (compress, translate, expand); this one holds the configuration,
//! the scheme and its precomputation (plan, cache, estimate).

mod apply;
mod compress;
mod store;

use ferrofmm_kernels::{Kernel, Precision, Real};

use super::{M2lProgress, M2lScheme, Plan, planned_sets};
use crate::cache::{CacheKey, CacheStatus, FlatStore, StoreLayout};
use crate::estimate::seconds_for;
use crate::levels::LevelMap;
use crate::linalg::round_to;
use crate::threads::effective_threads;
use crate::{
    FieldError, M2lInteractions, M2lUsage, N_TRANSFER_VECTORS, OperatorParams, PrecomputeEstimate,
    expansion_len,
};
use compress::{
    RECOMPRESSION_FACTOR, SetBases, SvdBasesLayout, TSQR_BLOCK, bases_units, compress_with,
    set_bases, set_units,
};
use store::{SvdLayout, SvdSetInfo, VectorOp};

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

    /// Number of transfer vectors with an operator, over all sets.
    pub fn n_vectors(&self) -> usize {
        self.store
            .layout
            .sets
            .iter()
            .map(|s| s.vector_ranks.iter().filter(|&&r| r > 0).count())
            .sum()
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
        let plan = Plan::new(kernel, params, domain_width, depth, usage)?;
        let (levels, plan_sets) = (&plan.levels, &plan.sets);
        let n = expansion_len(kernel, params.order);
        let tolerance = if config.tolerance > 0.0 {
            config.tolerance
        } else {
            default_svd_tolerance(T::PRECISION, params.order)
        };
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
                let bases = set_bases_cached(
                    &plan,
                    kernel,
                    params,
                    domain_width,
                    depth,
                    set,
                    h,
                    vs,
                    &units,
                )?;
                let (info, values) = compress_with(
                    kernel,
                    params,
                    h,
                    vs,
                    &bases,
                    config.rank,
                    tolerance,
                    &units,
                )?;
                sets.push(info);
                data.extend(round_to::<T>(&values));
            }
            Ok(FlatStore {
                layout: SvdLayout { n, sets },
                data,
            })
        };
        let key = || {
            let mut key =
                CacheKey::new::<K, T>("m2l-svd", kernel, params.order, params.radii.to_array())
                    .for_domain(domain_width, depth);
            key.scheme_config = format!(
                "rank={:?};tolerance={:?};recompression={RECOMPRESSION_FACTOR:?}",
                config.rank.map(|r| r.min(n)),
                tolerance
            );
            key
        };
        let accept = |l: &SvdLayout| {
            if l.n == n && l.sets.len() == levels.n_sets() {
                Ok(())
            } else {
                Err("layout disagrees with the parameters".to_string())
            }
        };
        let (store, cache_status) = plan.load_or_compute(params, key, accept, compute)?;
        let layout = store.layout.operators();
        Ok(SvdM2l {
            n,
            levels: plan.levels,
            store,
            layout,
            tolerance,
            cache_status,
        })
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
        self.apply_compressed(level, interactions, multipoles, check, M2lProgress::none());
    }

    /// Reports each chunk of target columns done (its pairs).
    fn apply_with_progress(
        &self,
        level: u32,
        interactions: &M2lInteractions,
        multipoles: &[T],
        check: &mut [T],
        progress: M2lProgress<'_>,
    ) {
        self.apply_compressed(level, interactions, multipoles, check, progress);
    }

    fn memory_bytes(&self) -> usize {
        self.store.data.len() * std::mem::size_of::<T>()
    }

    /// Per thread, one chunk's work (`k` the largest rank of the operator
    /// sets): its compressed source columns (at most eight per target
    /// column of a uniform level, or every source column), its compressed
    /// check potentials and one group's products (at most the chunk's
    /// columns each), and the chunk's pairs when they are made from the
    /// sibling blocks (8 bytes each, at most 189 per target column).
    fn apply_scratch_bytes(&self, interactions: &M2lInteractions) -> usize {
        let k = self
            .store
            .layout
            .sets
            .iter()
            .map(|s| s.rank)
            .max()
            .unwrap_or(0);
        let cols = interactions.chunk_size().min(interactions.n_target_cols());
        let sources = (8 * cols).min(interactions.n_source_cols());
        let values = k * (sources + 4 * cols);
        let pairs = if interactions.holds_pair_lists() {
            0
        } else {
            8 * 189 * cols
        };
        let per_thread = values * std::mem::size_of::<T>() + pairs;
        rayon::current_num_threads().min(interactions.n_chunks().max(1)) * per_thread
    }

    /// `false`: each chunk's pairs are read on their own
    /// ([`for_each_chunk`](crate::plumbing::for_each_chunk)), so the FMM
    /// keeps only the sibling blocks.
    fn reads_pair_lists(&self) -> bool {
        false
    }

    fn flops(&self, interactions: &M2lInteractions) -> f64 {
        self.apply_flops(interactions)
    }

    fn cache_status(&self) -> CacheStatus {
        self.cache_status.clone()
    }
}

/// The bases of set `set` (half-width `h`, vectors `vs`): from the cache
/// when the plan may use it (an entry of their own, `m2l-svd-bases`, in
/// `f64` and without the tolerance, so that every truncation and both
/// working types share one computation), else computed.
#[allow(clippy::too_many_arguments)]
fn set_bases_cached<K: Kernel>(
    plan: &Plan,
    kernel: &K,
    params: &OperatorParams,
    domain_width: f64,
    depth: u32,
    set: usize,
    h: f64,
    vs: &[usize],
    units: &crate::monitor::Units<'_>,
) -> Result<SetBases, FieldError> {
    let n = expansion_len(kernel, params.order);
    let key = || {
        let mut key = CacheKey::new::<K, f64>(
            "m2l-svd-bases",
            kernel,
            params.order,
            params.radii.to_array(),
        )
        .for_domain(domain_width, depth);
        key.scheme_config = format!("set={set};half_width={h:?};tsqr_block={TSQR_BLOCK}");
        key
    };
    let (store, status) = plan.load_or_compute::<f64, FlatStore<SvdBasesLayout, f64>>(
        params,
        key,
        SvdBasesLayout { n }.accept(),
        || Ok(set_bases(kernel, params, h, vs, units)?.into_store()),
    )?;
    if status.is_hit() {
        units.add(bases_units(vs.len()))?;
    }
    Ok(SetBases::from_store(store))
}
