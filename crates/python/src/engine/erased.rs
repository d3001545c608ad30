//! An [`Fmm`] of any float type, kernel and M2L scheme behind the
//! object-safe [`Engine`], and its build from [`BuildOptions`].

use std::sync::Arc;

use ferrofmm_field::{
    CacheSetting, CacheStatus, DenseM2l, FftConfig, FftM2l, M2lScheme, PrecomputeMonitor, SvdM2l,
};
use ferrofmm_fmm::{
    EvalTimings, Fmm, FmmBuilder, FmmError, FmmSummary, Periodic, ProgressFn, SchemeChoice,
    SetupProgressFn, SetupTimings, StokesLayers, StokesRequest, Verification,
};
use ferrofmm_kernels::{EvalMode, Kernel, KernelChoice, KernelVisitor, SourceKind, Stokes3d};

use super::floats::{Float, Floats};

/// What one evaluation returns: the values, their timings, the energy of
/// each vector ([`Fmm::energy`]: charges of a scalar kernel at the
/// sources themselves, else `None`) and, for the first evaluation of a
/// tolerance, its verification.
pub(super) struct Evaluated {
    pub(super) values: Floats,
    pub(super) timings: EvalTimings,
    pub(super) energies: Vec<Option<f64>>,
    pub(super) verification: Option<Verification>,
}

/// An [`Fmm`] with its type parameters erased.
pub(super) trait Engine: Send + Sync {
    /// `n_vectors` charge vectors one after another; values likewise.
    fn evaluate(&self, charges: Floats, n_vectors: usize) -> Result<Evaluated, FmmError>;
    /// The first vector through [`Fmm::evaluate_verified`] (which may
    /// raise the order), the others as [`Engine::evaluate`].
    fn evaluate_verified(
        &mut self,
        charges: Floats,
        n_vectors: usize,
    ) -> Result<Evaluated, FmmError>;
    fn summary(&self) -> FmmSummary;
    /// [`Fmm::set_progress`].
    fn set_progress(&mut self, progress: Option<Arc<ProgressFn>>);
    fn setup_timings(&self) -> SetupTimings;
    fn n_sources(&self) -> usize;
    fn n_targets(&self) -> usize;
    /// Why the operator cache could not be written (one line per file).
    fn cache_write_errors(&self) -> Vec<String>;
    /// What the cache did, in words ([`CacheStatus::summary`]).
    fn cache_summary(&self) -> Option<String>;
}

impl<T: Float, K: Kernel, S: M2lScheme<T>> Engine for Fmm<T, K, S> {
    fn evaluate(&self, charges: Floats, n_vectors: usize) -> Result<Evaluated, FmmError> {
        let q = T::unwrap(charges);
        let per_vector = self.n_targets() * self.kernel().values_per_target(self.mode());
        let mut values = Vec::with_capacity(n_vectors * per_vector);
        let mut energies = Vec::with_capacity(n_vectors);
        let mut timings = EvalTimings::default();
        for one in
            q.chunks_exact(self.n_sources() * self.kernel().values_per_source(self.source_kind()))
        {
            let (v, t) = self.evaluate_timed(one)?;
            energies.push(self.energy(one, &v).ok());
            values.extend_from_slice(&v);
            timings.accumulate(&t);
        }
        Ok(Evaluated {
            values: T::wrap(values),
            timings,
            energies,
            verification: None,
        })
    }

    fn set_progress(&mut self, progress: Option<Arc<ProgressFn>>) {
        Fmm::set_progress(self, progress);
    }

    fn evaluate_verified(
        &mut self,
        charges: Floats,
        n_vectors: usize,
    ) -> Result<Evaluated, FmmError> {
        let q = T::unwrap(charges);
        let n = self.n_sources() * self.kernel().values_per_source(self.source_kind());
        let first = Fmm::evaluate_verified(self, &q[..n])?;
        let mut energies = vec![self.energy(&q[..n], &first.values).ok()];
        let mut values = first.values;
        let mut timings = first.timings;
        if n_vectors > 1 {
            let rest = Engine::evaluate(self, T::wrap(q[n..].to_vec()), n_vectors - 1)?;
            values.extend(T::unwrap(rest.values));
            energies.extend(rest.energies);
            timings.accumulate(&rest.timings);
        }
        Ok(Evaluated {
            values: T::wrap(values),
            timings,
            energies,
            verification: first.verification,
        })
    }

