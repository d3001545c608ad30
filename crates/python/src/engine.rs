//! `NativeFmm`: one built [`Fmm`] of any float type, kernel and M2L
//! scheme behind one object-safe trait, evaluated many times.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, RwLock};

use ferrofmm_field::{
    CacheLocation, CacheOff, CacheSetting, CacheStatus, DenseM2l, FftConfig, FftM2l, M2lScheme,
    PrecomputeMonitor,
};
use ferrofmm_fmm::{
    EvalProgress, EvalTimings, Fmm, FmmBuilder, FmmError, FmmSummary, Periodic, PeriodicAxes,
    ProgressFn, SchemeChoice, SetupTimings, SurfaceTerm, Verification,
};
use ferrofmm_kernels::{EvalMode, Kernel, KernelChoice, KernelVisitor, Real, SourceKind};
use numpy::{Element, PyArray1, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::{PyMemoryError, PyRuntimeWarning, PyTypeError, PyValueError};
use pyo3::prelude::*;
use serde_json::{Value, json};

use crate::errors::fmm_error;
use crate::limits::check_cache_dir;
use crate::run::{Threads, interruptible, interruptible_polling};

/// A float type a run can use: the library's [`Real`] and a NumPy element.
pub(crate) trait Float: Real + Element {
    /// Wrap owned values.
    fn wrap(values: Vec<Self>) -> Floats;
    /// The values of `f` in this type (copied only when the types differ).
    fn unwrap(f: Floats) -> Vec<Self>;
}

impl Float for f32 {
    fn wrap(values: Vec<Self>) -> Floats {
        Floats::F32(values)
    }
    fn unwrap(f: Floats) -> Vec<Self> {
        match f {
            Floats::F32(v) => v,
            Floats::F64(v) => v.into_iter().map(|x| x as f32).collect(),
        }
    }
}

impl Float for f64 {
    fn wrap(values: Vec<Self>) -> Floats {
        Floats::F64(values)
    }
    fn unwrap(f: Floats) -> Vec<Self> {
        match f {
            Floats::F64(v) => v,
            Floats::F32(v) => v.into_iter().map(f64::from).collect(),
        }
    }
}

/// Values of either float type.
pub(crate) enum Floats {
    F32(Vec<f32>),
    F64(Vec<f64>),
}

impl Floats {
    /// A flat, C-contiguous `float32` or `float64` NumPy array, copied.
    pub(crate) fn from_numpy(what: &str, array: &Bound<'_, PyAny>) -> PyResult<Self> {
        if let Ok(a) = array.extract::<PyReadonlyArray1<'_, f64>>() {
            return Ok(Floats::F64(try_copy(what, contiguous(what, &a)?)?));
        }
        if let Ok(a) = array.extract::<PyReadonlyArray1<'_, f32>>() {
            return Ok(Floats::F32(try_copy(what, contiguous(what, &a)?)?));
        }
        Err(PyTypeError::new_err(format!(
            "{what} must be a one-dimensional float32 or float64 NumPy array"
        )))
    }

    /// The NumPy array of these values (moved, not copied).
    fn into_numpy(self, py: Python<'_>) -> Bound<'_, PyAny> {
        match self {
            Floats::F32(v) => PyArray1::from_vec(py, v).into_any(),
            Floats::F64(v) => PyArray1::from_vec(py, v).into_any(),
        }
    }

    /// The values in `f64` (f32 widens exactly).
    pub(crate) fn into_f64(self) -> Vec<f64> {
        f64::unwrap(self)
    }

    fn len(&self) -> usize {
        match self {
            Floats::F32(v) => v.len(),
            Floats::F64(v) => v.len(),
        }
    }
}

/// A copy of `values`, or `MemoryError` when it cannot be allocated
/// (never the abort of a failed infallible allocation).
pub(crate) fn try_copy<T: Copy>(what: &str, values: &[T]) -> PyResult<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(values.len()).map_err(|_| {
        PyMemoryError::new_err(format!(
            "cannot allocate {} bytes for a copy of {what} ({} values)",
            std::mem::size_of_val(values),
            values.len()
        ))
    })?;
    v.extend_from_slice(values);
    Ok(v)
}

