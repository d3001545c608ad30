//! [`Fmm`]: a built problem (tree + operators) that evaluates any number of
//! charge vectors.

use std::time::Instant;

use ferrofmm_field::{M2lInteractions, M2lScheme, Operators, surface_points};
use ferrofmm_kernels::{EvalMode, Kernel, Real};
use ferrofmm_tree::{Octree, TreeOptions};

use crate::builder::FmmBuilder;
use crate::timings::{EvalTimings, SetupTimings};
use crate::{FmmError, passes};

/// A kernel-independent FMM, built once for fixed sources, targets, kernel
/// and parameters, then evaluated for as many charge vectors as needed.
///
/// `T` is the float type (`f32` or `f64`), `K` the kernel and `S` the M2L
/// translation scheme. `Fmm` is `Sync`: [`Fmm::evaluate`] takes `&self`
/// and may be called from several threads at once.
pub struct Fmm<T: Real, K: Kernel, S: M2lScheme<T>> {
    pub(crate) kernel: K,
    pub(crate) mode: EvalMode,
    pub(crate) tree: Octree,
    pub(crate) operators: Operators<T>,
    pub(crate) m2l: S,
    /// V-list interactions per level (index = level).
    pub(crate) m2l_interactions: Vec<M2lInteractions>,
    /// Sources in Morton (leaf) order, interleaved.
    pub(crate) sources: Vec<T>,
    /// Targets in Morton (leaf) order, interleaved.
    pub(crate) targets: Vec<T>,
    /// Unit-cube surface grid (centre 0, half-width 1, radius 1), interleaved, f64.
    pub(crate) unit_surface: Vec<f64>,
    pub(crate) n_sources: usize,
    pub(crate) n_targets: usize,
    pub(crate) order: usize,
    pub(crate) leaf_size: usize,
    pub(crate) setup: SetupTimings,
}

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
}

impl<T: Real, K: Kernel, S: M2lScheme<T>> Fmm<T, K, S> {
    pub(crate) fn build(b: FmmBuilder<'_, T, K>, config: S::Config) -> Result<Self, FmmError> {
        b.validate()?;
        let t0 = Instant::now();
        let mut setup = SetupTimings::default();

        let to_f64 = |p: &[T]| p.iter().map(|x| x.to_f64()).collect::<Vec<f64>>();
        let src64 = to_f64(b.sources);
        let tgt64 = b.targets.map(to_f64);
        let options = TreeOptions {
            leaf_size: b.leaf_size,
            max_level: b.max_level,
            domain: b.domain,
            uniform_depth: None,
        };
        let tree = Octree::new(&src64, tgt64.as_deref(), &options)?;
        drop(src64);
        drop(tgt64);
        setup.tree = t0.elapsed();

        let t = Instant::now();
        let params = b.operator_params();
        let width = tree.domain().width;
        let depth = tree.depth();
        let operators = Operators::<T>::new(&b.kernel, &params, width, depth)?;
        setup.operators = t.elapsed();

        let t = Instant::now();
        let m2l = S::precompute(&b.kernel, &params, &config, width, depth)?;
        setup.m2l_precompute = t.elapsed();

        let t = Instant::now();
        let m2l_interactions = (0..=depth)
            .map(|level| level_interactions(&tree, level))
            .collect();
        let sources = permute_points(b.sources, tree.source_permutation());
        let targets = match b.targets {
            Some(t) => permute_points(t, tree.target_permutation()),
            None => sources.clone(),
        };
        let unit_surface = surface_points::<f64>(b.order, [0.0; 3], 1.0, 1.0);
        setup.layout = t.elapsed();
        setup.total = t0.elapsed();

        Ok(Fmm {
            kernel: b.kernel,
            mode: b.mode,
            n_sources: b.sources.len() / 3,
            n_targets: targets.len() / 3,
            tree,
            operators,
            m2l,
            m2l_interactions,
            sources,
            targets,
            unit_surface,
            order: b.order,
            leaf_size: b.leaf_size,
            setup,
        })
    }

    /// Potentials (and gradients, depending on the mode) at the targets for
    /// one charge per source, in the caller's original target order:
    /// `values_per_target` values per target (`[phi]` or `[phi, gx, gy, gz]`).
    ///
    /// `phi(y) = sum_i K(x_i, y) q_i` with coincident pairs excluded.
    pub fn evaluate(&self, charges: &[T]) -> Result<Vec<T>, FmmError> {
        self.evaluate_timed(charges).map(|(v, _)| v)
    }

