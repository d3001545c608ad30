//! M2L (multipole-to-local) translation schemes behind one trait.
//!
//! An M2L scheme maps the upward equivalent densities `phi_s` of the
//! source boxes in a target box's V list to the target's **downward check
//! potential**:
//!
//! ```text
//! d_t += sum_{(t, s, v)} K_v phi_s,   K_v[j, i] = K(y_i + 2 h v, x_j)
//! ```
//!
//! where `y_i` are the upward equivalent points (radius `r_ue h`) and `x_j`
//! the downward check points (radius `r_dc h`) of a box of half-width `h`
//! centred at the origin, and `v` is the integer transfer vector (source
//! center minus target center over the box width). The driver then applies
//! DC2E ([`Operators::dc2e`](crate::Operators::dc2e)) to get the local
//! expansion. For a kernel homogeneous of degree `d`, `K_v` at half-width
//! `h` is `h^d` times `K_v` at half-width 1, so one set of operators serves
//! all levels; otherwise each level `2..=depth` (the only levels with V
//! lists) gets its own.

mod dense;
mod fft;
mod progress;
mod svd;

pub use dense::{DenseConfig, DenseM2l};
pub use fft::{FftConfig, FftM2l, SPECTRA_BUDGET_BYTES};
pub use progress::M2lProgress;
pub use svd::{SvdConfig, SvdM2l, default_svd_tolerance};

use faer::Mat;
use ferrofmm_kernels::{Kernel, Real};
use rayon::prelude::*;

use crate::levels::FIRST_M2L_LEVEL;
use crate::usage::{cacheable, first_m2l_level, planned_sets};

use crate::cache::{CacheKey, CachePayload, load_or_compute};
use crate::estimate::seconds_for;
use crate::interactions::ChunkView;
use crate::levels::LevelMap;
use crate::linalg::kernel_matrix;
use crate::threads::effective_threads;
use crate::{
    CacheStatus, FieldError, M2lInteractions, M2lUsage, N_TRANSFER_VECTORS, OperatorParams,
    PrecomputeEstimate, SurfaceRadii, surface_points,
};

/// How a scheme's M2L time grows with the order and the tree, for the
/// parameter chooser of ferrofmm-fmm (`tuning`), which predicts the cost of
/// each candidate order and leaf size from it. With `n` surface points,
/// `v` V-list pairs and `b` boxes on levels `>= 2`:
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum M2lCostShape {
    /// One `n x n` product per pair: `n^2 v` (the default of
    /// [`M2lScheme::COST_SHAPE`], an upper bound for any scheme).
    Dense,
    /// Products at rank `k` plus compression per box: `k^2 v + n k b`
    /// ([`SvdM2l`]).
    Compressed,
    /// Pointwise products on `F` frequencies plus two FFTs per box: `F v +
    /// F log2(F) b`, `F = N^2 (floor(N/2) + 1)` for the grid size `N` of
    /// [`FftM2l`] ([`fft_frequencies`]).
    Fft,
}

impl M2lCostShape {
    /// Short name: `"dense"`, `"compressed"`, `"fft"`.
    pub fn name(self) -> &'static str {
        match self {
            M2lCostShape::Dense => "dense",
            M2lCostShape::Compressed => "compressed",
            M2lCostShape::Fft => "fft",
        }
    }
}

/// Frequencies `F = N^2 (floor(N/2) + 1)` of [`FftM2l`]'s convolution grid
/// at `order` (`N` is the smallest 2, 3, 5, 7-smooth size `>= 2p - 1`).
///
/// ```
/// assert_eq!(ferrofmm_field::fft_frequencies(6), 12 * 12 * 7);
/// assert_eq!(ferrofmm_field::fft_frequencies(8), 15 * 15 * 8);
/// ```
pub fn fft_frequencies(order: usize) -> usize {
    let n = fft::grid_size(order.max(2));
    n * n * (n / 2 + 1)
}

/// A swappable M2L translation scheme. The FMM driver is generic over it.
///
/// Contract of [`M2lScheme::apply`]: `multipoles` is column-major `n x
/// n_source_cols` (upward equivalent densities), `check` is column-major `n
/// x n_target_cols` (downward check potentials, **accumulated into**), with
/// `n` = [`n_surface_points`](crate::n_surface_points)`(order)`. It runs in
/// parallel (rayon) over target chunks, each task owning its columns, so
/// there are no data races; call it from outside rayon tasks (the driver's
/// main thread), once per level.
pub trait M2lScheme<T: Real>: Sized + Send + Sync {
    /// Scheme-specific settings (rank, tolerance, ...).
    type Config: Clone + Default + std::fmt::Debug + Send + Sync;