fn contiguous<'a, T: Element>(what: &str, a: &'a PyReadonlyArray1<'_, T>) -> PyResult<&'a [T]> {
    a.as_slice().map_err(|_| {
        PyValueError::new_err(format!(
            "{what} must be contiguous (got strides {:?})",
            a.strides()
        ))
    })
}

/// What one evaluation returns: the values, their timings, the energy of
/// each vector ([`Fmm::energy`]: charges of a scalar kernel at the
/// sources themselves, else `None`) and, for the first evaluation of a
/// tolerance, its verification.
struct Evaluated {
    values: Floats,
    timings: EvalTimings,
    energies: Vec<Option<f64>>,
    verification: Option<Verification>,
}

/// An [`Fmm`] with its type parameters erased.
trait Engine: Send + Sync {
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
        [
            self.operators().cache_status().clone(),
            self.m2l_scheme().cache_status(),
        ]
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
}

/// Everything a build needs besides the points.
#[derive(Clone, Debug)]
struct BuildOptions {
    kernel: KernelChoice,
    scheme: SchemeChoice,
    eps: Option<f64>,
    order: Option<usize>,
    leaf_size: Option<usize>,
    mode: EvalMode,
    source_kind: SourceKind,
    verify: bool,
    /// `cache_dir=` / `cache="path"`, `cache=False`, else the default.
    cache: CacheSetting,
    /// `box=` (with `box_origin=`, `periodic=`, `surface=`): the periodic
    /// cell, `None` for free space.
    periodic: Option<Periodic>,
}

/// Build for float type `T` from points held in `f64`: they are rounded to
/// `T` only relative to the tree's origin ([`FmmBuilder::from_f64`]), so an
/// `f32` run on points far from the origin keeps their separations.
fn build<T: Float>(
    o: &BuildOptions,
    monitor: PrecomputeMonitor,
    sources: &[f64],
    targets: Option<&[f64]>,
) -> Result<Box<dyn Engine>, FmmError> {
    o.kernel.visit(BuildWith {
        o,
        monitor,
        sources,
        targets,
        float: std::marker::PhantomData::<T>,
    })
}

/// [`build`] with the kernel chosen.
struct BuildWith<'a, T> {
    o: &'a BuildOptions,
    monitor: PrecomputeMonitor,
    sources: &'a [f64],
    targets: Option<&'a [f64]>,
    float: std::marker::PhantomData<T>,
}

impl<T: Float> KernelVisitor for BuildWith<'_, T> {
    type Output = Result<Box<dyn Engine>, FmmError>;

    fn visit<K: Kernel>(self, kernel: K) -> Self::Output {
        build_with::<T, K>(kernel, self.o, self.monitor, self.sources, self.targets)
    }
}

fn build_with<T: Float, K: Kernel>(
    kernel: K,
    o: &BuildOptions,
    monitor: PrecomputeMonitor,
    sources: &[f64],
    targets: Option<&[f64]>,
) -> Result<Box<dyn Engine>, FmmError> {
    let mut b = FmmBuilder::<T, _>::from_f64(sources)
        .kernel(kernel)
        .mode(o.mode)
        .source_kind(o.source_kind)
        .monitor(monitor)
        .verify(o.verify);
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
    b = b.cache(o.cache.clone());
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
    let scheme = o.scheme.resolve(
        o.kernel,
        ferrofmm_fmm::effective_tolerance(o.eps, o.order, T::PRECISION),
        o.order,
        Some((sources, targets)),
        o.mode,
        T::PRECISION,
        cached,
    )?;
    Ok(match scheme {
        SchemeChoice::Svd | SchemeChoice::Auto => Box::new(b.build_svd()?),
        SchemeChoice::Dense => Box::new(b.build_with::<DenseM2l<T>>(Default::default())?),
        SchemeChoice::Fft => Box::new(b.build_with::<FftM2l<T>>(FftConfig)?),
    })
}

