//! `NativeDistStokesLayers`: Stokes forces and stresslets with the
//! pressure across ranks ([`DistStokesLayers`]: a Stokeslet FMM and, for
//! stresslets or the pressure, a Laplace FMM beside it), built once for
//! each rank's points and evaluated many times. The public wrappers are
//! `ferrofmm.distributed.Fmm(..., "stokes", stresslets=True,
//! pressure=True)` and `ferrofmm.distributed.stokes(..., strslet=,
//! strsvec=, pressure=)`.

use std::path::PathBuf;
use std::sync::Mutex;

use ferrofmm_fmm::StokesRequest;
use ferrofmm_mpi::DistStokesLayers;
use mpi::topology::SimpleCommunicator;
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use serde_json::json;

use super::fmm::{cache_words, dist_request};
use super::{Start, Work, dist_error};

/// One rank's part of the distributed Stokes FMM with stresslets or the
/// pressure.
#[pyclass(module = "ferrofmm._ferrofmm", frozen)]
pub(crate) struct NativeDistStokesLayers {
    state: Mutex<State>,
    /// What the sources carry and what is computed.
    wanted: StokesRequest,
}

/// Both FMMs and what they run on. Fields drop in order: the solvers
/// before the communicator they were built on.
struct State {
    layers: DistStokesLayers<SimpleCommunicator>,
    work: Work,
}

/// Velocities (flat, 3 or 12 per target), pressures (flat, 1 or 4 per
/// target, or `None`) and a JSON report.
type Evaluated<'py> = (
    Bound<'py, PyArray1<f64>>,
    Option<Bound<'py, PyArray1<f64>>>,
    String,
);

#[pymethods]
impl NativeDistStokesLayers {
    /// Plans and builds both FMMs for this rank's `sources` (flat `xyz`)
    /// and, when given, its own `targets`; the sources carry `forces`
    /// and/or `stresslets`, and `pressure` adds the pressure (with its
    /// gradient when `gradient`). A collective: every rank passes its own
    /// rows and the same parameters.
    #[new]
    #[pyo3(signature = (comm, sources, targets, eps, order, leaf_size, scheme, gradient, verify, samples, threads, cache_dir, cache, dtype, forces, stresslets, pressure))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        comm: i64,
        sources: PyReadonlyArray1<'_, f64>,
        targets: Option<PyReadonlyArray1<'_, f64>>,
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
        dtype: &str,
        forces: bool,
        stresslets: bool,
        pressure: bool,
    ) -> PyResult<Self> {
        let local = dist_request(
            "stokes", None, eps, order, leaf_size, scheme, gradient, verify, samples, cache_dir,
            cache, "charge", dtype,
        );
        let Start {
            request,
            work,
            points,
            targets,
        } = Start::new(comm, local, threads, sources, targets)?;
        let wanted = StokesRequest {
            forces,
            stresslets,
            pressure,
        };
        let layers = work
            .run(py, |comm| {
                DistStokesLayers::build(comm, points, targets, request, wanted)
            })
            .map_err(dist_error)?;
        Ok(NativeDistStokesLayers {
            state: Mutex::new(State { layers, work }),
            wanted,
        })
    }

    /// Velocity (and pressure) at this rank's targets for its `forces`
    /// and stresslets `(strslet, strsvec)` (flat, three values per point,
    /// input order; those the sources carry). The first evaluation of a
    /// tolerance is verified. A collective.
    #[pyo3(signature = (forces, strslet, strsvec))]
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        forces: Option<PyReadonlyArray1<'_, f64>>,
        strslet: Option<PyReadonlyArray1<'_, f64>>,
        strsvec: Option<PyReadonlyArray1<'_, f64>>,
    ) -> PyResult<Evaluated<'py>> {
        let flat = |a: Option<PyReadonlyArray1<'_, f64>>| -> PyResult<Option<Vec<f64>>> {
            a.map(|a| a.as_slice().map(<[f64]>::to_vec))
                .transpose()
                .map_err(Into::into)
        };
        let forces = flat(forces)?;
        // A missing half of a stresslet reaches the library as no
        // stresslets, which it refuses on every rank alike.
        let stresslets = flat(strslet)?.zip(flat(strsvec)?);
        let mut state = self.lock()?;
        let State { layers, work } = &mut *state;
        let solution = work
            .run(py, |comm| {
                let mn = stresslets.as_ref().map(|(m, n)| (&m[..], &n[..]));
                layers.evaluate(comm, forces.as_deref(), mn)
            })
            .map_err(dist_error)?;
        let stokes = layers.stokes();
        let plan = stokes.plan();
        let info = json!({
            "order": plan.order,
            "leaf_size": plan.leaf_size,
            "scheme": plan.scheme,
            "laplace_order": layers.laplace().map(|l| l.plan().order),
            "eps": plan.tolerance,
            "verified": solution.verified,
            "measured_error": solution.check.map(|e| json!({
                "velocity": e.velocity,
                "velocity_gradient": e.velocity_gradient,
                "pressure": e.pressure,
                "pressure_gradient": e.pressure_gradient,
                "worst": e.worst(),
                "sampled_targets": e.n_sampled,
            })),
            "threads": work.threads(),
            "ranks": work.size(),
            "cache": cache_words(stokes),
        });
        let velocity = PyArray1::from_vec(py, solution.values.velocity);
        let pressure = solution.values.pressure.map(|p| PyArray1::from_vec(py, p));
        Ok((velocity, pressure, info.to_string()))
    }

    /// Points this rank passed.
    #[getter]
    fn n_sources(&self) -> PyResult<usize> {
        Ok(self.lock()?.layers.stokes().points().len() / 3)
    }

    /// Points every rank passed, in rank order.
    #[getter]
    fn input_counts(&self) -> PyResult<Vec<u64>> {
        Ok(self.lock()?.layers.stokes().tree().input_counts.clone())
    }

    /// Targets of this rank (its points, without separate targets).
    #[getter]
    fn n_targets(&self) -> PyResult<usize> {
        Ok(self.lock()?.layers.n_targets())
    }

    /// Whether the sources carry forces, stresslets, and the pressure is
    /// computed.
    #[getter]
    fn carries(&self) -> (bool, bool, bool) {
        (
            self.wanted.forces,
            self.wanted.stresslets,
            self.wanted.pressure,
        )
    }
}

impl NativeDistStokesLayers {
    fn lock(&self) -> PyResult<std::sync::MutexGuard<'_, State>> {
        self.state
            .lock()
            .map_err(|_| PyValueError::new_err("a previous evaluation of this Fmm panicked"))
    }
}