    /// As [`Fmm::evaluate`], and the time spent in each operator.
    pub fn evaluate_timed(&self, charges: &[T]) -> Result<(Vec<T>, EvalTimings), FmmError> {
        self.check_charges(charges, 1)?;
        Ok(passes::evaluate(self, charges))
    }

    /// Evaluate `n_vectors` charge vectors stored one after another in
    /// `charges` (length `n_vectors * n_sources`); results are stored the
    /// same way (vector-major). Nothing is rebuilt between vectors.
    pub fn evaluate_many(&self, charges: &[T], n_vectors: usize) -> Result<Vec<T>, FmmError> {
        self.check_charges(charges, n_vectors)?;
        let mut out =
            Vec::with_capacity(n_vectors * self.n_targets * self.mode.values_per_target());
        for q in charges.chunks_exact(self.n_sources) {
            out.extend(passes::evaluate(self, q).0);
        }
        Ok(out)
    }

    fn check_charges(&self, charges: &[T], n_vectors: usize) -> Result<(), FmmError> {
        let expected = n_vectors * self.n_sources;
        if charges.len() != expected || n_vectors == 0 {
            return Err(FmmError::ChargeCount {
                expected,
                got: charges.len(),
            });
        }
        if let Some(index) = charges.iter().position(|q| !q.is_finite()) {
            return Err(FmmError::NonFiniteCharge {
                index,
                value: charges[index].to_f64(),
            });
        }
        Ok(())
    }

    /// The octree (plain data: keys, ranges, lists).
    pub fn tree(&self) -> &Octree {
        &self.tree
    }

    /// The kernel.
    pub fn kernel(&self) -> &K {
        &self.kernel
    }

    /// The M2L scheme.
    pub fn m2l_scheme(&self) -> &S {
        &self.m2l
    }

    /// What is evaluated.
    pub fn mode(&self) -> EvalMode {
        self.mode
    }

    /// Number of sources.
    pub fn n_sources(&self) -> usize {
        self.n_sources
    }

    /// Number of targets.
    pub fn n_targets(&self) -> usize {
        self.n_targets
    }

    /// Expansion order.
    pub fn order(&self) -> usize {
        self.order
    }

    /// Time spent building.
    pub fn setup_timings(&self) -> &SetupTimings {
        &self.setup
    }

    /// Tree and operator figures.
    pub fn summary(&self) -> FmmSummary {
        let tree = &self.tree;
        let n = tree.n_boxes();
        let count = |f: &dyn Fn(usize) -> usize| (0..n).map(f).sum::<usize>();
        FmmSummary {
            n_sources: self.n_sources,
            n_targets: self.n_targets,
            order: self.order,
            n_surface: self.operators.n_surface(),
            leaf_size: self.leaf_size,
            depth: tree.depth(),
            n_boxes: n,
            n_leaves: tree.leaves().len(),
            list_entries: [
                count(&|b| tree.u_list(b).len()),
                count(&|b| tree.v_list(b).len()),
                count(&|b| tree.w_list(b).len()),
                count(&|b| tree.x_list(b).len()),
            ],
            m2l_scheme: self.m2l.name().to_string(),
            m2l_bytes: self.m2l.memory_bytes(),
            kernel: self.kernel.name(),
            precision: T::PRECISION.name().to_string(),
        }
    }

    /// Check or equivalent surface of box `b` scaled by `radius` (a multiple
    /// of the half-width), written into `out` (interleaved).
    pub(crate) fn surface_of(&self, b: usize, radius: f64, out: &mut Vec<T>) {
        let key = self.tree.key(b);
        let domain = self.tree.domain();
        let c = key.center(domain);
        let r = key.half_width(domain) * radius;
        out.clear();
        out.extend(
            self.unit_surface
                .chunks_exact(3)
                .flat_map(|u| [c[0] + r * u[0], c[1] + r * u[1], c[2] + r * u[2]])
                .map(T::from_f64),
        );
    }
}

/// `(target column, source column, transfer vector)` for every V-list pair of a level.
fn level_interactions(tree: &Octree, level: u32) -> M2lInteractions {
    let range = tree.level_range(level);
    let mut pairs = Vec::new();
    for b in range.clone() {
        let key = tree.key(b);
        for &a in tree.v_list(b) {
            pairs.push((
                b - range.start,
                a - range.start,
                key.transfer_vector(tree.key(a)),
            ));
        }
    }
    M2lInteractions::new(range.len(), range.len(), &pairs)
}

/// Points in the tree's sorted order: `out[k] = points[perm[k]]`.
fn permute_points<T: Real>(points: &[T], perm: &[usize]) -> Vec<T> {
    perm.iter()
        .flat_map(|&i| [points[3 * i], points[3 * i + 1], points[3 * i + 2]])
        .collect()
}