    fn summary(&self) -> FmmSummary {
        Fmm::summary(self)
    }

    fn setup_timings(&self) -> SetupTimings {
        *Fmm::setup_timings(self)
    }

    fn n_sources(&self) -> usize {
        Fmm::n_sources(self)
    }

    fn n_targets(&self) -> usize {
        Fmm::n_targets(self)
    }

    fn cache_summary(&self) -> Option<String> {
        CacheStatus::summary(
            self.operators().cache_status(),
            &self.m2l_scheme().cache_status(),
        )
    }

    fn cache_write_errors(&self) -> Vec<String> {
        write_errors([
            self.operators().cache_status().clone(),
            self.m2l_scheme().cache_status(),
        ])
    }
}

/// Why each of these cache files could not be written (one line each).
pub(super) fn write_errors(statuses: impl IntoIterator<Item = CacheStatus>) -> Vec<String> {
    statuses
        .into_iter()
        .filter_map(|status| match status {
            CacheStatus::Computed {
                write_error: Some(e),
                ..
            } => Some(e),
            _ => None,
        })
        .collect()
}

/// Everything a build needs besides the points.
#[derive(Clone, Debug)]
pub(super) struct BuildOptions {
    pub(super) kernel: KernelChoice,
    pub(super) scheme: SchemeChoice,
    pub(super) eps: Option<f64>,
    pub(super) order: Option<usize>,
    pub(super) leaf_size: Option<usize>,
    pub(super) mode: EvalMode,
    pub(super) source_kind: SourceKind,
    pub(super) verify: bool,
    /// `cache_dir=` / `cache="path"`, `cache=False`, else the default.
    pub(super) cache: CacheSetting,
    /// `box=` (with `box_origin=`, `periodic=`, `surface=`): the periodic
    /// cell, `None` for free space.
    pub(super) periodic: Option<Periodic>,
    /// Stokes with stresslets or the pressure ([`StokesLayers`]): what the
    /// sources carry and whether the pressure is computed; `None` for one
    /// FMM of the kernel with `source_kind`.
    pub(super) layers: Option<StokesRequest>,
}

impl BuildOptions {
    /// Values per source of one density vector.
    pub(super) fn values_per_source(&self) -> usize {
        match self.layers {
            Some(r) => super::layers::values_per_source(r.forces, r.stresslets),
            None => self.kernel.components() * self.source_kind.values_per_source(),
        }
    }

    /// Values per target of one vector.
    pub(super) fn values_per_target(&self) -> usize {
        let base = self.kernel.components() * self.mode.values_per_target();
        match self.layers {
            Some(r) if r.pressure => base + self.mode.values_per_target(),
            _ => base,
        }
    }
}

/// What watches a build: the precomputation's cancel flag (and callback)
/// and the build's progress callback.
pub(super) struct Watch {
    pub(super) monitor: PrecomputeMonitor,
    pub(super) setup: Option<Arc<SetupProgressFn>>,
}

/// Build for float type `T` from points held in `f64`: they are rounded to
/// `T` only relative to the tree's origin ([`FmmBuilder::from_f64`]), so an
/// `f32` run on points far from the origin keeps their separations.
pub(super) fn build<T: Float>(
    o: &BuildOptions,
    watch: Watch,
    sources: &[f64],
    targets: Option<&[f64]>,
) -> Result<Box<dyn Engine>, FmmError> {
    if let Some(request) = o.layers {
        return build_layers::<T>(request, o, watch, sources, targets);
    }
    o.kernel.visit(BuildWith {
        o,
        watch,
        sources,
        targets,
        float: std::marker::PhantomData::<T>,
    })
}

/// [`build`] with the kernel chosen.
struct BuildWith<'a, T> {
    o: &'a BuildOptions,
    watch: Watch,
    sources: &'a [f64],
    targets: Option<&'a [f64]>,
    float: std::marker::PhantomData<T>,
}

