//! `NativeFmm`: one built [`Fmm`](ferrofmm_fmm::Fmm) of any float type, kernel and M2L
//! scheme behind one object-safe trait, evaluated many times.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, RwLock};

use ferrofmm_field::{CacheLocation, CacheSetting, PrecomputeMonitor};
use ferrofmm_fmm::{SchemeChoice, Verification};
use ferrofmm_kernels::EvalMode;
use pyo3::exceptions::{PyRuntimeWarning, PyValueError};
use pyo3::prelude::*;
use serde_json::{Value, json};

use crate::errors::fmm_error;
use crate::limits::check_cache_dir;
use crate::run::{Threads, interruptible, interruptible_polling};

mod arguments;
mod erased;
mod floats;
mod layers;
mod progress;
mod report;

pub(crate) use arguments::{box_lengths, kernel_choice, parameters_given, source_kind};
pub(crate) use floats::Floats;

use arguments::periodic_cell;
use erased::{BuildOptions, Engine, Watch, build};
use floats::Float;
use progress::{ProgressSink, SetupSink, callable_or_none};
use report::setup_seconds;

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
    #[pyo3(signature = (sources, targets, kernel, k, eps, order, leaf_size, scheme, gradient, verify, threads, cache_dir, hessian=false, source="charge", dtype=None, cache=true, cell_lengths=None, cell_origin=None, periodic=None, surface=None, layers=None, progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        sources: &Bound<'_, PyAny>,
        targets: Option<&Bound<'_, PyAny>>,
        kernel: &str,
        k: Option<(f64, f64)>,
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
        layers: Option<(bool, bool, bool)>,
        progress: Option<Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let progress = callable_or_none(progress, "(step, done, total)")?;
        let periodic = periodic_cell(cell_lengths, cell_origin, periodic, surface)?;
        let source_kind = source_kind(source)?;
        let kernel_name = kernel;
        let kernel = kernel_choice(kernel, k)?;
        let layers = stokes_layers(kernel_name, layers, source_kind, hessian)?;
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
            layers,
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
        let sink = progress.as_ref().map(|_| Arc::new(SetupSink::default()));
        let watch = Watch {
            monitor: PrecomputeMonitor::new().with_cancel_flag(cancel.clone()),
            setup: sink.as_ref().map(|s| s.callback()),
        };
        let job_options = options.clone();
        let poll = |_: Python<'_>| match (&progress, &sink) {
            (Some(f), Some(sink)) => sink.deliver(f),
            _ => Ok(()),
        };
        let (dtype, engine) = if run_f32 {
            ("float32", {
                interruptible_polling(
                    py,
                    &threads,
                    Some(&cancel),
                    move || build::<f32>(&job_options, watch, &sources, targets.as_deref()),
                    poll,
                )?
            })
        } else {
            ("float64", {
                interruptible_polling(
                    py,
                    &threads,
                    Some(&cancel),
                    move || build::<f64>(&job_options, watch, &sources, targets.as_deref()),
                    poll,
                )?
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
        let progress = callable_or_none(progress, "(done, total)")?;
        let charges = Floats::from_numpy("charges", charges)?;
        let n_sources = self.read().n_sources();
        let per = self.options.values_per_source();
        if n_vectors == 0 || charges.len() != n_vectors * n_sources * per {
            let kind = match self.options.layers {
                Some(_) => "stokes force/stresslet",
                None => self.options.source_kind.name(),
            };
            return Err(PyValueError::new_err(format!(
                "expected {} values ({n_vectors} vector(s) of {per} per source for {} sources, {n_sources} sources), got {}",
                n_vectors * n_sources * per,
                kind,
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

    /// Values per target of one vector (the pressure after the velocity
    /// with `layers`).
    #[getter]
    fn values_per_target(&self) -> usize {
        self.options.values_per_target()
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

/// `layers = (forces, stresslets, pressure)`: a Stokes run with stresslets
/// or the pressure ([`ferrofmm_fmm::StokesLayers`]); `None` (or neither)
/// is one FMM of the kernel.
fn stokes_layers(
    kernel: &str,
    layers: Option<(bool, bool, bool)>,
    source_kind: ferrofmm_kernels::SourceKind,
    hessian: bool,
) -> PyResult<Option<ferrofmm_fmm::StokesRequest>> {
    let Some((forces, stresslets, pressure)) = layers.filter(|l| l.1 || l.2) else {
        return Ok(None);
    };
    if kernel != "stokes" {
        return Err(PyValueError::new_err(format!(
            "stresslets and the pressure belong to the stokes kernel, not {kernel:?}"
        )));
    }
    if source_kind.has_dipoles() {
        return Err(PyValueError::new_err(
            "force dipoles (dipoles=True) do not combine with stresslets or the pressure: \
             give stresslets as strslet and strsvec",
        ));
    }
    if hessian {
        return Err(PyValueError::new_err("the stokes kernel has no Hessians"));
    }
    if !(forces || stresslets) {
        return Err(PyValueError::new_err(
            "the sources carry nothing: give forces, stresslets or both",
        ));
    }
    Ok(Some(ferrofmm_fmm::StokesRequest {
        forces,
        stresslets,
        pressure,
    }))
}
