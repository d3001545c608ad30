//! # ferrofmm-field
//!
//! Everything that turns a [`Kernel`](ferrofmm_kernels::Kernel) into the
//! translation operators of the kernel-independent FMM (KIFMM, Ying, Biros
//! and Zorin 2004): equivalent and check surfaces, stable check-to-equivalent
//! pseudo-inverses, the parent/child operators, swappable M2L schemes and an
//! on-disk operator cache. All dense linear algebra is faer, all
//! precomputation is `f64`, operators are rounded to the working type
//! (`f32` or `f64`) once at the end.
//!
//! ## Surfaces and expansions
//!
//! A box `B` with center `c` and half-width `h` (at tree level `l` of a
//! cubic domain of width `W`, `h = W / 2^(l+1)`) carries four surfaces, each
//! the order-`p` cube-surface grid ([`surface_points`], `n = 6 (p-1)^2 + 2`
//! points, the same point order for every box) scaled to radius `r h`
//! around `c`, with the radii of [`SurfaceRadii`] (default `1.05 / 2.95 /
//! 2.95 / 1.05`):
//!
//! | surface | radius | points |
//! |---|---|---|
//! | upward equivalent | `r_ue h` | `y^{B,u}` carry the multipole `phi` (`n` values) |
//! | upward check | `r_uc h` | `x^{B,u}` |
//! | downward equivalent | `r_de h` | `y^{B,d}` carry the local expansion `psi` (`n` values) |
//! | downward check | `r_dc h` | `x^{B,d}` |
//!
//! With `K(y <- x)` the matrix `[K(x_i, y_j)]_{j,i}` (targets by rows) and
//! the sources `x_s`, charges `q_s`, targets `t` of a box:
//!
//! | operator | formula | who computes it |
//! |---|---|---|
//! | P2M | `u = K(x^{B,u} <- x_s) q`, then `phi_B = UC2E u` | driver (kernel evaluation + [`Operators::uc2e`]) |
//! | M2M | `phi_P += M2M_o phi_C` for child `C` in octant `o` of `P` | [`Operators::m2m`] |
//! | M2L | `d_B += K(x^{B,d} <- y^{S,u}) phi_S` for `S` in V(B) | [`M2lScheme::apply`] |
//! | P2L | `d_B += K(x^{B,d} <- x_s) q` for sources of boxes in X(B) | driver (kernel evaluation) |
//! | DC2E | `psi_B += DC2E d_B` (after all M2L and P2L contributions) | [`Operators::dc2e`] |
//! | L2L | `psi_C += L2L_o psi_P` | [`Operators::l2l`] |
//! | L2P | `phi(t) += K(t <- y^{B,d}) psi_B` | driver (kernel evaluation) |
//! | M2P | `phi(t) += K(t <- y^{S,u}) phi_S` for `S` in W(B) | driver (kernel evaluation) |
//!
//! where `UC2E = K(x^{B,u} <- y^{B,u})^+` and `DC2E = K(x^{B,d} <- y^{B,d})^+`
//! are truncated pseudo-inverses (module `pinv`, cutoff
//! [`OperatorParams::pinv_rcond`]). The surfaces for P2M/P2L/L2P/M2P are
//! [`surface_points`]`(order, center, h, radius)` or
//! [`Operators::surface_points`]. Expansions of many boxes are column-major
//! `n x ncols` blocks with each box's `n` values contiguous; every operator
//! applies to a whole block at once with one matrix-matrix product.
//!
//! ## Scaling
//!
//! For a kernel homogeneous of degree `d` ([`Kernel::homogeneity`](
//! ferrofmm_kernels::Kernel::homogeneity), Laplace: `d = -1`), operators
//! are computed once at half-width 1 and reused at every level: kernel
//! matrices (M2L) scale by `h^d`, pseudo-inverses (UC2E, DC2E) by `h^-d`,
//! M2M and L2L not at all. Other kernels (e.g. modified Helmholtz) get
//! operators per level (`0..=depth`; M2L for `2..=depth`).
//!
//! ## M2L schemes
//!
//! [`M2lScheme`] is the seam: [`DenseM2l`] (one `n x n` matrix per transfer
//! vector, the reference) and [`SvdM2l`] (Fong–Darve: one pair of bases for
//! all 316 transfer vectors, `k x k` cores, each factored again at its own
//! rank `C_v = A_v B_v^T`). Interactions of a level are
//! grouped by [`M2lInteractions`] so that every transfer vector is applied
//! as one GEMM over all boxes that share it.
//!
//! ## Cache
//!
//! With [`OperatorParams::cache_dir`] set, [`Operators`] and the M2L schemes
//! are stored on disk (module `cache`: bincode header + raw little-endian
//! payload with an XXH64 checksum) and reloaded when every parameter
//! matches; anything stale, truncated or corrupt is recomputed and rewritten.
//! See [`CacheStatus`]. [`OperatorParams::cache_size_limit`] caps the
//! folder (least recently used files deleted first). Where the folder is
//! (an explicit one, `FERROFMM_CACHE`, the XDG cache folder) is decided by
//! [`CacheSetting::resolve`], for every front end.

#![warn(missing_docs)]

mod cache;
mod cache_location;
mod environment;
mod error;
mod estimate;
mod fft3d;
mod gemm;
mod interactions;
mod levels;
mod linalg;
mod m2l;
mod memory;
mod monitor;
mod operators;
mod params;
mod pinv;
pub mod plumbing;
pub(crate) mod siblings;
mod surface;
mod sysmem;
mod threads;
mod usage;

pub use cache::{CACHE_FORMAT_VERSION, CacheStatus, cached_values};
pub use cache_location::{
    CACHE_ENV, CACHE_SIZE_ENV, CacheLocation, CacheOff, CacheOrigin, CacheSetting,
    DEFAULT_CACHE_SIZE, parse_cache_size,
};
pub use environment::MEMORY_LIMIT_ENV;
pub use error::FieldError;
pub use estimate::PrecomputeEstimate;
pub use gemm::{Update, gemm, gemm_scaled};
pub use interactions::{
    M2lInteractions, N_TRANSFER_VECTORS, transfer_vector_index, transfer_vectors,
};
pub use m2l::{
    DenseConfig, DenseM2l, FftConfig, FftM2l, M2lCostShape, M2lProgress, M2lScheme,
    SPECTRA_BUDGET_BYTES, SvdConfig, SvdM2l, default_svd_tolerance, fft_frequencies,
};
pub use memory::MemoryLimit;
pub use monitor::{PrecomputeMonitor, PrecomputeProgress};
pub use operators::{AMPLIFICATION_WARNING, OperatorDiagnostics, Operators, octant_offset};
pub use params::{MAX_ORDER, MIN_ORDER, OperatorParams, default_pinv_rcond};
pub use pinv::PinvSummary;
pub use surface::{SurfaceKind, SurfaceRadii, expansion_len, n_surface_points, surface_points};
pub use sysmem::{address_space_limit, available_memory};
pub use usage::{M2lUsage, first_m2l_level, planned_sets};
