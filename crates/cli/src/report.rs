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

use std::fmt::Write as _;
use std::time::Duration;

use ferrofmm_field::{CacheLocation, CacheOff, CacheSetting, CacheStatus};
use ferrofmm_fmm::{EvalTimings, FmmSummary, SetupTimings};

use crate::commands::{PrecisionArg, SchemeArg};
use serde::{Deserialize, Serialize};

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

/// Bytes of the big buffers of a run by component: the library's
/// ([`ferrofmm_fmm::MemoryReport`], counted from the buffers' lengths)
/// and the command's own inputs (its results are the library's outputs,
/// counted in `evaluation_scratch`).
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct MemoryFigures {
    /// Points the per-point figures divide by (sources plus separate
    /// targets).
    pub n_points: usize,
    /// The FMM's sorted points and the tree's permutations.
    pub points: u64,
    /// Tree structure: per-box arrays and the U/V/W/X lists.
    pub tree: u64,
    /// Multipole and local expansions.
    pub expansions: u64,
    /// Check potentials, densities in tree order, the outputs and the M2L
    /// scheme's working memory (the FFT scheme's source spectra).
    pub evaluation_scratch: u64,
    /// M2L interaction groups of every level.
    pub m2l_interactions: u64,
    /// Check-to-equivalent, M2M and L2L operators.
    pub operators: u64,
    /// M2L operators.
    pub m2l: u64,
    /// The command's own: the densities, and the caller's points where
    /// they are kept (in `f32`, or wrapped into a periodic cell; in `f64`
    /// the FMM's copy gives them back exactly, see `Fmm::points_f64`).
    pub inputs: u64,
    /// All of the above.
    pub total: u64,
    /// `total / n_points`.
    pub bytes_per_point: f64,
    /// The process's peak resident memory over `n_points` (`None` where
    /// unknown).
    pub peak_bytes_per_point: Option<f64>,
}

impl MemoryFigures {
    /// The figures of `library` and `inputs` bytes of the command's own
    /// for `n_points` points, with the process's peak.
    pub fn new(
        library: &ferrofmm_fmm::MemoryReport,
        inputs: u64,
        n_points: usize,
        peak_rss_bytes: Option<u64>,
    ) -> Self {
        let total = library.total as u64 + inputs;
        let per = |b: u64| b as f64 / n_points.max(1) as f64;
        MemoryFigures {
            n_points,
            points: library.points as u64,
            tree: library.tree as u64,
            expansions: library.expansions as u64,
            evaluation_scratch: library.evaluation_scratch as u64,
            m2l_interactions: library.m2l_interactions as u64,
            operators: library.operators as u64,
            m2l: library.m2l as u64,
            inputs,
            total,
            bytes_per_point: per(total),
            peak_bytes_per_point: peak_rss_bytes.map(per),
        }
    }

    /// One line per component: bytes a point and MiB.
    fn rows(&self, o: &mut String) {
        let per = |b: u64| b as f64 / self.n_points.max(1) as f64;
        let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
        let _ = writeln!(
            o,
            "memory by component   bytes a point (MiB), {} points",
            thousands(self.n_points)
        );
        for (name, b) in [
            ("points", self.points),
            ("tree", self.tree),
            ("expansions", self.expansions),
            ("evaluation", self.evaluation_scratch),
            ("M2L lists", self.m2l_interactions),
            ("operators", self.operators + self.m2l),
            ("inputs", self.inputs),
            ("total", self.total),
        ] {
            let _ = writeln!(o, "  {name:<19}{:>10.1} ({:.0})", per(b), mib(b));
        }
        if let Some(p) = self.peak_bytes_per_point {
            let _ = writeln!(o, "  {:<19}{p:>10.1}", "peak (measured)");
        }
    }
}

