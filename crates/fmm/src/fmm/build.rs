//! Building an [`Fmm`] from a builder (tree, parameters, operators, M2L
//! scheme, far images) and rebuilding its operators at another order.

use std::borrow::Cow;
use std::time::Instant;

use ferrofmm_field::{M2lScheme, surface_points};
use ferrofmm_kernels::{EvalMode, Kernel, Precision, Real};
use ferrofmm_tree::Domain;

use crate::builder::FmmBuilder;
use crate::coordinates::Coordinates;
use crate::memory::MemoryReport;
use crate::part::{Body, Part, PartInput, build_tree_part, clusters_of, gather, points_part};
use crate::periodic::FarImages;
use crate::precompute::build_operators;
use crate::timings::SetupTimings;
use crate::tuning::{self, ChosenParameters, Tuner};
use crate::validate::{check_domain_width, check_wavenumber};
use crate::{FmmError, SetupStep};

use super::{ConfigFromChosen, Fmm};

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
            cell.check_open_axes("source", &src64)?;
            if let Some(t) = &tgt64 {
                cell.check_open_axes("target", t)?;
            }
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
        let reporter = b.setup_progress.clone();
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
            let mut tuner = Tuner::from_model(model, T::PRECISION, model_mode, S::COST_SHAPE)
                .with_calibration(b.machine_calibration());
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
                        let bytes = tuning::box_bytes(&c.estimated_work, n, T::PRECISION);
                        bytes <= room
                    })
                };
                let (c, root) = tuning::choose_root_reporting(
                    &tuner,
                    eps,
                    tune_sources,
                    tune_targets,
                    b.max_level,
                    fits,
                    &|done, total| reporter.report(SetupStep::Tuning, done, total),
                )?;
                b.domain = root;
                c
            } else {
                reporter.report(SetupStep::Tuning, 0, 1);
                let occupancy =
                    tuning::Occupancy::new(tune_sources, tune_targets, b.domain, b.max_level)?;
                let c = tuner.choose_for(eps, &occupancy)?;
                reporter.report(SetupStep::Tuning, 1, 1);
                c
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
                let far = far_images(cell, &b.kernel, &params, &parts)?;
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
            self.periodic = Some(far_images(&far.cell, &self.kernel, &params, &self.parts)?);
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
}

/// The far images of a periodic run of `kernel` at `order`, for the
/// surfaces of its tree's operators.
fn far_images<T: Real, K: Kernel, S: M2lScheme<T>>(
    cell: &crate::periodic::Periodic,
    kernel: &K,
    params: &ferrofmm_field::OperatorParams,
    parts: &[Part<T, S>],
) -> Result<FarImages, FmmError> {
    let lattice = crate::periodic::required_lattice(kernel)?;
    let operators = &parts[0]
        .tree_part()
        .expect("a periodic run has one tree")
        .operators;
    let (far, _) = FarImages::new(
        *cell,
        lattice,
        kernel,
        params,
        *operators.radii(),
        operators.rcond(),
    )?;
    Ok(far)
}
