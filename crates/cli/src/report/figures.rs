//! The parts of a [`RunReport`](super::RunReport): memory, tree, setup and
//! evaluation times, errors, each as its JSON object.

use std::time::Duration;

use ferrofmm_fmm::{EvalTimings, FmmSummary, SetupTimings};

use serde::{Deserialize, Serialize};

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
    /// Relative L2 error of the Stokes pressure (`None` without
    /// `--pressure`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pressure: Option<f64>,
    /// Relative L2 error of its gradient (`None` without `--pressure
    /// --gradients`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pressure_gradient: Option<f64>,
}