/// A built FMM: tree and operators for fixed sources, targets, kernel and
/// accuracy; `evaluate` any number of charge vectors.
///
/// The public wrapper is `ferrofmm.Fmm`; this class takes flat,
/// C-contiguous arrays (interleaved `x, y, z`).
#[pyclass(module = "ferrofmm._ferrofmm", frozen)]
pub(crate) struct NativeFmm {
    engine: Arc<RwLock<Box<dyn Engine>>>,
    threads: Threads,
    /// The first evaluation of a tolerance is checked (when `verify`).
    verify_pending: AtomicBool,
    /// Verification of the first evaluation, reported by every later one.
    verification: Mutex<Option<Verification>>,
    options: BuildOptions,
    dtype: &'static str,
    /// Where the operator cache is (resolved once, at construction).
    cache: CacheLocation,
}

#[pymethods]
impl NativeFmm {
    #[new]
    #[pyo3(signature = (sources, targets, kernel, k, eps, order, leaf_size, scheme, gradient, verify, threads, cache_dir, hessian=false, source="charge", dtype=None, cache=true, cell_lengths=None, cell_origin=None, periodic=None, surface=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        sources: &Bound<'_, PyAny>,
        targets: Option<&Bound<'_, PyAny>>,
        kernel: &str,
        k: Option<f64>,
        eps: Option<f64>,
        order: Option<usize>,
        leaf_size: Option<usize>,
        scheme: &str,
        gradient: bool,
        verify: bool,
        threads: Option<usize>,
        cache_dir: Option<PathBuf>,
        hessian: bool,
        source: &str,
        dtype: Option<&str>,
        cache: bool,
        cell_lengths: Option<Vec<f64>>,
        cell_origin: Option<Vec<f64>>,
        periodic: Option<&str>,
        surface: Option<&str>,
    ) -> PyResult<Self> {
        let periodic = periodic_cell(cell_lengths, cell_origin, periodic, surface)?;
        let source_kind = source_kind(source)?;
        let kernel = kernel_choice(kernel, k)?;
        let scheme = SchemeChoice::parse(scheme).map_err(PyValueError::new_err)?;
        parameters_given(eps, order, leaf_size)?;
        let options = BuildOptions {
            kernel,
            scheme,
            eps,
            order,
            leaf_size,
            mode: if hessian {
                EvalMode::PotentialGradientHessian
            } else if gradient {
                EvalMode::PotentialGradient
            } else {
                EvalMode::Potential
            },
            source_kind,
            verify,
            cache: match (cache_dir, cache) {
                (Some(dir), _) => CacheSetting::Dir(dir),
                (None, true) => CacheSetting::Default,
                (None, false) => CacheSetting::Off,
            },
            periodic,
        };
        // A folder the caller named must be usable; the default one may
        // not be (read-only home): the operators then stay in memory.
        if let CacheSetting::Dir(dir) = &options.cache {
            check_cache_dir(dir)?;
        }
        let cache_location = options
            .cache
            .resolve()
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let threads = Threads::new(py, threads)?;
        // The run's float type: `dtype`, else the sources'. The points go
        // to the builder in f64 (f32 widens exactly) and are rounded to the
        // run's type only relative to the tree's origin.
        let sources = Floats::from_numpy("sources", sources)?;
        let run_f32 = match dtype {
            None => matches!(sources, Floats::F32(_)),
            Some("float32") => true,
            Some("float64") => false,
            Some(other) => {
                return Err(PyValueError::new_err(format!(
                    "dtype must be \"float32\" or \"float64\", got {other:?}"
                )));
            }
        };
        let sources = f64::unwrap(sources);
        let targets = targets
            .map(|t| Floats::from_numpy("targets", t).map(f64::unwrap))
            .transpose()?;
        let cancel = Arc::new(AtomicBool::new(false));
        let monitor = PrecomputeMonitor::new().with_cancel_flag(cancel.clone());
        let job_options = options.clone();
        let (dtype, engine) = if run_f32 {
            ("float32", {
                interruptible(py, &threads, Some(&cancel), move || {
                    build::<f32>(&job_options, monitor, &sources, targets.as_deref())
                })?
            })
        } else {
            ("float64", {
                interruptible(py, &threads, Some(&cancel), move || {
                    build::<f64>(&job_options, monitor, &sources, targets.as_deref())
                })?
            })
        };
        let engine = engine.map_err(fmm_error)?;
        for e in engine.cache_write_errors() {
            PyErr::warn(
                py,
                &py.get_type::<PyRuntimeWarning>(),
                &std::ffi::CString::new(format!(
                    "the operator cache was not saved (the operators were computed and are \
                     correct): {e}"
                ))
                .unwrap_or_default(),
                1,
            )?;
        }
        Ok(NativeFmm {
            engine: Arc::new(RwLock::new(engine)),
            threads,
            verify_pending: AtomicBool::new(verify && eps.is_some()),
            verification: Mutex::new(None),
            options,
            dtype,
            cache: cache_location,
        })
    }

    /// Evaluate `n_vectors` charge vectors stored one after another in the
    /// flat array `charges`; returns the flat values (per vector, per
    /// target: `phi` or `phi, gx, gy, gz`) and a JSON report.
    ///
    /// `progress`, when given, is called as `progress(done, total)` with
    /// the GIL held, at most every 0.1 s while the passes run and once at
    /// the end (`done == total`), the work counted in rough cost units over
    /// all the evaluations of the call. An exception it raises ends the
    /// call with that exception.
    #[pyo3(signature = (charges, n_vectors, progress=None))]
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        charges: &Bound<'py, PyAny>,
        n_vectors: usize,
        progress: Option<Bound<'py, PyAny>>,
    ) -> PyResult<(Bound<'py, PyAny>, String)> {
        let progress = match progress {
            Some(p) if !p.is_none() => {
                if !p.is_callable() {
                    return Err(PyTypeError::new_err(format!(
                        "progress must be a callable taking (done, total) or None, not {}",
                        p.get_type().name()?
                    )));
                }
                Some(p)
            }
            _ => None,
        };
        let charges = Floats::from_numpy("charges", charges)?;
        let n_sources = self.read().n_sources();
        let per = self.options.kernel.components() * self.options.source_kind.values_per_source();
        if n_vectors == 0 || charges.len() != n_vectors * n_sources * per {
            return Err(PyValueError::new_err(format!(
                "expected {} values ({n_vectors} vector(s) of {per} per source for {} sources, {n_sources} sources), got {}",
                n_vectors * n_sources * per,
                self.options.source_kind.name(),
                charges.len()
            )));
        }
        let verify = self.verify_pending.swap(false, Ordering::SeqCst);
        let engine = self.engine.clone();
        let sink = progress
            .as_ref()
            .map(|_| Arc::new(ProgressSink::new(n_vectors)));
        let feed = sink.clone();
        let job = move || match feed {
            Some(feed) => {
                let mut e = engine.write().unwrap_or_else(|p| p.into_inner());
                e.set_progress(Some(feed.callback()));
                let r = if verify {
                    e.evaluate_verified(charges, n_vectors)
                } else {
                    e.evaluate(charges, n_vectors)
                };
                e.set_progress(None);
                r
            }
            None if verify => {
                let mut e = engine.write().unwrap_or_else(|p| p.into_inner());
                e.evaluate_verified(charges, n_vectors)
            }
            None => {
                let e = engine.read().unwrap_or_else(|p| p.into_inner());
                e.evaluate(charges, n_vectors)
            }
        };
        let result = match (&progress, &sink) {
            (Some(f), Some(sink)) => {
                interruptible_polling(py, &self.threads, None, job, |_| sink.deliver(f))
            }
            _ => interruptible(py, &self.threads, None, job),
        };
        let evaluated = match result {
            Ok(Ok(e)) => e,
            Ok(Err(e)) => {
                self.verify_pending.fetch_or(verify, Ordering::SeqCst);
                return Err(fmm_error(e));
            }
            Err(e) => {
                self.verify_pending.fetch_or(verify, Ordering::SeqCst);
                return Err(e);
            }
        };
        let mut last = self.verification.lock().unwrap_or_else(|p| p.into_inner());
        if evaluated.verification.is_some() {
            last.clone_from(&evaluated.verification);
        }
        let mut info = self.info(&evaluated.timings, last.as_ref(), n_vectors);
        if let Value::Object(map) = &mut info {
            map.insert("energy".into(), json!(evaluated.energies));
        }
        Ok((evaluated.values.into_numpy(py), info.to_string()))
    }

    /// JSON of the tree, operator and parameter figures.
    fn summary_json(&self) -> String {
        let last = self.verification.lock().unwrap_or_else(|p| p.into_inner());
        let mut s = serde_json::to_value(self.read().summary()).unwrap_or(Value::Null);
        if let (Some(v), Value::Object(map)) = (last.as_ref(), &mut s) {
            map.insert(
                "verification".into(),
                serde_json::to_value(v).unwrap_or(Value::Null),
            );
        }
        s.to_string()
    }

    /// JSON of the setup times (seconds).
    fn setup_timings_json(&self) -> String {
        setup_seconds(&self.read().setup_timings()).to_string()
    }

    /// `"float32"` or `"float64"`.
    #[getter]
    fn dtype(&self) -> &'static str {
        self.dtype
    }

    /// Number of sources.
    #[getter]
    fn n_sources(&self) -> usize {
        self.read().n_sources()
    }

    /// Number of targets.
    #[getter]
    fn n_targets(&self) -> usize {
        self.read().n_targets()
    }

    /// Number of threads the work runs on.
    #[getter]
    fn threads(&self) -> usize {
        self.threads.count()
    }
}

