//! `NativeDistFmm`: the distributed FMM ([`DistSolver`]) on an mpi4py
//! communicator, built once for each rank's points and evaluated many
//! times.

use std::path::PathBuf;
use std::sync::Mutex;

use ferrofmm_field::{CacheLocation, CacheOff, CacheSetting};
use ferrofmm_fmm::SchemeChoice;
use ferrofmm_kernels::{EvalMode, Precision};
use ferrofmm_mpi::{DistRequest, DistSolver};
use mpi::topology::SimpleCommunicator;
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use serde_json::{Value, json};

use super::{Start, Work, dist_error};
use crate::engine::{kernel_choice, parameters_given, source_kind};

/// One rank's part of a distributed FMM. The public wrapper is
/// `ferrofmm.distributed.Fmm`.
#[pyclass(module = "ferrofmm._ferrofmm", frozen)]
pub(crate) struct NativeDistFmm {
    state: Mutex<State>,
}

/// The solver and what it runs on. Fields drop in order: the solver
/// before the communicator it was built on.
struct State {
    solver: DistSolver<SimpleCommunicator>,
    work: Work,
}

#[pymethods]
impl NativeDistFmm {
    #[new]
    #[pyo3(signature = (comm, sources, targets, kernel, k, eps, order, leaf_size, scheme, gradient, verify, samples, threads, cache_dir, cache, source, dtype))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        comm: i64,
        sources: PyReadonlyArray1<'_, f64>,
        targets: Option<PyReadonlyArray1<'_, f64>>,
        kernel: &str,
        k: Option<(f64, f64)>,
        eps: Option<f64>,
        order: Option<usize>,
        leaf_size: Option<usize>,
        scheme: &str,
        gradient: bool,
        verify: bool,
        samples: usize,
        threads: Option<usize>,
        cache_dir: Option<PathBuf>,
        cache: bool,
        source: &str,
        dtype: &str,
    ) -> PyResult<Self> {
        let local = dist_request(
            kernel, k, eps, order, leaf_size, scheme, gradient, verify, samples, cache_dir, cache,
            source, dtype,
        );
        let Start {
            request,
            work,
            points,
            targets,
        } = Start::new(comm, local, threads, sources, targets)?;
        let solver = work
            .run(py, |comm| match targets {
                None => DistSolver::build(comm, points, request),
                Some(t) => DistSolver::build_with_targets(comm, points, t, request),
            })
            .map_err(dist_error)?;
        Ok(NativeDistFmm {
            state: Mutex::new(State { solver, work }),
        })
    }

    /// Evaluate the densities of this rank's sources (flat, input order,
    /// `values_per_source` per point); returns the flat values at this
    /// rank's targets (input order, `values_per_target` per target) and a
    /// JSON report. A collective.
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        densities: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<(Bound<'py, PyArray1<f64>>, String)> {
        let mut state = self.lock()?;
        let densities = densities.as_slice()?.to_vec();
        let State { solver, work } = &mut *state;
        let solution = work
            .run(py, |comm| solver.evaluate(comm, &densities))
            .map_err(dist_error)?;
        let plan = solver.plan();
        let stats = &solution.stats;
        let info = json!({
            "order": plan.order,
            "leaf_size": plan.leaf_size,
            "scheme": plan.scheme,
            "svd_tolerance": plan.svd_tolerance,
            "eps": plan.tolerance,
            "predicted_error": plan.choice.as_ref().map(|c| c.predicted_error),
            "calibrated": plan.choice.as_ref().map(|c| c.calibrated),
            "measured_error": solution.errors.map(|e| json!({
                "potential": e[0],
                "gradient": (solver.request().mode != EvalMode::Potential).then_some(e[1]),
                "sampled_targets": solver.samples(),
            })),
            "verified": solution.verified,
            "attempts": solver.attempts().iter().map(|a| json!({
                "order": a.order,
                "potential_error": a.errors[0],
                "gradient_error": a.errors[1],
            })).collect::<Vec<Value>>(),
            "threads": work.threads(),
            "ranks": work.size(),
            "points": solver.tree().points.len(),
            "ghost_points": solver.setup_stats().ghost_points,
            "cache": cache_words(solver),
            "cache_dir": solver.cache().dir().map(|d| d.display().to_string()),
            "timings": {
                "setup": solver.setup_stats().seconds,
                "evaluate": ferrofmm_mpi::EVAL_PHASES
                    .iter()
                    .zip(stats.seconds)
                    .map(|(name, s)| (name.to_string(), json!(s)))
                    .collect::<serde_json::Map<String, Value>>(),
            },
            "bytes_sent": ferrofmm_mpi::EVAL_PHASES
                .iter()
                .zip(stats.bytes_sent)
                .map(|(name, b)| (name.to_string(), json!(b)))
                .collect::<serde_json::Map<String, Value>>(),
        });
        Ok((PyArray1::from_vec(py, solution.values), info.to_string()))
    }

    /// Values per point in the density vectors.
    #[getter]
    fn values_per_source(&self) -> PyResult<usize> {
        Ok(self.lock()?.solver.values_per_source())
    }

    /// Values per point in the results.
    #[getter]
    fn values_per_target(&self) -> PyResult<usize> {
        Ok(self.lock()?.solver.values_per_target())
    }

    /// Points this rank passed.
    #[getter]
    fn n_sources(&self) -> PyResult<usize> {
        Ok(self.lock()?.solver.points().len() / 3)
    }

    /// Points every rank passed, in rank order.
    #[getter]
    fn input_counts(&self) -> PyResult<Vec<u64>> {
        Ok(self.lock()?.solver.tree().input_counts.clone())
    }

    /// Targets of this rank (its points, without separate targets).
    #[getter]
    fn n_targets(&self) -> PyResult<usize> {
        let state = self.lock()?;
        let solver = &state.solver;
        Ok(solver.targets().unwrap_or(solver.points()).len() / 3)
    }

    /// Targets every rank passed, in rank order.
    #[getter]
    fn target_counts(&self) -> PyResult<Vec<u64>> {
        Ok(self.lock()?.solver.target_counts().to_vec())
    }
}

