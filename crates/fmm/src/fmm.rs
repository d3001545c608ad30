//! [`Fmm`]: a built problem (tree + operators) that evaluates any number of
//! charge vectors.

use std::borrow::Cow;
use std::sync::Arc;
use std::time::Instant;

use ferrofmm_field::{M2lScheme, OperatorParams, Operators, surface_points};
use ferrofmm_kernels::{EvalMode, Kernel, Precision, Real, SourceKind};
use ferrofmm_tree::{Domain, Octree};

use crate::builder::FmmBuilder;
use crate::coordinates::Coordinates;
use crate::memory::MemoryReport;
use crate::part::{
    Body, Part, PartInput, TreePart, build_tree_part, clusters_of, gather, points_part,
};
use crate::periodic::FarImages;
use crate::precompute::build_operators;
use crate::progress::ProgressFn;
use crate::timings::{EvalTimings, SetupTimings};
use crate::tuning::{self, ChosenParameters, ErrorModel, Tuner};
use crate::validate::{check_domain_width, check_wavenumber};
use crate::verify::Verification;
use crate::{FmmError, passes};

/// How a scheme follows parameters chosen for a tolerance (the SVD
/// tolerance of [`crate::FmmBuilder::build_svd`]), also when verification
/// raises the order; schemes given to [`crate::FmmBuilder::build_with`]
/// keep their configuration (`None`).
pub(crate) struct ChosenScheme<C, S> {
    /// The configuration for the chosen parameters.
    pub(crate) config: fn(&ChosenParameters) -> C,
    /// The rank the built scheme reports (for [`ChosenParameters::svd_rank`]).
    pub(crate) rank: fn(&S) -> usize,
}

/// [`ChosenScheme`] when there is one.
pub(crate) type ConfigFromChosen<C, S> = Option<ChosenScheme<C, S>>;

/// A kernel-independent FMM, built once for fixed sources, targets, kernel
/// and parameters, then evaluated for as many charge vectors as needed.
///
/// `T` is the float type (`f32` or `f64`), `K` the kernel and `S` the M2L
/// translation scheme. `Fmm` is `Sync`: [`Fmm::evaluate`] takes `&self`
/// and may be called from several threads at once.
pub struct Fmm<T: Real, K: Kernel, S: M2lScheme<T>> {
    pub(crate) kernel: K,
    pub(crate) mode: EvalMode,
    /// What each source carries (densities per source).
    pub(crate) source_kind: SourceKind,
    /// The far-separated clusters of the problem ([`crate::part`]); part 0
    /// is the largest and always has a tree. One part for most inputs.
    pub(crate) parts: Vec<Part<T, S>>,
    /// Whether targets were given apart from the sources.
    pub(crate) separate_targets: bool,
    /// Unit-cube surface grid (centre 0, half-width 1, radius 1), interleaved, f64.
    pub(crate) unit_surface: Vec<f64>,
    pub(crate) n_sources: usize,
    pub(crate) n_targets: usize,
    pub(crate) order: usize,
    pub(crate) leaf_size: usize,
    pub(crate) setup: SetupTimings,
    /// Parameters chosen for a tolerance (`None`: given by the caller).
    pub(crate) chosen: Option<ChosenParameters>,
    /// Operator parameters as built (the order among them).
    pub(crate) params: OperatorParams,
    /// The M2L configuration as built.
    pub(crate) config: S::Config,
    /// How to remake it for new chosen parameters (see [`ConfigFromChosen`]).
    pub(crate) config_from_chosen: ConfigFromChosen<S::Config, S>,
    /// Whether [`Fmm::evaluate_verified`] checks a tolerance.
    pub(crate) verify: bool,
    /// The error model the parameters were chosen with (`None`: given by
    /// the caller); the verification raises the order with it.
    pub(crate) error_model: Option<ErrorModel>,
    /// The last verification (see [`Fmm::evaluate_verified`]).
    pub(crate) verification: Option<Verification>,
    /// The far images of a periodic cell ([`crate::periodic`]); `None` in
    /// free space.
    pub(crate) periodic: Option<FarImages>,
    /// Told the progress of each evaluation ([`Fmm::set_progress`]).
    pub(crate) progress: Option<Arc<ProgressFn>>,
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
    /// The parameters chosen for [`FmmBuilder::tolerance`] (`null` when
    /// they were given).
    pub chosen: Option<ChosenParameters>,
    /// The last after-the-fact check of the tolerance by
    /// [`Fmm::evaluate_verified`] (`null` before one, or when off).
    pub verification: Option<Verification>,
    /// Bytes of the big buffers (see [`Fmm::memory`]).
    pub memory: MemoryReport,
}