/// The progress of one Python `evaluate` call, written by the FMM passes
/// (any thread) and handed to the Python callback by the calling thread,
/// with the GIL held, when it wakes ([`interruptible_polling`]).
///
/// Each evaluation of the call (one per charge vector, more when the
/// verification raises the order) reports from 0 to its own total; the
/// sink adds the finished ones so that Python sees one rising count.
struct ProgressSink {
    /// Charge vectors of the call.
    n_vectors: u64,
    state: Mutex<SinkState>,
}

#[derive(Default)]
struct SinkState {
    /// Evaluations finished before the current one.
    finished: u64,
    /// Units of the evaluations finished before the current one.
    before: u64,
    /// The current evaluation's report.
    current: EvalProgress,
    /// Whether something new came since the last delivery.
    fresh: bool,
}

impl ProgressSink {
    /// The callback for [`Fmm::set_progress`].
    fn callback(self: &Arc<Self>) -> Arc<ProgressFn> {
        let sink = self.clone();
        Arc::new(move |p: EvalProgress| {
            let mut s = sink.state.lock().unwrap_or_else(|e| e.into_inner());
            if p.done == 0 && s.current.done > 0 {
                // A new evaluation starts: the previous one is done.
                s.before += s.current.total;
                s.finished += 1;
            }
            s.current = p;
            s.fresh = true;
        })
    }