    /// Short name, e.g. `"dense"`, `"svd"`.
    fn name(&self) -> &'static str;

    /// How the scheme's apply time grows (for the parameter chooser);
    /// [`M2lCostShape::Dense`] unless a scheme says otherwise.
    const COST_SHAPE: M2lCostShape = M2lCostShape::Dense;

    /// Precompute the operators of `kernel` for a domain of width
    /// `domain_width` and levels up to `depth` (per level for a
    /// non-homogeneous kernel), using the order and radii of `params` and
    /// its cache directory: every transfer vector at every level, that is
    /// [`M2lScheme::precompute_for`] with [`M2lUsage::all`]`(depth)`.
    ///
    /// Provided; a scheme implements [`M2lScheme::precompute_for`] only.
    fn precompute<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        config: &Self::Config,
        domain_width: f64,
        depth: u32,
    ) -> Result<Self, FieldError> {
        let usage = M2lUsage::all(depth);
        Self::precompute_for(kernel, params, config, domain_width, depth, &usage)
    }

    /// Precompute only what `usage` needs: for a kernel homogeneous of
    /// degree `d` the operators `K_v` for `v` in the union `V = U_l V_l` of
    /// the used transfer vectors (one set, scaled by `h^d` per level);
    /// otherwise for each level `l` with `V_l` nonempty, `K_v(h_l)` for
    /// `v in V_l` only. An empty `usage` (a tree without V lists) computes
    /// nothing at all. [`M2lScheme::apply`] may then only be called with
    /// the interactions `usage` was made from.
    ///
    /// With a cache directory in `params`, all 316 vectors of every set are
    /// computed (unless `usage` is empty) so that the cache file stays
    /// complete and serves any later tree ([`planned_sets`] says which
    /// vectors each set gets). A scheme that cannot make use of `usage` may
    /// ignore it and build everything.
    fn precompute_for<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        config: &Self::Config,
        domain_width: f64,
        depth: u32,
        usage: &M2lUsage,
    ) -> Result<Self, FieldError>;

    /// Predicted peak memory and time of
    /// [`M2lScheme::precompute_for`]`(.., depth, usage)`, before any work.
    ///
    /// The default, right for [`DenseM2l`]: with `m` the matrices to
    /// assemble (see [`planned_sets`]) and `n` points per surface, `m n^2`
    /// stored values of `T` plus one `f64` matrix per worker thread;
    /// `m n^2` kernel evaluations at about 20 flops each.
    fn estimate<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        config: &Self::Config,
        depth: u32,
        usage: &M2lUsage,
    ) -> PrecomputeEstimate {
        let _ = config;
        let m: usize = planned_sets(kernel.homogeneity().is_some(), params, depth, usage)
            .iter()
            .map(Vec::len)
            .sum();
        let n = crate::expansion_len(kernel, params.order) as u64;
        let threads = effective_threads() as u64;
        let size = std::mem::size_of::<T>() as u64;
        let flops = 20.0 * m as f64 * (n * n) as f64;
        PrecomputeEstimate {
            matrices: m,
            peak_bytes: m as u64 * n * n * size + if m > 0 { threads * n * n * 8 } else { 0 },
            flops,
            seconds: seconds_for(flops),
        }
    }

    /// `check[:, t] += sum_{(t, s, v)} M2L_v(level) multipoles[:, s]`.
    ///
    /// # Panics
    /// When a slice length disagrees with the interactions, or for a level
    /// without operators (non-homogeneous kernel, `level < 2` or `> depth`).
    fn apply(&self, level: u32, interactions: &M2lInteractions, multipoles: &[T], check: &mut [T]);

    /// [`M2lScheme::apply`], telling `progress` how far it got within the
    /// level (the FMM driver calls this one, so that a progress bar moves
    /// during a long level). The results are those of `apply`, bit for bit.
    ///
    /// Provided: `apply`, then the whole level reported done at once. A
    /// scheme overrides it to report per piece of work (the built-in ones
    /// report per chunk of target columns, or per task of target groups)
    /// and then implements `apply` as this with [`M2lProgress::none`];
    /// [`plumbing::for_each_chunk_with_progress`](crate::plumbing::for_each_chunk_with_progress)
    /// does the reporting for a scheme built on chunks.
    fn apply_with_progress(
        &self,
        level: u32,
        interactions: &M2lInteractions,
        multipoles: &[T],
        check: &mut [T],
        progress: M2lProgress<'_>,
    ) {
        self.apply(level, interactions, multipoles, check);
        progress.advance(1, 1);
    }

    /// Bytes held by the precomputed operators.
    fn memory_bytes(&self) -> usize;

    /// Bytes of working memory one [`M2lScheme::apply`] of `interactions`
    /// holds beyond its arguments (the FFT scheme's source spectra, at most
    /// its budget); default none.
    fn apply_scratch_bytes(&self, _interactions: &M2lInteractions) -> usize {
        0
    }

    /// Whether [`M2lScheme::apply`] reads the whole pair lists of its
    /// interactions ([`M2lInteractions::chunk_views`]). A scheme that reads
    /// only their sibling blocks ([`M2lInteractions::sibling_blocks`], as
    /// the FFT scheme does) or one chunk at a time
    /// ([`M2lInteractions::with_chunk`], [`for_each_chunk`], as the SVD
    /// scheme does) says `false`, and the FMM driver then releases the
    /// lists once the blocks are made ([`M2lInteractions::release_pairs`]):
    /// 8 bytes a V-list pair, about 16 bytes a point on a uniform tree of
    /// 100 points a leaf. Reading the lists anyway stays correct (they are
    /// made again, and held again). Default `true`.
    fn reads_pair_lists(&self) -> bool {
        true
    }

    /// Floating-point operations of one [`M2lScheme::apply`] of
    /// `interactions` (multiply and add counted separately), for GFLOP/s
    /// figures. `0.0` when a scheme does not say.
    fn flops(&self, interactions: &M2lInteractions) -> f64 {
        let _ = interactions;
        0.0
    }

    /// What happened with the on-disk cache during precomputation.
    fn cache_status(&self) -> CacheStatus {
        CacheStatus::Disabled
    }
}

