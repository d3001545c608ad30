//! Checks on resources before any work: the memory a run needs, the cache
//! directory.

use std::path::Path;

use ferrofmm_fmm::{MemoryLimit, MemoryReport, RunSize, check_memory};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::errors::fmm_error;

/// Raise `MemoryError` when a run of `n_sources` sources, `n_targets`
/// separate targets (`None`: the sources), `values_per_source` values per
/// source and vector, `values_per_target` per target and `n_vectors`
/// density vectors in `dtype` is predicted
/// ([`MemoryReport::predict`], plus this module's own copies: the input
/// handed over, a converted copy of it, the densities and the reshaped
/// results) to need more than the memory limit
/// (`FERROFMM_MEMORY_LIMIT`, else the memory available, lowered by
/// `RLIMIT_AS`). With `build` false, only the evaluation's share (the
/// FMM is built: its points are allocated). Called by the Python wrapper before it copies or
/// converts anything: it needs the shapes only.
#[pyfunction]
#[pyo3(signature = (what, dtype, n_sources, n_targets, values_per_source, values_per_target, n_vectors, build=true))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn check_run_memory(
    what: &str,
    dtype: &str,
    n_sources: usize,
    n_targets: Option<usize>,
    values_per_source: usize,
    values_per_target: usize,
    n_vectors: usize,
    build: bool,
) -> PyResult<()> {
    let size = RunSize {
        n_sources,
        n_targets,
        values_per_source,
        values_per_target,
        n_vectors,
    };
    // An evaluation of an FMM already built: its points are allocated.
    let (library, t) = match (dtype, build) {
        ("float32", true) => (MemoryReport::predict::<f32>(&size), 4u128),
        ("float64", true) => (MemoryReport::predict::<f64>(&size), 8u128),
        ("float32", false) => (MemoryReport::predict_evaluation::<f32>(&size), 4),
        ("float64", false) => (MemoryReport::predict_evaluation::<f64>(&size), 8),
        (other, _) => {
            return Err(PyValueError::new_err(format!(
                "dtype must be float32 or float64, got {other}"
            )));
        }
    };
    let (n, m) = (n_sources as u128, n_targets.unwrap_or(0) as u128);
    let m_all = n_targets.unwrap_or(n_sources) as u128;
    let k = n_vectors as u128;
    // The points handed over and a converted copy of them; the densities
    // (converted and copied); the results reshaped by the wrapper.
    // Points go over in their own precision (at most f64).
    let points = if build { 2 * 3 * (n + m) * 8 } else { 0 };
    let own = points
        + 2 * k * n * values_per_source as u128 * t
        + k * m_all * values_per_target as u128 * t;
    let needed = u64::try_from(library as u128 + own).unwrap_or(u64::MAX);
    check_memory(needed, MemoryLimit::Auto, what).map_err(fmm_error)
}

/// A cache directory that exists and is not a directory, or that cannot
/// be created, is an error before any work (the library would compute
/// the operators and only fail to save them, silently for the caller).
pub(crate) fn check_cache_dir(dir: &Path) -> PyResult<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(PyValueError::new_err(format!(
            "cache_dir {} exists and is not a directory",
            dir.display()
        )));
    }
    std::fs::create_dir_all(dir).map_err(|e| {
        PyValueError::new_err(format!(
            "cache_dir {} cannot be created: {e}",
            dir.display()
        ))
    })
}