impl<T: Real, K: Kernel, S: M2lScheme<T>> Fmm<T, K, S> {
    /// Build with the scheme configuration `config`, or, when parameters
    /// are chosen for a tolerance and `from_chosen` is given, the one it
    /// makes from them.
    pub(crate) fn build(
        mut b: FmmBuilder<'_, T, K>,
        config: S::Config,
        from_chosen: ConfigFromChosen<S::Config, S>,
    ) -> Result<Self, FmmError> {
        b.validate()?;
        // A run whose points alone cannot fit is refused before anything
        // is allocated for them (the operators are checked later, once
        // the tree says which are needed).
        let size = crate::RunSize {
            n_sources: b.sources.len() / 3,
            n_targets: b.targets.map(|t| t.len() / 3),
            values_per_source: b.kernel.values_per_source(b.source_kind),
            values_per_target: b.kernel.values_per_target(b.mode),
            n_vectors: 1,
        };
        crate::check_memory(
            MemoryReport::predict::<T>(&size),
            b.memory_limit,
            &format!(
                "an FMM of {} points",
                size.n_sources + size.n_targets.unwrap_or(0)
            ),
        )?;
        let t0 = Instant::now();
        let mut setup = SetupTimings::default();

        // Every point in f64 (borrowed when given so): the tree is built on
        // them and the run's float type only sees coordinates relative to
        // the tree's origin (see `crate::coordinates`).
        let mut src64 = b.sources.to_f64();
        let mut tgt64 = b.targets.map(Coordinates::to_f64);
        // A periodic run: every point wrapped into the cell, which is the
        // tree's domain (so one cluster).
        if let Some(cell) = &b.periodic {
            src64 = Cow::Owned(cell.wrap_all(&src64));
            tgt64 = tgt64.map(|t| Cow::Owned(cell.wrap_all(&t)));
            b.domain = Some(cell.domain()?);
        }
        let clusters = clusters_of(&src64, tgt64.as_deref(), b.domain.is_some());
        let mut error_model = None;
        // What is chosen: nothing when the caller gave both the order and
        // the leaf size without a tolerance; else the rest, for the
        // tolerance (or the default one, unless the order is given).
        let eps = crate::builder::effective_tolerance(
            b.tolerance,
            b.order_given.then_some(b.order),
            T::PRECISION,
        );
        let tune = !(b.order_given && b.leaf_given && b.tolerance.is_none());
        let chosen = if tune {
            let main = &clusters[0];
            let t = Instant::now();
            let (s, tg) = match (&clusters.len(), &tgt64) {
                (1, _) => (None, None),
                (_, Some(t)) => (
                    Some(gather(&src64, &main.sources)),
                    Some(gather(t, &main.targets)),
                ),
                (_, None) => (Some(gather(&src64, &main.sources)), None),
            };
            let model = match &b.tuning_model {
                Some(m) => m.clone(),
                None => {
                    let width = match (b.domain, &tgt64) {
                        (Some(d), _) => d.width,
                        (None, Some(t)) => Domain::from_points(&[&src64[..], t])?.width,
                        (None, None) => Domain::from_points(&[&src64[..]])?.width,
                    };
                    // The build's own checks first: the model has no
                    // order for a domain beyond the float type or a
                    // wavenumber beyond the low-frequency limit, and
                    // would only say "no order reaches eps".
                    check_domain_width(width, T::PRECISION, 0)?;
                    check_wavenumber(&b.kernel, width)?;
                    tuning::default_model(&b.kernel, width)
                }
            };
            // A dipole's potential is a derivative of a charge's: its
            // error follows the gradient's (measured, see
            // `examples/sources_sweep.rs`), so dipoles are modelled
            // with the gradient's table at least.
            let model_mode = match (b.source_kind.has_dipoles(), b.mode) {
                (true, EvalMode::Potential) => EvalMode::PotentialGradient,
                (_, mode) => mode,
            };
            let mut tuner = Tuner::from_model(model, T::PRECISION, model_mode, S::COST_SHAPE);
            if b.order_given {
                tuner = tuner.with_order(b.order);
            }
            if b.leaf_given {
                tuner = tuner.with_leaf_size(b.leaf_size);
            }
            error_model = Some(tuner.error.clone());
            let tune_sources = s.as_deref().unwrap_or(&src64);
            let tune_targets = if clusters.len() == 1 {
                tgt64.as_deref()
            } else {
                tg.as_deref()
            };
            // A root wider than the bounding cube is weighed where the
            // tree is ours to shape (`tuning::choose_root`).
            let widen = b.domain.is_none()
                && b.periodic.is_none()
                && clusters.len() == 1
                && !b.leaf_given
                && b.kernel.homogeneity().is_some()
                && b.root_search.unwrap_or(
                    size.n_sources + size.n_targets.unwrap_or(0) >= tuning::ROOT_SEARCH_MIN_POINTS,
                );
            let mut c = if widen {
                // The memory left for the boxes beside the points' buffers.
                let box_budget = tuning::box_budget::<T>(
                    b.memory_limit.resolve()?,
                    &size,
                    S::COST_SHAPE == tuning::M2lCostShape::Fft,
                );
                let fits = |c: &tuning::ChosenParameters| {
                    box_budget.is_none_or(|room| {
                        let n = ferrofmm_field::expansion_len(&b.kernel, c.order);
                        tuning::box_bytes(&c.estimated_work, n, T::PRECISION) <= room
                    })
                };
                let (c, root) = tuning::choose_root(
                    &tuner,
                    eps,
                    tune_sources,
                    tune_targets,
                    b.max_level,
                    fits,
                )?;
                b.domain = root;
                c
            } else {
                let occupancy =
                    tuning::Occupancy::new(tune_sources, tune_targets, b.domain, b.max_level)?;
                tuner.choose_for(eps, &occupancy)?
            };
            // A direct sum is a candidate when the leaf size is ours to
            // choose, the points are one cluster (far clusters keep their
            // own trees and coordinate origins) and the float type is
            // f64 (an f32 sum over every pair of a large set rounds more
            // than the FMM's near field does). The operators of a
            // homogeneous kernel are counted unless a cache keeps them
            // (one set serves every domain); a kernel with operators per
            // level and domain width pays them on every new set of points.
            if b.allow_direct
                && b.periodic.is_none()
                && !b.leaf_given
                && clusters.len() == 1
                && T::PRECISION == Precision::F64
            {
                let cached = !matches!(b.cache, ferrofmm_field::CacheSetting::Off)
                    && b.kernel.homogeneity().is_some();
                let precompute = if cached {
                    0.0
                } else {
                    tuning::precompute_seconds(&b.kernel, S::COST_SHAPE, &c)
                };
                c = tuner.prefer_direct(
                    c,
                    b.sources.len() / 3,
                    b.targets.map_or(b.sources.len(), |t| t.len()) / 3,
                    precompute,
                );
            }
            b.order = c.order;
            b.leaf_size = c.leaf_size;
            setup.tuning = t.elapsed();
            Some(c)
        } else {
            None
        };
        // Verification checks a tolerance: none to check with an order alone.
        b.verify &= eps.is_some();
        let config = match (&chosen, &from_chosen) {
            (Some(c), Some(f)) => (f.config)(c),
            _ => config,
        };
        let params = b.operator_params()?;
        let mut parts = Vec::with_capacity(clusters.len());
        let mut first_rank = None;
        let single = clusters.len() == 1;
        for (k, cluster) in clusters.iter().enumerate() {
            let input = PartInput {
                src64: &src64,
                tgt64: tgt64.as_deref(),
                ids: (!single).then_some(cluster),
            };
            let part = if k == 0 || cluster.size() > b.leaf_size {
                let t = build_tree_part(&b, &params, &config, &input, &mut setup)?;
                if first_rank.is_none()
                    && let Some(f) = &from_chosen
                {
                    first_rank = Some((f.rank)(&t.m2l));
                }
                Body::Tree(Box::new(t))
            } else {
                Body::Points(points_part(&input))
            };
            parts.push(Part {
                body: part,
                n_sources: if single {
                    b.sources.len() / 3
                } else {
                    cluster.sources.len()
                },
                n_targets: if single {
                    b.targets.map_or(b.sources.len(), |t| t.len()) / 3
                } else {
                    cluster.targets.len()
                },
                source_ids: (!single).then(|| cluster.sources.clone()),
                target_ids: (!single).then(|| cluster.targets.clone()),
            });
        }
        drop(src64);
        drop(tgt64);
        let mut chosen = chosen;
        if let (Some(c), Some(r)) = (chosen.as_mut(), first_rank) {
            c.svd_rank = Some(r);
        }
        let t = Instant::now();
        let unit_surface = surface_points::<f64>(b.order, [0.0; 3], 1.0, 1.0);
        setup.layout += t.elapsed();
        let periodic = match &b.periodic {
            Some(cell) => {
                let t = Instant::now();
                let far = far_images(cell, b.order, &parts)?;
                setup.operators += t.elapsed();
                Some(far)
            }
            None => None,
        };
        setup.total = t0.elapsed();

        Ok(Fmm {
            kernel: b.kernel,
            mode: b.mode,
            source_kind: b.source_kind,
            n_sources: b.sources.len() / 3,
            n_targets: b.targets.map_or(b.sources.len(), |t| t.len()) / 3,
            parts,
            separate_targets: b.targets.is_some(),
            unit_surface,
            order: b.order,
            leaf_size: b.leaf_size,
            setup,
            chosen,
            params,
            config,
            config_from_chosen: from_chosen,
            verify: b.verify,
            error_model,
            verification: None,
            periodic,
            progress: None,
        })
    }