/// What one precomputation of a scheme builds: which operator set serves
/// which level, at which half-width (`levels`), and the transfer vectors
/// of each set (`sets`, from [`planned_sets`]).
pub(crate) struct Plan {
    /// Levels [`first_m2l_level`]`..=depth` (2 unless a periodic tree's
    /// V lists reach level 1) and their sets.
    pub levels: LevelMap,
    /// Per set, the transfer vector indices to compute.
    pub sets: Vec<Vec<usize>>,
    /// Whether the store may go through the cache (its sets start at
    /// level 2, as cache files' do).
    cacheable: bool,
}

impl Plan {
    /// The plan for `usage` (see [`M2lScheme::precompute_for`]).
    pub(crate) fn new<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        domain_width: f64,
        depth: u32,
        usage: &M2lUsage,
    ) -> Result<Self, FieldError> {
        let homogeneous = kernel.homogeneity().is_some();
        let first = if homogeneous {
            FIRST_M2L_LEVEL
        } else {
            first_m2l_level(usage)
        };
        let levels = LevelMap::new(kernel.homogeneity(), domain_width, depth, first)?;
        let sets = planned_sets(homogeneous, params, depth, usage);
        Ok(Plan {
            levels,
            sets,
            cacheable: cacheable(homogeneous, usage),
        })
    }

    /// Whether every set gets all 316 vectors.
    pub(crate) fn is_complete(&self) -> bool {
        self.sets.iter().all(|s| s.len() == N_TRANSFER_VECTORS)
    }

    /// The scheme's store: through the cache of `params` (the file named by
    /// `key`, its layout checked by `accept`) when the plan is complete,
    /// else computed and not cached (a partial store would not serve a
    /// later tree).
    pub(crate) fn load_or_compute<T: Real, S: CachePayload<T>>(
        &self,
        params: &OperatorParams,
        key: impl FnOnce() -> CacheKey,
        accept: impl Fn(&S::Layout) -> Result<(), String>,
        compute: impl FnOnce() -> Result<S, FieldError>,
    ) -> Result<(S, CacheStatus), FieldError> {
        match params.cache_dir.as_deref() {
            Some(dir) if self.cacheable && self.is_complete() => {
                load_or_compute(Some(dir), params.cache_size_limit, &key(), accept, compute)
            }
            _ => Ok((compute()?, CacheStatus::Disabled)),
        }
    }
}