impl<T: Float> KernelVisitor for BuildWith<'_, T> {
    type Output = Result<Box<dyn Engine>, FmmError>;

    fn visit<K: Kernel>(self, kernel: K) -> Self::Output {
        build_with::<T, K>(kernel, self.o, self.watch, self.sources, self.targets)
    }
}

fn build_with<T: Float, K: Kernel>(
    kernel: K,
    o: &BuildOptions,
    watch: Watch,
    sources: &[f64],
    targets: Option<&[f64]>,
) -> Result<Box<dyn Engine>, FmmError> {
    let b = configure(kernel, o, watch, sources, targets);
    Ok(match resolve_scheme::<T>(o, sources, targets)? {
        SchemeChoice::Svd | SchemeChoice::Auto => Box::new(b.build_svd()?),
        SchemeChoice::Dense => Box::new(b.build_with::<DenseM2l<T>>(Default::default())?),
        SchemeChoice::Fft => Box::new(b.build_with::<FftM2l<T>>(FftConfig)?),
    })
}

/// [`build`] of Stokes forces and stresslets with the pressure.
fn build_layers<T: Float>(
    request: StokesRequest,
    o: &BuildOptions,
    watch: Watch,
    sources: &[f64],
    targets: Option<&[f64]>,
) -> Result<Box<dyn Engine>, FmmError> {
    let b = configure(Stokes3d::default(), o, watch, sources, targets);
    Ok(match resolve_scheme::<T>(o, sources, targets)? {
        SchemeChoice::Svd | SchemeChoice::Auto => {
            Box::new(StokesLayers::<T, SvdM2l<T>>::build(b, request)?)
        }
        SchemeChoice::Dense => Box::new(StokesLayers::<T, DenseM2l<T>>::build(b, request)?),
        SchemeChoice::Fft => Box::new(StokesLayers::<T, FftM2l<T>>::build(b, request)?),
    })
}

/// The builder the options describe, for `kernel`.
fn configure<'a, T: Float, K: Kernel>(
    kernel: K,
    o: &BuildOptions,
    watch: Watch,
    sources: &'a [f64],
    targets: Option<&'a [f64]>,
) -> FmmBuilder<'a, T, K> {
    let mut b = FmmBuilder::<T, _>::from_f64(sources)
        .kernel(kernel)
        .mode(o.mode)
        .source_kind(o.source_kind)
        .monitor(watch.monitor)
        .verify(o.verify);
    if let Some(f) = watch.setup {
        b = b.setup_progress(move |p| f(p));
    }
    if let Some(t) = targets {
        b = b.targets_f64(t);
    }
    if let Some(eps) = o.eps {
        b = b.tolerance(eps);
    }
    if let Some(p) = o.order {
        b = b.order(p);
    }
    if let Some(l) = o.leaf_size {
        b = b.leaf_size(l);
    }
    if let Some(cell) = o.periodic {
        b = b.periodic(cell);
    }
    b.cache(o.cache.clone())
}

/// The scheme the options ask for, `auto` resolved on these points.
fn resolve_scheme<T: Float>(
    o: &BuildOptions,
    sources: &[f64],
    targets: Option<&[f64]>,
) -> Result<SchemeChoice, FmmError> {
    // The SVD precomputation counts as free only with a folder the user
    // named (the default folder may be cold).
    let cached = matches!(o.cache, CacheSetting::Dir(_));
    // A periodic run's tree is built on the points wrapped into its cell:
    // the cost model sees those.
    let wrapped = o
        .periodic
        .map(|cell| (cell.wrap_all(sources), targets.map(|t| cell.wrap_all(t))));
    let (sources, targets) = match &wrapped {
        Some((s, t)) => (s.as_slice(), t.as_deref()),
        None => (sources, targets),
    };
    o.scheme.resolve(
        o.kernel,
        ferrofmm_fmm::effective_tolerance(o.eps, o.order, T::PRECISION),
        o.order,
        Some((sources, targets)),
        o.mode,
        T::PRECISION,
        cached,
        ferrofmm_fmm::tuning::MachineCalibration::from_cache(&o.cache).as_ref(),
    )
}
