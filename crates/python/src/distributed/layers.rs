//! `dist_stokes_layers`: Stokes forces and stresslets with the pressure
//! across ranks ([`DistStokesLayers`]), one call. The public wrapper is
//! `ferrofmm.distributed.stokes(..., strslet=, strsvec=, pressure=)`.

use std::path::PathBuf;

use ferrofmm_fmm::StokesRequest;
use ferrofmm_mpi::{DistStokesLayers, agree_text};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use serde_json::json;

use super::comm::AdoptedComm;
use super::fmm::{cache_words, dist_request};
use super::{Work, dist_error};

/// Velocities (flat, 3 or 12 per target), pressures (flat, 1 or 4 per
/// target, or `None`) and a JSON report of one evaluation of forces
/// and/or stresslets `(strslet, strsvec)` (flat, three values per point)
/// at this rank's targets. A collective: every rank passes its own rows.
#[pyfunction]
#[pyo3(signature = (comm, sources, targets, forces, strslet, strsvec, pressure, eps, order, leaf_size, scheme, gradient, verify, samples, threads, cache_dir, cache, dtype))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub(crate) fn dist_stokes_layers<'py>(
    py: Python<'py>,
    comm: i64,
    sources: PyReadonlyArray1<'_, f64>,
    targets: Option<PyReadonlyArray1<'_, f64>>,
    forces: Option<PyReadonlyArray1<'_, f64>>,
    strslet: Option<PyReadonlyArray1<'_, f64>>,
    strsvec: Option<PyReadonlyArray1<'_, f64>>,
    pressure: bool,
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
) -> PyResult<(
    Bound<'py, PyArray1<f64>>,
    Option<Bound<'py, PyArray1<f64>>>,
    String,
)> {
    let adopted = AdoptedComm::duplicate(comm)?;
    let local = dist_request(
        "stokes", None, eps, order, leaf_size, scheme, gradient, verify, samples, cache_dir, cache,
        "charge", dtype,
    );
    let request = agree_text(adopted.comm(), local.map_err(|e| e.to_string()))
        .map_err(PyValueError::new_err)?;
    let work = Work::new(adopted, threads)?;
    let flat = |a: Option<PyReadonlyArray1<'_, f64>>| -> PyResult<Option<Vec<f64>>> {
        a.map(|a| a.as_slice().map(<[f64]>::to_vec))
            .transpose()
            .map_err(Into::into)
    };
    let points = sources.as_slice()?.to_vec();
    let targets = flat(targets)?;
    let forces = flat(forces)?;
    let stresslets = match (flat(strslet)?, flat(strsvec)?) {
        (Some(m), Some(n)) => Some((m, n)),
        (None, None) => None,
        _ => {
            return Err(PyValueError::new_err("give strslet and strsvec together"));
        }
    };
    let wanted = StokesRequest {
        forces: forces.is_some(),
        stresslets: stresslets.is_some(),
        pressure,
    };
    let (solution, info) = work
        .run(py, |comm| -> Result<_, ferrofmm_mpi::DistError> {
            let mut layers = DistStokesLayers::build(comm, points, targets, request, wanted)?;
            let mn = stresslets.as_ref().map(|(m, n)| (&m[..], &n[..]));
            let solution = layers.evaluate(comm, forces.as_deref(), mn)?;
            let stokes = layers.stokes();
            let info = json!({
                "order": stokes.plan().order,
                "leaf_size": stokes.plan().leaf_size,
                "scheme": stokes.plan().scheme,
                "laplace_order": layers.laplace().map(|l| l.plan().order),
                "eps": stokes.plan().tolerance,
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
            Ok((solution, info))
        })
        .map_err(dist_error)?;
    let velocity = PyArray1::from_vec(py, solution.values.velocity);
    let pressure = solution.values.pressure.map(|p| PyArray1::from_vec(py, p));
    Ok((velocity, pressure, info.to_string()))
}