/// `K_v` at half-width `h` (column-major `n x n`, `f64`):
/// `K_v[j, i] = K(y_i + 2 h v, x_j)` with `y_i` the upward equivalent
/// points (radius `r_ue h`) and `x_j` the downward check points (radius
/// `r_dc h`) of a box of half-width `h` at the origin.
///
/// # Errors
/// [`FieldError::NonFiniteKernel`] when the kernel returns a non-finite
/// value.
pub fn m2l_matrix<K: Kernel>(
    kernel: &K,
    order: usize,
    radii: &SurfaceRadii,
    h: f64,
    v: [i32; 3],
) -> Result<Mat<f64>, FieldError> {
    let center = [
        2.0 * h * v[0] as f64,
        2.0 * h * v[1] as f64,
        2.0 * h * v[2] as f64,
    ];
    let ue: Vec<f64> = surface_points(order, center, h, radii.upward_equivalent);
    let dc: Vec<f64> = surface_points(order, [0.0; 3], h, radii.downward_check);
    kernel_matrix(kernel, &ue, &dc, "an M2L matrix")
}

/// Check the slice lengths of an [`M2lScheme::apply`] call: `multipoles`
/// must be `n x n_source_cols` and `check` `n x n_target_cols`.
///
/// # Panics
/// When they are not (the contract of `apply`).
pub fn check_lengths<T>(n: usize, inter: &M2lInteractions, multipoles: &[T], check: &[T]) {
    assert_eq!(
        multipoles.len(),
        n * inter.n_source_cols(),
        "M2L apply: multipoles must be n x n_source_cols = {n} x {}",
        inter.n_source_cols()
    );
    assert_eq!(
        check.len(),
        n * inter.n_target_cols(),
        "M2L apply: check must be n x n_target_cols = {n} x {}",
        inter.n_target_cols()
    );
}

/// The start of an `apply` of a scheme whose operator sets follow
/// `levels`: the slice lengths checked ([`check_lengths`], `n` values per
/// expansion), then the set serving `level` and its scale
/// ([`LevelMap::lookup`]); `None` when there are no interactions.
pub(crate) fn level_set<T>(
    levels: &LevelMap,
    level: u32,
    n: usize,
    interactions: &M2lInteractions,
    multipoles: &[T],
    check: &[T],
) -> Option<(usize, f64)> {
    check_lengths(n, interactions, multipoles, check);
    if interactions.is_empty() {
        return None;
    }
    Some(levels.lookup(level, 1.0))
}

