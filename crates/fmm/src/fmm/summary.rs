//! [`FmmSummary`]: the figures that describe a built [`Fmm`].

use ferrofmm_field::M2lScheme;
use ferrofmm_kernels::{Kernel, Real};

use crate::memory::MemoryReport;
use crate::part::Part;
use crate::tuning::ChosenParameters;
use crate::verify::Verification;

use super::Fmm;

/// Figures that describe a built [`Fmm`] (for reports and JSON output).
#[derive(Clone, Debug, serde::Serialize)]
pub struct FmmSummary {
    /// Number of sources.
    pub n_sources: usize,
    /// Number of targets.
    pub n_targets: usize,
    /// Expansion order.
    pub order: usize,
    /// Equivalent/check points per box.
    pub n_surface: usize,
    /// Far-separated clusters (see [`Fmm::n_clusters`]); 1 for most
    /// inputs. The tree figures below are the largest cluster's.
    pub clusters: usize,
    /// Sources plus targets outside the largest cluster.
    pub far_points: usize,
    /// Points per leaf at most (except at the deepest level).
    pub leaf_size: usize,
    /// Deepest level of the tree.
    pub depth: u32,
    /// Boxes in the tree.
    pub n_boxes: usize,
    /// Leaves in the tree.
    pub n_leaves: usize,
    /// Total entries of the U, V, W and X lists.
    pub list_entries: [usize; 4],
    /// Name of the M2L scheme.
    pub m2l_scheme: String,
    /// Bytes held by the M2L operators.
    pub m2l_bytes: usize,
    /// Kernel name.
    pub kernel: String,
    /// `f32` or `f64`.
    pub precision: String,
    /// The parameters chosen for [`FmmBuilder::tolerance`](crate::FmmBuilder::tolerance) (`null` when
    /// they were given).
    pub chosen: Option<ChosenParameters>,
    /// The last after-the-fact check of the tolerance by
    /// [`Fmm::evaluate_verified`] (`null` before one, or when off).
    pub verification: Option<Verification>,
    /// Bytes of the big buffers (see [`Fmm::memory`]).
    pub memory: MemoryReport,
}

impl<T: Real, K: Kernel, S: M2lScheme<T>> Fmm<T, K, S> {
    /// Tree and operator figures.
    pub fn summary(&self) -> FmmSummary {
        let main = self.main();
        let tree = &main.tree;
        let n = tree.n_boxes();
        let count = |f: &dyn Fn(usize) -> usize| (0..n).map(f).sum::<usize>();
        FmmSummary {
            n_sources: self.n_sources,
            n_targets: self.n_targets,
            order: self.order,
            n_surface: main.operators.n_surface(),
            clusters: self.parts.len(),
            far_points: self.parts[1..]
                .iter()
                .map(|p| p.n_sources + p.n_targets)
                .sum(),
            leaf_size: self.leaf_size,
            depth: tree.depth(),
            n_boxes: n,
            n_leaves: tree.leaves().len(),
            list_entries: [
                count(&|b| tree.u_list(b).len()),
                main.m2l_pairs(),
                count(&|b| tree.w_list(b).len()),
                count(&|b| tree.x_list(b).len()),
            ],
            m2l_scheme: main.m2l.name().to_string(),
            m2l_bytes: self
                .parts
                .iter()
                .filter_map(Part::tree_part)
                .map(|t| t.m2l.memory_bytes())
                .sum(),
            kernel: self.kernel.name(),
            precision: T::PRECISION.name().to_string(),
            chosen: self.chosen.clone(),
            verification: self.verification.clone(),
            memory: self.memory(),
        }
    }
}