    /// Rebuild the operators and the M2L scheme at `order` (the tree, the
    /// lists and the points stay): what verification does when the
    /// achieved error is above the tolerance. Updates the chosen
    /// parameters (order, SVD tolerance, predicted error, rank).
    pub(crate) fn rebuild_at_order(&mut self, chosen: ChosenParameters) -> Result<(), FmmError> {
        let mut params = self.params.clone();
        params.order = chosen.order;
        let mut chosen = chosen;
        let config = match &self.config_from_chosen {
            Some(f) => (f.config)(&chosen),
            None => self.config.clone(),
        };
        let mut setup = self.setup;
        let mut rebuilt = Vec::new();
        for part in &self.parts {
            if let Some(t) = part.tree_part() {
                let mut s = SetupTimings::default();
                rebuilt.push(build_operators(
                    &self.kernel,
                    &params,
                    &config,
                    &t.tree,
                    &t.needs,
                    &mut s,
                )?);
                setup.operators += s.operators;
                setup.m2l_precompute += s.m2l_precompute;
            }
        }
        let mut rebuilt = rebuilt.into_iter();
        for part in &mut self.parts {
            if let Body::Tree(t) = &mut part.body {
                let (operators, m2l) = rebuilt.next().expect("one set per tree part");
                t.operators = operators;
                t.m2l = m2l;
            }
        }
        self.unit_surface = surface_points::<f64>(chosen.order, [0.0; 3], 1.0, 1.0);
        if let Some(far) = &self.periodic {
            let t = Instant::now();
            self.periodic = Some(far_images(&far.cell, chosen.order, &self.parts)?);
            setup.operators += t.elapsed();
            self.setup.operators = setup.operators;
        }
        self.order = chosen.order;
        self.params = params;
        self.config = config;
        if let Some(f) = &self.config_from_chosen {
            chosen.svd_rank = Some((f.rank)(&self.main().m2l));
        }
        self.setup.operators = setup.operators;
        self.setup.m2l_precompute = setup.m2l_precompute;
        self.chosen = Some(chosen);
        Ok(())
    }