/// Tree and operator figures of a built FMM.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct TreeFigures {
    /// Deepest level.
    pub depth: u32,
    /// Boxes.
    pub n_boxes: usize,
    /// Leaves.
    pub n_leaves: usize,
    /// Points per equivalent / check surface.
    pub n_surface: usize,
    /// Total U-list entries (P2P).
    pub u_list: usize,
    /// Total V-list entries (M2L).
    pub v_list: usize,
    /// Total W-list entries (M2P).
    pub w_list: usize,
    /// Total X-list entries (P2L).
    pub x_list: usize,
    /// Bytes held by the M2L operators.
    pub m2l_bytes: usize,
    /// Far-separated clusters, each with a tree of its own or its bare
    /// points (1 for most inputs; the figures above are the largest
    /// cluster's tree). Reports written before it existed read as 1.
    #[serde(default = "one")]
    pub clusters: usize,
    /// Sources plus targets outside the largest cluster.
    #[serde(default)]
    pub far_points: usize,
    /// Width of the root box as a multiple of the points' bounding cube
    /// (1 unless the chooser widened it, see
    /// [`ferrofmm_fmm::tuning::choose_root`]).
    #[serde(default = "one_f64")]
    pub root_scale: f64,
}

fn one() -> usize {
    1
}

fn one_f64() -> f64 {
    1.0
}

impl From<&FmmSummary> for TreeFigures {
    fn from(s: &FmmSummary) -> Self {
        TreeFigures {
            depth: s.depth,
            n_boxes: s.n_boxes,
            n_leaves: s.n_leaves,
            n_surface: s.n_surface,
            u_list: s.list_entries[0],
            v_list: s.list_entries[1],
            w_list: s.list_entries[2],
            x_list: s.list_entries[3],
            m2l_bytes: s.m2l_bytes,
            clusters: s.clusters,
            far_points: s.far_points,
            root_scale: s.chosen.as_ref().map_or(1.0, |c| c.root_scale),
        }
    }
}

/// Setup time by step, in seconds.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SetupSeconds {
    /// Octree.
    pub tree_s: f64,
    /// Check-to-equivalent pseudo-inverses, M2M / L2L.
    pub operators_s: f64,
    /// M2L scheme precomputation (or cache load).
    pub m2l_precompute_s: f64,
    /// Sorting points and bookkeeping.
    pub layout_s: f64,
    /// All of setup.
    pub total_s: f64,
}

impl From<&SetupTimings> for SetupSeconds {
    fn from(t: &SetupTimings) -> Self {
        SetupSeconds {
            tree_s: t.tree.as_secs_f64(),
            operators_s: t.operators.as_secs_f64(),
            m2l_precompute_s: t.m2l_precompute.as_secs_f64(),
            layout_s: t.layout.as_secs_f64(),
            total_s: t.total.as_secs_f64(),
        }
    }
}

/// Evaluation time over `repeats` calls, in seconds.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct EvalSeconds {
    /// Calls of `evaluate`.
    pub repeats: usize,
    /// Fastest call.
    pub best_s: f64,
    /// Median call.
    pub median_s: f64,
    /// Time per operator in the fastest call.
    pub operators_s: OperatorSeconds,
}

/// Time per operator, in seconds.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct OperatorSeconds {
    /// Particle to multipole (leaves).
    pub p2m: f64,
    /// Multipole to multipole.
    pub m2m: f64,
    /// Multipole to local (V lists).
    pub m2l: f64,
    /// Particle to local (X lists).
    pub p2l: f64,
    /// Local to local.
    pub l2l: f64,
    /// Local to particle.
    pub l2p: f64,
    /// Multipole to particle (W lists).
    pub m2p: f64,
    /// Particle to particle (U lists).
    pub p2p: f64,
    /// Between far-separated clusters (root expansions or direct sums);
    /// zero for a problem that is one cluster.
    #[serde(default)]
    pub far: f64,
}

impl OperatorSeconds {
    /// Operator names as the FMM literature writes them, in pass order.
    pub const NAMES: [&'static str; 9] = [
        "P2M", "M2M", "M2L", "P2L", "L2L", "L2P", "M2P", "P2P", "Far",
    ];

