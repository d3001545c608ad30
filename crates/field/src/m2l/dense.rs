//! [`DenseM2l`]: one full `n x n` matrix per transfer vector (the reference).

use ferrofmm_kernels::{Kernel, Real};
use rayon::prelude::*;

use super::{
    FIRST_M2L_LEVEL, M2lProgress, M2lScheme, Plan, for_each_chunk_with_progress,
    for_each_vector_group, level_set, m2l_matrix,
};
use crate::cache::{CacheKey, CacheStatus, FlatStore, StoreLayout};
use crate::levels::LevelMap;
use crate::linalg::col_major;
use crate::{
    FieldError, M2lInteractions, M2lUsage, N_TRANSFER_VECTORS, OperatorParams, Update, gemm_scaled,
    transfer_vectors,
};

/// Configuration of [`DenseM2l`] (nothing to configure).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DenseConfig;

/// The reference M2L scheme: the 316 kernel matrices `K_v` (`n x n`) per
/// operator set, stored in the working type.
///
/// Application, per target chunk (one rayon task) and per transfer vector
/// `v` present in it: gather the source multipoles of all pairs with `v`
/// into an `n x m` block, one GEMM `K_v (n x n) * block`, scatter-add the
/// result into the targets' check potentials. `2 n^2` flops per pair.
///
/// Memory: `316 n^2` values per set (`p = 6`: 7.3 M values, 58 MB in
/// `f64`; `p = 10`: 75 M values, 602 MB in `f64`).
///
/// ```
/// use ferrofmm_field::{DenseConfig, DenseM2l, M2lInteractions, M2lScheme, OperatorParams};
/// use ferrofmm_kernels::Laplace3d;
/// let m2l = DenseM2l::<f64>::precompute(&Laplace3d, &OperatorParams::new(3), &DenseConfig, 1.0, 3).unwrap();
/// let n = ferrofmm_field::n_surface_points(3);
/// let inter = M2lInteractions::new(1, 1, &[(0, 0, [2, 0, 0])]);
/// let mut check = vec![0.0; n];
/// m2l.apply(3, &inter, &vec![1.0; n], &mut check);
/// assert!(check.iter().all(|&x| x > 0.0));
/// ```
pub struct DenseM2l<T: Real> {
    n: usize,
    levels: LevelMap,
    store: FlatStore<DenseLayout, T>,
    /// Per set, the storage slot of each transfer vector's matrix
    /// ([`NOT_COMPUTED`] when not precomputed).
    slots: Vec<Vec<u32>>,
    cache_status: CacheStatus,
}

/// What a cached dense scheme holds: `sets x 316` column-major `n x n`
/// matrices `K_v`, set by set, in transfer-vector order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
struct DenseLayout {
    /// Surface points `n`.
    n: usize,
    /// Operator sets.
    sets: usize,
}

impl StoreLayout for DenseLayout {
    fn n_values(&self) -> Result<usize, String> {
        Ok(self.sets * N_TRANSFER_VECTORS * self.n * self.n)
    }
}

impl<T: Real> DenseM2l<T> {
    /// `K_v` of operator set `set` (column-major `n x n`).
    ///
    /// # Panics
    /// When `v` was not precomputed for `set` (see
    /// [`M2lScheme::precompute_for`]).
    fn matrix(&self, set: usize, v: usize) -> &[T] {
        let nn = self.n * self.n;
        let slot = self.slots[set][v];
        assert!(
            slot != NOT_COMPUTED,
            "M2L operator of transfer vector {v} (set {set}) was not precomputed: \
             the interactions differ from the usage given to precompute_for"
        );
        let start = slot as usize * nn;
        &self.store.data[start..start + nn]
    }

    /// Number of `K_v` matrices held.
    pub fn n_matrices(&self) -> usize {
        self.slots
            .iter()
            .flatten()
            .filter(|&&s| s != NOT_COMPUTED)
            .count()
    }

    /// Whether `K_v` of transfer vector index `vector` is held for `level`.
    pub fn has_vector(&self, level: u32, vector: usize) -> bool {
        if self.slots.is_empty() || level < self.levels.first_level.min(FIRST_M2L_LEVEL) {
            return false;
        }
        let set = match self.levels.homogeneity {
            Some(_) => 0,
            None if level >= self.levels.first_level && level <= self.levels.depth => {
                (level - self.levels.first_level) as usize
            }
            None => return false,
        };
        self.slots
            .get(set)
            .and_then(|s| s.get(vector))
            .is_some_and(|&s| s != NOT_COMPUTED)
    }
}

