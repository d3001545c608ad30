//! # ferrofmm-fmm
//!
//! The kernel-independent fast multipole method (KIFMM, Ying, Biros & Zorin
//! 2004) driver: it computes
//!
//! ```text
//! phi(y_j) = sum_i K(x_i, y_j) q_i        (K(x, x) := 0)
//! ```
//!
//! for N sources and M targets in O(N + M) work, to an accuracy set by the
//! expansion order `p`, for any [`ferrofmm_kernels::Kernel`] and any
//! [`ferrofmm_field::M2lScheme`].
//!
//! Build once with [`FmmBuilder`], then call [`Fmm::evaluate`] for as many
//! charge vectors as needed. All passes run in parallel with rayon (over
//! leaves and over the boxes of a level); dense operators are applied to
//! whole levels at once as matrix-matrix products.
//!
//! Each box `B` of the adaptive, 2:1-balanced octree carries an upward
//! equivalent density `u_B` (its multipole expansion) and a downward
//! equivalent density `d_B` (its local expansion) on `6 (p - 1)^2 + 2`
//! points of a cube surface. The eight operators (see the `passes` module
//! docs): P2M, M2M, M2L over V lists, P2L over X lists, L2L, L2P, M2P over
//! W lists, P2P over U lists.
//!
//! [`TreeFmm`] runs the same passes one at a time over a tree the caller
//! supplies (a distributed driver's piece of a global tree).

pub mod accuracy;
mod batch;
mod build_scheme;
mod builder;
mod coordinates;
mod coupling;
pub mod data;
mod error;
mod fmm;
mod memory;
mod overflow;
mod part;
mod passes;
pub mod periodic;
mod precompute;
mod progress;
mod scheme_choice;
mod setup_progress;
pub mod stokes_layers;
mod timings;
mod tree_fmm;
pub mod tuning;
mod validate;
pub mod verify;

pub use accuracy::{
    ErrorReport, estimate_errors, random_sample, relative_errors, relative_errors_periodic,
    relative_errors_sources, relative_errors_sources_with_progress, sample_indices,
};
pub use build_scheme::BuildScheme;
pub use builder::{
    DEFAULT_F32_TOLERANCE, DEFAULT_LEAF_SIZE, DEFAULT_ORDER, DEFAULT_TOLERANCE, FmmBuilder,
    MAX_ORDER, MAX_WAVENUMBER_WIDTH, MIN_ORDER, default_tolerance, effective_tolerance,
};
pub use data::{Charges, Geometry, charges};
pub use error::FmmError;
pub use ferrofmm_field::{
    CacheLocation, CacheSetting, MemoryLimit, PrecomputeMonitor, PrecomputeProgress,
};
pub use fmm::{Fmm, FmmSummary};
pub use memory::{MemoryReport, RunSize, check_memory};
pub use overflow::check_finite_output;
pub use periodic::{Periodic, PeriodicAxes, SurfaceTerm};
pub use precompute::{first_far_level, m2l_usage};
pub use progress::{EvalProgress, ProgressFn};
pub use scheme_choice::SchemeChoice;
pub use setup_progress::{SetupProgress, SetupProgressFn, SetupStep};
pub use stokes_layers::{
    LaplacePart, StokesErrors, StokesEvaluation, StokesLayerPlan, StokesLayers, StokesRequest,
    StokesValues,
};
pub use timings::{EvalTimings, SetupTimings};
pub use tree_fmm::{LocalTree, TreeFmm};
pub use tuning::{CalibrationSetting, ChosenParameters, f32_reaches};
pub use validate::check_representable;
pub use verify::{Evaluation, Verification, VerificationAttempt};