/// Run `f(chunk, check_columns_of_chunk)` in parallel (rayon) over the
/// chunks of `inter`: each call gets the chunk and its own disjoint block
/// of `check` (the chunk's target columns, `rows` values each, column
/// `first_target() + t` at `t * rows`), so no two tasks write the same
/// value. Empty chunks are skipped. After
/// [`M2lInteractions::release_pairs`] each task makes its chunk's pairs
/// from the sibling blocks and drops them when done
/// ([`M2lInteractions::with_chunk`]), so a scheme built on this loop never
/// needs the level's whole pair lists.
///
/// # Panics
/// When `check` is shorter than `rows * inter.n_target_cols()`.
pub fn for_each_chunk<T: Real>(
    inter: &M2lInteractions,
    rows: usize,
    check: &mut [T],
    f: impl Fn(ChunkView<'_>, &mut [T]) + Sync + Send,
) {
    for_each_chunk_with_progress(inter, rows, check, M2lProgress::none(), f)
}

/// [`for_each_chunk`], telling `progress` after each chunk its pairs done
/// out of `inter.len()` (for [`M2lScheme::apply_with_progress`]). Without
/// a listener nothing is counted.
///
/// # Panics
/// When `check` is shorter than `rows * inter.n_target_cols()`.
pub fn for_each_chunk_with_progress<T: Real>(
    inter: &M2lInteractions,
    rows: usize,
    check: &mut [T],
    progress: M2lProgress<'_>,
    f: impl Fn(ChunkView<'_>, &mut [T]) + Sync + Send,
) {
    let total = inter.len() as u64;
    let mut blocks = Vec::with_capacity(inter.n_chunks());
    let mut rest = check;
    for c in 0..inter.n_chunks() {
        let (a, b) = rest.split_at_mut(inter.chunk_targets(c).len() * rows);
        blocks.push((c, a));
        rest = b;
    }
    blocks.into_par_iter().for_each(|(c, out)| {
        inter.with_chunk(c, |c| {
            if !c.is_empty() {
                let pairs = if progress.is_active() {
                    c.groups().map(|g| g.sources.len() as u64).sum()
                } else {
                    0
                };
                f(c, out);
                progress.advance(pairs, total);
            }
        });
    });
}

/// Copy columns `cols` of the column-major `src` (`rows` values per
/// column) into the contiguous `rows x cols.len()` block `out`.
///
/// ```
/// use ferrofmm_field::plumbing::{gather, scatter_add};
/// let src = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]; // three columns of two
/// let mut block = [0.0; 4];
/// gather(2, &src, &[2, 0], &mut block);
/// assert_eq!(block, [5.0, 6.0, 1.0, 2.0]);
/// let mut dst = [0.0; 4];
/// scatter_add(2, &block, &[1, 1], &mut dst);
/// assert_eq!(dst, [0.0, 0.0, 6.0, 8.0]);
/// ```
pub fn gather<T: Real>(rows: usize, src: &[T], cols: &[u32], out: &mut [T]) {
    for (j, &s) in cols.iter().enumerate() {
        let s = s as usize;
        out[j * rows..(j + 1) * rows].copy_from_slice(&src[s * rows..(s + 1) * rows]);
    }
}

/// Add the columns of a contiguous `rows x cols.len()` block to columns
/// `cols` of `dst` (repeated columns add up).
pub fn scatter_add<T: Real>(rows: usize, block: &[T], cols: &[u32], dst: &mut [T]) {
    for (j, &t) in cols.iter().enumerate() {
        let t = t as usize;
        for (d, &b) in dst[t * rows..(t + 1) * rows]
            .iter_mut()
            .zip(&block[j * rows..(j + 1) * rows])
        {
            *d += b;
        }
    }
}

/// The per-group loop of a chunk, for schemes whose M2L is one linear map
/// `P_v` per transfer vector: for each group `g` of `chunk`,
///
/// ```text
/// out[:, g.targets] += P_{g.vector} (columns[:, g.sources])
/// ```
///
/// where `columns` has `rows_in` values per column (the multipoles, or a
/// compressed form of them) and `out` is the chunk's own block with
/// `rows_out` values per column (indexed by the chunk-relative target
/// columns). The group's source columns are gathered into one contiguous
/// `rows_in x len` block `src`; `product(v, src, dst)` must overwrite the
/// `rows_out x len` block `dst` with `P_v src`; the result is scatter-added
/// ([`gather`], [`scatter_add`]). The two blocks are allocated once per
/// call, for the chunk's largest group. `product` runs sequentially, so it
/// may keep its own scratch (an `FnMut`).
///
/// ```
/// use ferrofmm_field::M2lInteractions;
/// use ferrofmm_field::plumbing::{for_each_chunk, for_each_vector_group};
/// // One target column, two source columns of 2 values; source 1 acts on target 0.
/// let inter = M2lInteractions::new(1, 2, &[(0, 1, [2, 0, 0])]);
/// let multipoles = [1.0, 2.0, 3.0, 4.0];
/// let mut check = [0.5, 0.5];
/// for_each_chunk(&inter, 2, &mut check, |chunk, out| {
///     // P_v = 10 I for every v.
///     for_each_vector_group(&chunk, &multipoles, 2, out, 2, |_, src, dst| {
///         dst.iter_mut().zip(src).for_each(|(d, s)| *d = 10.0 * s);
///     });
/// });
/// assert_eq!(check, [30.5, 40.5]);
/// ```
pub fn for_each_vector_group<T: Real>(
    chunk: &ChunkView<'_>,
    columns: &[T],
    rows_in: usize,
    out: &mut [T],
    rows_out: usize,
    product: impl FnMut(usize, &[T], &mut [T]),
) {
    for_each_vector_group_at(
        chunk,
        columns,
        |s| s as usize,
        rows_in,
        out,
        rows_out,
        product,
    );
}

/// [`for_each_vector_group`] with source column `s` found at column
/// `column(s)` of `columns`: for a scheme that keeps only the columns a
/// chunk reads (the SVD scheme's compressed multipoles).
#[allow(clippy::too_many_arguments)]
pub(crate) fn for_each_vector_group_at<T: Real>(
    chunk: &ChunkView<'_>,
    columns: &[T],
    column: impl Fn(u32) -> usize,
    rows_in: usize,
    out: &mut [T],
    rows_out: usize,
    mut product: impl FnMut(usize, &[T], &mut [T]),
) {
    let m = chunk.max_group_len();
    let mut src = vec![T::ZERO; rows_in * m];
    let mut dst = vec![T::ZERO; rows_out * m];
    for g in chunk.groups() {
        let len = g.sources.len();
        let (src, dst) = (&mut src[..rows_in * len], &mut dst[..rows_out * len]);
        for (block, &s) in src.chunks_exact_mut(rows_in).zip(g.sources) {
            let c = column(s);
            block.copy_from_slice(&columns[c * rows_in..(c + 1) * rows_in]);
        }
        product(g.vector, src, dst);
        scatter_add(rows_out, dst, g.targets, out);
    }
}