/// Marks a transfer vector without a matrix.
const NOT_COMPUTED: u32 = u32::MAX;

/// The 316 transfer vectors, computed once.
fn vectors() -> &'static [[i32; 3]] {
    static V: std::sync::OnceLock<Vec<[i32; 3]>> = std::sync::OnceLock::new();
    V.get_or_init(transfer_vectors)
}

impl<T: Real> M2lScheme<T> for DenseM2l<T> {
    type Config = DenseConfig;

    fn name(&self) -> &'static str {
        "dense"
    }

    fn precompute_for<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        _config: &DenseConfig,
        domain_width: f64,
        depth: u32,
        usage: &M2lUsage,
    ) -> Result<Self, FieldError> {
        params.validate()?;
        let plan = Plan::new(kernel, params, domain_width, depth, usage)?;
        let (levels, sets) = (&plan.levels, &plan.sets);
        let n = crate::expansion_len(kernel, params.order);
        let n_sets = levels.n_sets();
        let monitor = &params.monitor;
        monitor.check()?;
        let total: usize = sets.iter().map(Vec::len).sum();
        let units = monitor.units(total as u64);
        // (set, vector) of each matrix slot, in storage order.
        let order: Vec<(usize, usize)> = sets
            .iter()
            .enumerate()
            .flat_map(|(set, vs)| vs.iter().map(move |&v| (set, v)))
            .collect();
        let compute = || -> Result<FlatStore<DenseLayout, T>, FieldError> {
            let mut data = vec![T::ZERO; order.len() * n * n];
            data.par_chunks_mut(n * n)
                .zip(order.par_iter())
                .try_for_each(|(dst, &(set, v))| -> Result<(), FieldError> {
                    units.check()?;
                    let h = levels.set_half_width(set);
                    let k = m2l_matrix(kernel, params.order, &params.radii, h, vectors()[v])?;
                    for (d, s) in dst.iter_mut().zip(col_major(k.as_ref())) {
                        *d = T::from_f64(s);
                    }
                    units.add(1)
                })?;
            Ok(FlatStore {
                layout: DenseLayout { n, sets: n_sets },
                data,
            })
        };
        let key = || {
            CacheKey::new::<K, T>("m2l-dense", kernel, params.order, params.radii.to_array())
                .for_domain(domain_width, depth)
        };
        let expected = DenseLayout { n, sets: n_sets };
        let (store, cache_status) =
            plan.load_or_compute(params, key, expected.accept(), compute)?;
        let mut slots = vec![vec![NOT_COMPUTED; N_TRANSFER_VECTORS]; n_sets];
        for (slot, &(set, v)) in order.iter().enumerate() {
            slots[set][v] = slot as u32;
        }
        Ok(DenseM2l {
            n,
            levels: plan.levels,
            store,
            slots,
            cache_status,
        })
    }

    fn apply(&self, level: u32, interactions: &M2lInteractions, multipoles: &[T], check: &mut [T]) {
        self.apply_with_progress(level, interactions, multipoles, check, M2lProgress::none());
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
        let n = self.n;
        let Some((set, scale)) = level_set(&self.levels, level, n, interactions, multipoles, check)
        else {
            return;
        };
        for_each_chunk_with_progress(interactions, n, check, progress, |chunk, out| {
            for_each_vector_group(&chunk, multipoles, n, out, n, |v, src, dst| {
                let len = src.len() / n;
                gemm_scaled(
                    n,
                    len,
                    n,
                    scale,
                    self.matrix(set, v),
                    src,
                    dst,
                    Update::Overwrite,
                );
            });
        });
    }

    /// `false`: chunk by chunk ([`for_each_chunk_with_progress`]), so the
    /// FMM keeps only the sibling blocks.
    fn reads_pair_lists(&self) -> bool {
        false
    }

    fn memory_bytes(&self) -> usize {
        self.store.data.len() * std::mem::size_of::<T>()
    }

    fn flops(&self, interactions: &M2lInteractions) -> f64 {
        2.0 * (self.n * self.n) as f64 * interactions.len() as f64
    }

    fn cache_status(&self) -> CacheStatus {
        self.cache_status.clone()
    }
}
