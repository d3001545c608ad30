//! What a run reports: a [`RunReport`], printed as a table for people or as
//! one JSON object (the last line of stdout) for scripts and for `sweep`.
//!
//! JSON keys (times in seconds, memory in bytes):
//!
//! ```text
//! command, geometry (demo only), n_sources, n_targets, order, leaf_size,
//! scheme, precision, gradients, hessians, kernel ("laplace" or "yukawa:K"),
//! sources ("charge", "dipole" or "charge+dipole"), threads, tolerance,
//! predicted_error,
//! cache (in words: hit, miss (computed, saved), off (--no-cache), memory only: why, ...),
//! cache_dir (the cache folder, null when off),
//! tree:       { depth, n_boxes, n_leaves, n_surface, u_list, v_list, w_list, x_list, m2l_bytes,
//!               clusters, far_points },
//! setup:      { tree_s, operators_s, m2l_precompute_s, layout_s, total_s },
//! evaluation: { repeats, best_s, median_s,
//!               operators_s: { p2m, m2m, m2l, p2l, l2l, l2p, m2p, p2p, far } },
//! charges (demo: "signed" or "positive"; eval: null),
//! verification: { tolerance, met, rebuild_s,
//!                 attempts: [ { order, svd_tolerance, predicted_error,
//!                               measured: { n_sampled, potential, gradient, hessian },
//!                               evaluation_s, check_s } ] }
//!               or null (no --tolerance, or --verify off; see verify),
//! verify ("on", "off", or "n/a" without --tolerance),
//! errors:     { n_sampled, potential, gradient, hessian } or null,
//! direct_check_s, peak_rss_bytes (null where unknown), wall_s,
//! memory:     { n_points, points, tree, expansions, evaluation_scratch,
//!               m2l_interactions, operators, m2l, inputs, total,
//!               bytes_per_point, peak_bytes_per_point }
//!               (bytes of the big buffers by component, see MemoryFigures)
//! ```

use crate::commands::{PrecisionArg, SchemeArg};
use serde::{Deserialize, Serialize};

mod cache;
mod figures;
mod format;
mod table;

pub use cache::cache_report;
pub use figures::{
    ErrorFigures, EvalSeconds, MemoryFigures, OperatorSeconds, SetupSeconds, TreeFigures,
};
pub use format::{mebibytes, seconds, thousands};

/// Everything one `demo` or `eval` run measured.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct RunReport {
    /// `"demo"` or `"eval"`.
    pub command: String,
    /// Built-in geometry (demo) or `None` (points from files).
    pub geometry: Option<String>,
    /// Number of sources.
    pub n_sources: usize,
    /// Number of targets.
    pub n_targets: usize,
    /// Expansion order.
    pub order: usize,
    /// Points per leaf at most.
    pub leaf_size: usize,
    /// Requested accuracy (`--tolerance`), when given.
    #[serde(default)]
    pub tolerance: Option<f64>,
    /// Whether `tolerance` is the default one (neither `--tolerance` nor
    /// `--order` given).
    #[serde(default)]
    pub default_tolerance: bool,
    /// The library's predicted error for the chosen parameters (with
    /// `--tolerance`; after verification raised the order, the last
    /// order's).
    #[serde(default)]
    pub predicted_error: Option<f64>,
    /// Built-in charges (`signed` / `positive`; `None` for charges from a file).
    #[serde(default)]
    pub charges: Option<String>,
    /// `"on"` or `"off"` with `--tolerance`, `"n/a"` without.
    #[serde(default)]
    pub verify: String,
    /// The after-the-fact check of the tolerance (with `--tolerance` and
    /// `--verify on`).
    #[serde(default)]
    pub verification: Option<ferrofmm_fmm::Verification>,
    /// M2L scheme as run (`svd`, `dense` or `fft`; never `auto`).
    pub scheme: SchemeArg,
    /// `"direct"` when the cost model chose a direct sum (one leaf holding
    /// every point: no expansions), else `"fmm"`.
    #[serde(default = "fmm_method")]
    pub method: String,
    /// Predicted seconds of the direct sum, when it was a candidate.
    #[serde(default)]
    pub direct_predicted_s: Option<f64>,
    /// The models the parameters were chosen with (`None` when they were
    /// given), saying whether the costs were calibrated on this machine
    /// (`ferrofmm calibrate`).
    #[serde(default)]
    pub cost_model: Option<String>,
    /// Predicted seconds of the cheapest FMM setting (tree, one
    /// evaluation and the operators' precomputation from nothing), when
    /// the parameters were chosen.
    #[serde(default)]
    pub fmm_predicted_s: Option<f64>,
    /// Float type as run (`f32` or `f64`; never `auto`).
    pub precision: PrecisionArg,
    /// Whether gradients were evaluated.
    pub gradients: bool,
    /// Whether Hessians were evaluated.
    #[serde(default)]
    pub hessians: bool,
    /// The kernel: `laplace` or `yukawa:K`.
    #[serde(default = "laplace_name")]
    pub kernel: String,
    /// The periodic cell (`--box`), e.g. `box 10 (xyz, tin-foil), origin
    /// [0, 0, 0]`; `None` in free space.
    #[serde(default)]
    pub periodic: Option<String>,
    /// The energy `1/2 sum_i q_i phi_i` (charges evaluated at the sources
    /// themselves, a scalar kernel; in a periodic cell, per cell).
    #[serde(default)]
    pub energy: Option<f64>,
    /// What the sources carry: `charge`, `dipole` or `charge+dipole`.
    #[serde(default = "charge_name")]
    pub sources: String,
    /// Rayon worker threads.
    pub threads: usize,
    /// What the operator cache did, in words ([`cache_report`]; `None`
    /// only in reports of older versions).
    #[serde(default)]
    pub cache: Option<String>,
    /// The operator cache folder (`None`: no folder, see `cache`).
    #[serde(default)]
    pub cache_dir: Option<String>,
    /// Tree and operator figures.
    pub tree: TreeFigures,
    /// Setup time by step.
    pub setup: SetupSeconds,
    /// Evaluation time.
    pub evaluation: EvalSeconds,
    /// Relative L2 errors against direct summation (`None` when not checked).
    pub errors: Option<ErrorFigures>,
    /// Time of the direct-summation check.
    pub direct_check_s: Option<f64>,
    /// Peak resident memory of the process (`None` where unknown).
    pub peak_rss_bytes: Option<u64>,
    /// Wall time of the whole command.
    pub wall_s: f64,
    /// The big buffers by component (`None` only in reports of older
    /// versions).
    #[serde(default)]
    pub memory: Option<MemoryFigures>,
}

fn laplace_name() -> String {
    "laplace".to_string()
}

fn charge_name() -> String {
    "charge".to_string()
}

/// The method of reports written before direct sums were a candidate.
fn fmm_method() -> String {
    "fmm".to_string()
}

impl RunReport {
    /// The report as one line of JSON.
    pub fn json(&self) -> String {
        serde_json::to_string(self).expect("a report always serialises")
    }
}