impl NativeDistFmm {
    fn lock(&self) -> PyResult<std::sync::MutexGuard<'_, State>> {
        self.state
            .lock()
            .map_err(|_| PyValueError::new_err("a previous evaluation of this Fmm panicked"))
    }
}

/// The request of the Python arguments (checked here, on this rank; the
/// caller agrees on the outcome).
#[allow(clippy::too_many_arguments)]
pub(super) fn dist_request(
    kernel: &str,
    k: Option<(f64, f64)>,
    eps: Option<f64>,
    order: Option<usize>,
    leaf_size: Option<usize>,
    scheme: &str,
    gradient: bool,
    verify: bool,
    samples: usize,
    cache_dir: Option<PathBuf>,
    cache: bool,
    source: &str,
    dtype: &str,
) -> PyResult<DistRequest> {
    parameters_given(eps, order, leaf_size)?;
    let precision = match dtype {
        "float32" => Precision::F32,
        "float64" => Precision::F64,
        other => {
            return Err(PyValueError::new_err(format!(
                "dtype must be \"float32\" or \"float64\", got {other:?}"
            )));
        }
    };
    Ok(DistRequest {
        mode: if gradient {
            EvalMode::PotentialGradient
        } else {
            EvalMode::Potential
        },
        sources: source_kind(source)?,
        precision,
        tolerance: eps,
        order,
        leaf_size,
        scheme: SchemeChoice::parse(scheme).map_err(PyValueError::new_err)?,
        verify,
        samples,
        cache: match (cache_dir, cache) {
            (Some(dir), _) => CacheSetting::Dir(dir),
            (None, true) => CacheSetting::Default,
            (None, false) => CacheSetting::Off,
        },
        ..DistRequest::new(kernel_choice(kernel, k)?)
    })
}

/// What the operator cache did, in words.
pub(super) fn cache_words(solver: &DistSolver<SimpleCommunicator>) -> String {
    match solver.cache() {
        CacheLocation::Off(CacheOff::Requested) => "off (cache=False)".into(),
        CacheLocation::Off(why) => why.to_string(),
        CacheLocation::Folder { .. } => solver
            .cache_summary()
            .unwrap_or_else(|| "not needed".into()),
    }
}