    /// Values in the order of [`OperatorSeconds::NAMES`].
    pub fn values(&self) -> [f64; 9] {
        [
            self.p2m, self.m2m, self.m2l, self.p2l, self.l2l, self.l2p, self.m2p, self.p2p,
            self.far,
        ]
    }
}

impl From<&EvalTimings> for OperatorSeconds {
    fn from(t: &EvalTimings) -> Self {
        let s = Duration::as_secs_f64;
        OperatorSeconds {
            p2m: s(&t.p2m),
            m2m: s(&t.m2m),
            m2l: s(&t.m2l),
            p2l: s(&t.p2l),
            l2l: s(&t.l2l),
            l2p: s(&t.l2p),
            m2p: s(&t.m2p),
            p2p: s(&t.p2p),
            far: s(&t.coupling),
        }
    }
}

/// Relative L2 errors on sampled targets.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ErrorFigures {
    /// Targets compared with direct summation.
    pub n_sampled: usize,
    /// Relative L2 error of the potential.
    pub potential: f64,
    /// Relative L2 error of the gradient (`None` without gradients).
    pub gradient: Option<f64>,
    /// Relative L2 error of the Hessian (`None` without Hessians).
    #[serde(default)]
    pub hessian: Option<f64>,
}

fn laplace_name() -> String {
    "laplace".to_string()
}

fn charge_name() -> String {
    "charge".to_string()
}