    /// A sink for a call of `n_vectors` charge vectors.
    fn new(n_vectors: usize) -> Self {
        Self {
            n_vectors: n_vectors as u64,
            state: Mutex::default(),
        }
    }

    /// Call `f(done, total)` when something new came: the total counts
    /// each vector not yet finished as the current one (an order raised by
    /// the verification adds an evaluation, so the total may grow once);
    /// the last report of the call has `done == total`.
    fn deliver(&self, f: &Bound<'_, PyAny>) -> PyResult<()> {
        let (done, total) = {
            let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
            if !s.fresh {
                return Ok(());
            }
            s.fresh = false;
            let left = self.n_vectors.saturating_sub(s.finished).max(1);
            (s.before + s.current.done, s.before + left * s.current.total)
        };
        f.call1((done, total)).map(drop)
    }
}

impl NativeFmm {
    fn read(&self) -> std::sync::RwLockReadGuard<'_, Box<dyn Engine>> {
        self.engine.read().unwrap_or_else(|p| p.into_inner())
    }

    /// The report of one evaluation (`info` in Python).
    fn info(
        &self,
        timings: &EvalTimings,
        verification: Option<&Verification>,
        n_vectors: usize,
    ) -> Value {
        let (s, setup, cache) = {
            let engine = self.read();
            (
                engine.summary(),
                engine.setup_timings(),
                engine.cache_summary(),
            )
        };
        let cache = match &self.cache {
            CacheLocation::Folder { .. } => cache.unwrap_or_else(|| "not needed".into()),
            CacheLocation::Off(CacheOff::Requested) => "off (cache=False)".into(),
            CacheLocation::Off(why) => why.to_string(),
        };
        let chosen = s.chosen.as_ref();
        json!({
            "kernel": s.kernel,
            "dtype": self.dtype,
            "order": s.order,
            "leaf_size": s.leaf_size,
            "scheme": s.m2l_scheme,
            "method": if chosen.is_some_and(|c| c.direct) { "direct" } else { "fmm" },
            "eps": self.options.eps,
            "predicted_error": verification
                .map(Verification::predicted_error)
                .or(chosen.map(|c| c.predicted_error)),
            "measured_error": verification.map(|v| {
                let m = v.measured();
                json!({"potential": m.potential, "gradient": m.gradient, "hessian": m.hessian, "sampled_targets": m.n_sampled})
            }),
            "verified": verification.map(|v| v.met),
            "n_vectors": n_vectors,
            "threads": self.threads.count(),
            "depth": s.depth,
            "root_scale": chosen.map_or(1.0, |c| c.root_scale),
            "boxes": s.n_boxes,
            "leaves": s.n_leaves,
            "clusters": s.clusters,
            "cache": cache,
            "cache_dir": self.cache.dir().map(|d| d.display().to_string()),
            "periodic": self.options.periodic.as_ref().map(periodic_info),
            "timings": {
                "setup": setup_seconds(&setup),
                "evaluate": eval_seconds(timings),
            },
        })
    }
}

