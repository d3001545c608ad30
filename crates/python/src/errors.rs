//! Library errors as Python exceptions.

use ferrofmm_fmm::FmmError;
use ferrofmm_tree::TreeError;
use pyo3::PyErr;
use pyo3::exceptions::{PyKeyboardInterrupt, PyMemoryError, PyValueError};

/// Bad input and impossible parameters are `ValueError` (with the
/// library's message, the same the command line prints); a precomputation
/// or a run predicted beyond the memory limit is `MemoryError`; a cancelled one is
/// `KeyboardInterrupt` (it was cancelled by Ctrl-C).
pub(crate) fn fmm_error(e: FmmError) -> PyErr {
    if e.is_cancelled() {
        return PyKeyboardInterrupt::new_err("interrupted during the operator precomputation");
    }
    match e {
        FmmError::PrecomputeMemory { .. } | FmmError::RunMemory { .. } => {
            PyMemoryError::new_err(e.to_string())
        }
        other => PyValueError::new_err(other.to_string()),
    }
}

/// Every tree error is bad input or a bad parameter.
pub(crate) fn tree_error(e: TreeError) -> PyErr {
    PyValueError::new_err(e.to_string())
}