/// `1234567` as `1,234,567`.
pub fn thousands(n: usize) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (k, c) in digits.chars().enumerate() {
        if k > 0 && (digits.len() - k).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Seconds in a readable unit (`1.234 s`, `12.3 ms`, `45 us`).
pub fn seconds(s: f64) -> String {
    if s >= 1.0 {
        format!("{s:.3} s")
    } else if s >= 1e-3 {
        format!("{:.1} ms", s * 1e3)
    } else {
        format!("{:.0} us", s * 1e6)
    }
}

/// Bytes as MiB (or `n/a`).
pub fn mebibytes(bytes: Option<u64>) -> String {
    match bytes {
        Some(b) => format!("{:.0} MiB", b as f64 / (1024.0 * 1024.0)),
        None => "n/a (no /proc/self/status)".to_string(),
    }
}

/// The cache's part in a run, from the status of the operator file and of
/// the M2L file ([`CacheStatus::summary`]): `hit`, `miss (computed,
/// saved)`, ... for both, or `operators X; M2L Y` when they differ. `None`
/// when caching is off.
pub fn cache_summary(operators: &CacheStatus, m2l: &CacheStatus) -> Option<String> {
    CacheStatus::summary(operators, m2l)
}

/// The cache's part in a run and its folder, for the report: the words
/// of [`cache_summary`] when there is a folder, else why there is none
/// (`off (--no-cache)`, `off (FERROFMM_CACHE=off)`, `memory only: no
/// cache folder (...)`).
pub fn cache_report(
    setting: &CacheSetting,
    operators: &CacheStatus,
    m2l: &CacheStatus,
) -> (Option<String>, Option<String>) {
    match setting.resolve() {
        Ok(CacheLocation::Folder { dir, .. }) => (
            Some(cache_summary(operators, m2l).unwrap_or_else(|| "not needed".into())),
            Some(dir.display().to_string()),
        ),
        Ok(CacheLocation::Off(CacheOff::Requested)) => (Some("off (--no-cache)".into()), None),
        Ok(CacheLocation::Off(why)) => (Some(why.to_string()), None),
        // The build read the same environment and succeeded.
        Err(e) => (Some(format!("unknown: {e}")), None),
    }
}

/// The method of reports written before direct sums were a candidate.
fn fmm_method() -> String {
    "fmm".to_string()
}

impl RunReport {
    /// The human-readable table.
    pub fn table(&self) -> String {
        let mut o = String::new();
        let row = |o: &mut String, label: &str, value: String| {
            let _ = writeln!(o, "  {label:<18} {value}");
        };
        let what = match (self.gradients, self.hessians) {
            (_, true) => "potential + gradient + Hessian",
            (true, false) => "potential + gradient",
            (false, false) => "potential",
        };
        let kernel = ferrofmm_kernels::KernelChoice::parse(&self.kernel)
            .map_or_else(|_| self.kernel.clone(), |k| k.title());
        let sources = match self.sources.as_str() {
            "charge" => String::new(),
            s => format!(", {s} sources"),
        };
        let _ = writeln!(
            o,
            "ferrofmm {}: {kernel}{sources}, {what}, {}",
            self.command, self.precision
        );
        let points = match &self.geometry {
            Some(g) => format!("{} ({g})", thousands(self.n_sources)),
            None => thousands(self.n_sources),
        };
        row(&mut o, "sources", points);
        if let Some(c) = &self.charges {
            let what = match c.as_str() {
                "signed" => "uniform in [-0.5, 0.5) (zero mean)",
                "positive" => "uniform in [0, 1) (all positive)",
                other => other,
            };
            row(&mut o, "charges", what.to_string());
        }
        row(&mut o, "targets", thousands(self.n_targets));
        if let Some(p) = &self.periodic {
            row(&mut o, "periodic", p.clone());
        }
        if let Some(e) = self.energy {
            row(&mut o, "energy", format!("{e:.12e} (1/2 sum q phi)"));
        }
        if self.method == "direct" {
            let predicted = match (self.direct_predicted_s, self.fmm_predicted_s) {
                (Some(d), Some(f)) => format!(
                    " (predicted {} against {} for the fastest FMM with its operators)",
                    seconds(d),
                    seconds(f)
                ),
                _ => String::new(),
            };
            row(
                &mut o,
                "method",
                format!("direct sum, exact to rounding{predicted}"),
            );
        } else {
            row(
                &mut o,
                "expansion",
                format!(
                    "order {} ({} points per surface), {} M2L ({:.1} MiB), leaf size {}",
                    self.order,
                    self.tree.n_surface,
                    self.scheme,
                    self.tree.m2l_bytes as f64 / (1024.0 * 1024.0),
                    self.leaf_size
                ),
            );
        }
        row(
            &mut o,
            "tree",
            format!(
                "depth {}, {} leaves, {} boxes{}{}",
                self.tree.depth,
                thousands(self.tree.n_leaves),
                thousands(self.tree.n_boxes),
                if self.tree.root_scale > 1.0 {
                    format!(
                        "; root {:.2}x the points' bounding cube",
                        self.tree.root_scale
                    )
                } else {
                    String::new()
                },
                if self.tree.clusters > 1 {
                    format!(
                        "; {} far clusters ({} points outside the largest)",
                        self.tree.clusters,
                        thousands(self.tree.far_points)
                    )
                } else {
                    String::new()
                }
            ),
        );
        row(
            &mut o,
            "lists",
            format!(
                "U {}, V {}, W {}, X {}",
                thousands(self.tree.u_list),
                thousands(self.tree.v_list),
                thousands(self.tree.w_list),
                thousands(self.tree.x_list)
            ),
        );
        row(&mut o, "threads", self.threads.to_string());
        if let Some(c) = &self.cache {
            let c = match &self.cache_dir {
                Some(dir) => format!("{c} in {dir}"),
                None => c.clone(),
            };
            row(&mut o, "operator cache", c);
        }

        let _ = writeln!(
            o,
            "setup                {:>10}",
            seconds(self.setup.total_s)
        );
        for (label, s) in [
            ("tree", self.setup.tree_s),
            ("operators", self.setup.operators_s),
            ("M2L precompute", self.setup.m2l_precompute_s),
            ("layout", self.setup.layout_s),
        ] {
            let _ = writeln!(o, "  {label:<18} {:>10}", seconds(s));
        }
        let e = &self.evaluation;
        let repeats = if e.repeats > 1 {
            format!(" (best of {}, median {})", e.repeats, seconds(e.median_s))
        } else {
            String::new()
        };
        let _ = writeln!(o, "evaluation           {:>10}{repeats}", seconds(e.best_s));
        for (name, s) in OperatorSeconds::NAMES.iter().zip(e.operators_s.values()) {
            if *name == "Far" && s == 0.0 {
                continue;
            }
            let share = if e.best_s > 0.0 {
                100.0 * s / e.best_s
            } else {
                0.0
            };
            let _ = writeln!(o, "  {name:<18} {:>10} {share:>5.1}%", seconds(s));
        }
        let _ = writeln!(
            o,
            "setup + evaluation   {:>10}",
            seconds(self.setup.total_s + e.best_s)
        );
        if let Some(eps) = self.tolerance {
            let predicted = self
                .predicted_error
                .map(|e| format!(", predicted error {e:.2e}"))
                .unwrap_or_default();
            row(
                &mut o,
                "tolerance",
                format!(
                    "{eps:.2e} {}{predicted}",
                    if self.default_tolerance {
                        "(the default; --tolerance or --order to change it)"
                    } else {
                        "requested"
                    }
                ),
            );
            match &self.verification {
                Some(v) => {
                    for (i, a) in v.attempts.iter().enumerate() {
                        let grad = a
                            .measured
                            .gradient
                            .map(|g| format!(", gradient {g:.2e}"))
                            .unwrap_or_default()
                            + &a.measured
                                .hessian
                                .map(|h| format!(", Hessian {h:.2e}"))
                                .unwrap_or_default();
                        let label = if i == 0 { "verified" } else { "  raised order" };
                        row(
                            &mut o,
                            label,
                            format!(
                                "order {}: potential {:.2e}{grad} on {} sampled targets ({})",
                                a.order,
                                a.measured.potential,
                                a.measured.n_sampled,
                                seconds(a.check_s)
                            ),
                        );
                    }
                    let verdict = if v.met {
                        "met".to_string()
                    } else {
                        format!(
                            "NOT met after {} attempts: the result is less accurate than asked",
                            v.attempts.len()
                        )
                    };
                    row(&mut o, "  tolerance", verdict);
                }
                None => row(
                    &mut o,
                    "verified",
                    "off (--verify off): the error is only predicted".to_string(),
                ),
            }
        }
        match &self.errors {
            Some(err) => {
                let check = self
                    .direct_check_s
                    .map(|s| format!(", {}", seconds(s)))
                    .unwrap_or_default();
                let _ = writeln!(
                    o,
                    "relative L2 error vs direct summation ({} sampled targets{check})",
                    err.n_sampled
                );
                row(&mut o, "potential", format!("{:.2e}", err.potential));
                if let Some(g) = err.gradient {
                    row(&mut o, "gradient", format!("{g:.2e}"));
                }
                if let Some(h) = err.hessian {
                    row(&mut o, "Hessian", format!("{h:.2e}"));
                }
            }
            None => {
                let _ = writeln!(o, "relative L2 error    not checked (use --check N)");
            }
        }
        let _ = writeln!(
            o,
            "peak memory          {:>10}",
            mebibytes(self.peak_rss_bytes)
        );
        if let Some(m) = &self.memory {
            m.rows(&mut o);
        }
        let _ = writeln!(o, "wall time            {:>10}", seconds(self.wall_s));
        o
    }

    /// The report as one line of JSON.
    pub fn json(&self) -> String {
        serde_json::to_string(self).expect("a report always serialises")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn number_formats() {
        assert_eq!(thousands(0), "0");
        assert_eq!(thousands(999), "999");
        assert_eq!(thousands(1000), "1,000");
        assert_eq!(thousands(1_234_567), "1,234,567");
        assert_eq!(seconds(2.5), "2.500 s");
        assert_eq!(seconds(0.0123), "12.3 ms");
        assert_eq!(seconds(0.000045), "45 us");
        assert_eq!(mebibytes(Some(3 * 1024 * 1024)), "3 MiB");
    }
}