/// The periodic cell of `box=`, `box_origin=`, `periodic=` and `surface=`
/// (as the command line's `--box`, `--box-origin`, `--periodic`,
/// `--surface`), checked; `None` without a box.
fn periodic_cell(
    lengths: Option<Vec<f64>>,
    origin: Option<Vec<f64>>,
    axes: Option<&str>,
    surface: Option<&str>,
) -> PyResult<Option<Periodic>> {
    let Some(lengths) = lengths else {
        let given = [
            ("box_origin", origin.is_some()),
            ("periodic", axes.is_some()),
            ("surface", surface.is_some()),
        ];
        if let Some((name, _)) = given.iter().find(|(_, g)| *g) {
            return Err(PyValueError::new_err(format!(
                "{name}= needs box= (the side L of the periodic cell, or its sides (Lx, Ly, Lz))"
            )));
        }
        return Ok(None);
    };
    let mut cell = Periodic::with_lengths(box_lengths(&lengths)?);
    if let Some(o) = origin {
        match o[..] {
            [x, y, z] => cell = cell.with_origin([x, y, z]),
            _ => {
                return Err(PyValueError::new_err(format!(
                    "box_origin takes three numbers (x, y, z), got {} values",
                    o.len()
                )));
            }
        }
    }
    if let Some(a) = axes {
        let axes: PeriodicAxes = a.parse().map_err(fmm_error)?;
        cell = cell.with_axes(axes);
    }
    if let Some(s) = surface {
        let surface: SurfaceTerm = s.parse().map_err(fmm_error)?;
        cell = cell.with_surface(surface);
    }
    cell.validate()
        .map_err(|e| PyValueError::new_err(format!("box: {e}")))?;
    Ok(Some(cell))
}

/// `info["periodic"]`: the cell of a periodic run.
fn periodic_info(cell: &Periodic) -> Value {
    json!({
        "box": cell.lengths(),
        "origin": cell.origin(),
        "axes": cell.axes().name(),
        "surface": surface_name(cell.surface()),
    })
}