    /// What the passes read besides a tree part.
    /// Values in one box's expansion: one per surface point and kernel
    /// [component](Kernel::components).
    pub(crate) fn expansion_len(&self) -> usize {
        self.kernel.components() * (self.unit_surface.len() / 3)
    }

    pub(crate) fn ctx(&self) -> passes::Ctx<'_, K> {
        passes::Ctx {
            kernel: &self.kernel,
            mode: self.mode,
            kind: self.source_kind,
            unit_surface: &self.unit_surface,
        }
    }

    /// The largest cluster's tree part (part 0 always has a tree).
    pub(crate) fn main(&self) -> &TreePart<T, S> {
        self.parts[0]
            .tree_part()
            .expect("the largest cluster has a tree")
    }

    /// Potentials (and gradients and Hessians, depending on the mode) at
    /// the targets for one charge per source (or the densities of the
    /// [source kind](FmmBuilder::source_kind): `[nx, ny, nz]` or
    /// `[q, nx, ny, nz]` per source), in the caller's original target
    /// order: `values_per_target` values per target (`[phi]`,
    /// `[phi, gx, gy, gz]`, or those and `[H11, H22, H33, H12, H13, H23]`).
    ///
    /// `phi(y) = sum_i q_i K(x_i, y) + n_i . grad_x K(x_i, y)` with
    /// coincident pairs excluded.
    pub fn evaluate(&self, charges: &[T]) -> Result<Vec<T>, FmmError> {
        self.evaluate_timed(charges).map(|(v, _)| v)
    }

    /// Tell `f` the progress of every later evaluation (from worker
    /// threads, at most about a thousand times an evaluation; the work is
    /// weighted by a rough cost estimate of each pass), or stop telling
    /// with `None`. Costs nothing measurable and changes no result.
    pub fn set_progress(&mut self, f: Option<Arc<ProgressFn>>) {
        self.progress = f;
    }

    /// As [`Fmm::evaluate`], and the time spent in each operator.
    pub fn evaluate_timed(&self, charges: &[T]) -> Result<(Vec<T>, EvalTimings), FmmError> {
        self.check_charges(charges, 1)?;
        let (values, timings) = passes::evaluate(self, charges);
        let per_target = self.kernel.values_per_target(self.mode);
        crate::check_finite_output(&values, per_target, charges)?;
        Ok((values, timings))
    }

    /// Evaluate `n_vectors` charge vectors stored one after another in
    /// `charges` (length `n_vectors * n_sources`); results are stored the
    /// same way (vector-major). Nothing is rebuilt between vectors.
    pub fn evaluate_many(&self, charges: &[T], n_vectors: usize) -> Result<Vec<T>, FmmError> {
        self.check_charges(charges, n_vectors)?;
        let mut out = Vec::with_capacity(
            n_vectors * self.n_targets * self.kernel.values_per_target(self.mode),
        );
        for q in
            charges.chunks_exact(self.n_sources * self.kernel.values_per_source(self.source_kind))
        {
            let values = passes::evaluate(self, q).0;
            crate::check_finite_output(&values, self.kernel.values_per_target(self.mode), q)?;
            out.extend(values);
        }
        Ok(out)
    }

    fn check_charges(&self, charges: &[T], n_vectors: usize) -> Result<(), FmmError> {
        let per_source = self.kernel.values_per_source(self.source_kind);
        let expected = n_vectors * self.n_sources * per_source;
        if charges.len() != expected || n_vectors == 0 {
            if self.source_kind == SourceKind::Charge && per_source == 1 {
                return Err(FmmError::ChargeCount {
                    expected,
                    got: charges.len(),
                });
            }
            return Err(FmmError::DensityCount {
                kind: self.source_kind.name(),
                per_source,
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
        if self.periodic.is_some() {
            for q in charges.chunks(self.n_sources * per_source) {
                crate::periodic::check_neutral(q)?;
            }
        }
        Ok(())
    }

    /// The periodic cell of a periodic run ([`FmmBuilder::periodic`]).
    pub fn periodic(&self) -> Option<&crate::periodic::Periodic> {
        self.periodic.as_ref().map(|f| &f.cell)
    }

    /// The energy `E = 1/2 sum_i q_i phi_i` of charges `charges` whose
    /// potentials (one vector, `values` as [`Fmm::evaluate`] returned them)
    /// are `phi`: the electrostatic energy of the set (the kernel's own
    /// constant included, `1 / (4 pi r)` for Laplace; in a periodic cell,
    /// per cell).
    ///
    /// # Errors
    /// [`FmmError::InvalidParameter`] when the targets are not the
    /// sources, the sources are not charges or the kernel has more than
    /// one component; [`FmmError::ChargeCount`] for lengths that do not
    /// match.
    pub fn energy(&self, charges: &[T], values: &[T]) -> Result<f64, FmmError> {
        if self.separate_targets
            || self.source_kind != SourceKind::Charge
            || self.kernel.components() != 1
        {
            return Err(FmmError::InvalidParameter(
                "an energy needs charges of a scalar kernel evaluated at the sources themselves"
                    .to_string(),
            ));
        }
        let w = self.kernel.values_per_target(self.mode);
        if charges.len() != self.n_sources || values.len() != w * self.n_sources {
            return Err(FmmError::ChargeCount {
                expected: self.n_sources,
                got: charges.len(),
            });
        }
        Ok(0.5
            * charges
                .iter()
                .zip(values.chunks_exact(w))
                .map(|(q, v)| q.to_f64() * v[0].to_f64())
                .sum::<f64>())
    }

    /// The octree (plain data: keys, ranges, lists) of the largest
    /// cluster: the whole problem unless it has far-separated clusters
    /// (see [`Fmm::n_clusters`]).
    pub fn tree(&self) -> &Octree {
        &self.main().tree
    }

    /// Number of far-separated clusters the problem was split into: 1 for
    /// most inputs; more when a group of points lies at least 256 times
    /// its own width (and the rest's) away. Each cluster with more than
    /// `leaf_size` points has a tree of its own; the clusters interact
    /// through their roots' expansions.
    pub fn n_clusters(&self) -> usize {
        self.parts.len()
    }

    /// The check-to-equivalent and parent/child operators (their
    /// [`Operators::diagnostics`] and [`Operators::cache_status`]) of the
    /// largest cluster's tree.
    pub fn operators(&self) -> &Operators<T> {
        &self.main().operators
    }

    /// The kernel.
    pub fn kernel(&self) -> &K {
        &self.kernel
    }

    /// The M2L scheme (of the largest cluster's tree).
    pub fn m2l_scheme(&self) -> &S {
        &self.main().m2l
    }

    /// What is evaluated.
    pub fn mode(&self) -> EvalMode {
        self.mode
    }

    /// What each source carries (see [`FmmBuilder::source_kind`]).
    pub fn source_kind(&self) -> SourceKind {
        self.source_kind
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

    /// The parameters chosen for [`FmmBuilder::tolerance`] (with the built
    /// SVD rank when built by [`FmmBuilder::build_svd`]); `None` when the
    /// caller gave them.
    pub fn chosen_parameters(&self) -> Option<&ChosenParameters> {
        self.chosen.as_ref()
    }

    /// Leaf size the tree was built with.
    pub fn leaf_size(&self) -> usize {
        self.leaf_size
    }

    /// An accounting of the big buffers, in bytes: what is held between
    /// evaluations and what one evaluation allocates. Every per-box buffer
    /// is sized by the boxes that exist (boxes holding points), never by
    /// `8^depth`.
    pub fn memory(&self) -> MemoryReport {
        MemoryReport::of(self)
    }

    /// Total of [`Fmm::memory`]: bytes held plus bytes one evaluation allocates.
    pub fn memory_bytes(&self) -> usize {
        self.memory().total
    }

    /// Time spent building.
    pub fn setup_timings(&self) -> &SetupTimings {
        &self.setup
    }

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
                // The V entries live in the M2L interactions (the tree's
                // V lists are handed over to them).
                main.m2l_interactions
                    .iter()
                    .map(ferrofmm_field::M2lInteractions::len)
                    .sum(),
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

/// The far images of a periodic run at `order`, for the surfaces of its
/// tree's operators.
fn far_images<T: Real, S: M2lScheme<T>>(
    cell: &crate::periodic::Periodic,
    order: usize,
    parts: &[Part<T, S>],
) -> Result<FarImages, FmmError> {
    let radii = parts[0]
        .tree_part()
        .expect("a periodic run has one tree")
        .operators
        .radii();
    FarImages::new(*cell, order, radii.upward_equivalent, radii.downward_check)
}