/// `"tin-foil"` or `"vacuum"`.
fn surface_name(s: SurfaceTerm) -> &'static str {
    match s {
        SurfaceTerm::TinFoil => "tin-foil",
        SurfaceTerm::Vacuum => "vacuum",
    }
}

fn setup_seconds(t: &SetupTimings) -> Value {
    json!({
        "tuning": t.tuning.as_secs_f64(),
        "tree": t.tree.as_secs_f64(),
        "operators": t.operators.as_secs_f64(),
        "m2l_precompute": t.m2l_precompute.as_secs_f64(),
        "layout": t.layout.as_secs_f64(),
        "total": t.total.as_secs_f64(),
    })
}

fn eval_seconds(t: &EvalTimings) -> Value {
    let mut map = serde_json::Map::new();
    for (name, d) in t.operators() {
        map.insert(name.to_lowercase(), json!(d.as_secs_f64()));
    }
    map.insert("total".into(), json!(t.total.as_secs_f64()));
    Value::Object(map)
}

/// `box=` as three sides: one side `L` (a cube) or three.
pub(crate) fn box_lengths(lengths: &[f64]) -> PyResult<[f64; 3]> {
    match lengths[..] {
        [l] => Ok([l; 3]),
        [a, b, c] => Ok([a, b, c]),
        _ => Err(PyValueError::new_err(format!(
            "box takes one side or three (Lx, Ly, Lz), got {} values",
            lengths.len()
        ))),
    }
}

/// The source kind a Python name means (`"charge"`, `"dipole"`,
/// `"charge+dipole"`).
pub(crate) fn source_kind(source: &str) -> PyResult<SourceKind> {
    match source {
        "charge" => Ok(SourceKind::Charge),
        "dipole" => Ok(SourceKind::Dipole),
        "charge+dipole" => Ok(SourceKind::ChargeDipole),
        other => Err(PyValueError::new_err(format!(
            "unknown source kind {other:?}: use \"charge\", \"dipole\" or \"charge+dipole\""
        ))),
    }
}

/// The kernel `kernel` names with its parameter `k`, or `ValueError`
/// saying what is missing or misplaced.
pub(crate) fn kernel_choice(kernel: &str, k: Option<f64>) -> PyResult<KernelChoice> {
    KernelChoice::from_parts(kernel, k).map_err(|e| {
        PyValueError::new_err(
            match KernelChoice::registered().iter().find(|d| d.name == kernel) {
                Some(d) => match (d.parameter, k) {
                    (Some(p), None) => format!(
                        "the {kernel} kernel needs {} (its {}), e.g. {}={}",
                        p.name, p.meaning, p.name, p.example
                    ),
                    (None, Some(_)) => {
                        let with_k: Vec<&str> = KernelChoice::registered()
                            .iter()
                            .filter(|d| d.parameter.is_some_and(|p| p.name == "k"))
                            .map(|d| d.name)
                            .collect();
                        format!(
                            "k is a parameter of the {} kernels, not {kernel}",
                            with_k.join(" and ")
                        )
                    }
                    _ => e.why,
                },
                None => format!("unknown kernel {kernel:?}: {}", e.why),
            },
        )
    })
}

/// `eps` (the order and leaf size then chosen) or `order` (with or without
/// a leaf size): exactly one way of fixing the accuracy.
pub(crate) fn parameters_given(
    eps: Option<f64>,
    order: Option<usize>,
    leaf_size: Option<usize>,
) -> PyResult<()> {
    match (eps, order, leaf_size) {
        (Some(_), Some(_), _) => Err(PyValueError::new_err(
            "give eps (the order and leaf size are then chosen) or order, not both",
        )),
        (Some(_), None, Some(_)) => Err(PyValueError::new_err(
            "leaf_size is chosen from eps: give order instead of eps to set it",
        )),
        (None, None, _) => Err(PyValueError::new_err("give eps (e.g. 1e-6) or order")),
        _ => Ok(()),
    }
}
