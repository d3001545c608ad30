//! Files through `ferrofmm-io`, the reader and writer of the `ferrofmm`
//! and `ferrofmm-mpi` commands: the same formats (`.csv`, `.npy`, raw
//! `.f64`), the same row rules and the same messages. The Python wrappers
//! (`ferrofmm.load`, `ferrofmm.save`) shape the arrays.

use std::path::PathBuf;

use ferrofmm_io::{Contents, FileError, Reader, Values};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::exceptions::{
    PyFileNotFoundError, PyIsADirectoryError, PyMemoryError, PyOSError, PyPermissionError,
    PyTypeError, PyValueError,
};
use pyo3::prelude::*;

/// A file error as the Python exception a caller expects: what the
/// operating system refused is an `OSError` (`FileNotFoundError`,
/// `PermissionError`, `IsADirectoryError`), a read beyond the memory
/// limit a `MemoryError`, anything wrong with the contents a `ValueError`;
/// the message is the commands' own.
pub(crate) fn file_error(e: FileError) -> PyErr {
    let message = e.to_string();
    match &e {
        FileError::Io { source, .. } | FileError::WriteFailed { source, .. } => {
            match source.kind() {
                std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
                std::io::ErrorKind::PermissionDenied => PyPermissionError::new_err(message),
                _ => PyOSError::new_err(message),
            }
        }
        FileError::IsDirectory(_) => PyIsADirectoryError::new_err(message),
        FileError::OutputUnusable { .. } => PyOSError::new_err(message),
        FileError::TooLarge { .. } => PyMemoryError::new_err(message),
        _ => PyValueError::new_err(message),
    }
}

/// What `what` names, for a kernel of `components` components that may be
/// `complex`.
fn contents(what: &str, components: usize, complex: bool) -> PyResult<Contents> {
    match what {
        "points" => Ok(Contents::Points),
        "charges" => Ok(Contents::charges(components, complex)),
        "dipoles" => Ok(Contents::dipoles(components, complex)),
        other => Err(PyValueError::new_err(format!(
            "what must be 'points', 'charges' or 'dipoles', got {other:?}"
        ))),
    }
}

/// Read `path` as `what` (`points`, `charges`, `dipoles`) of a kernel with
/// `components` components (`complex`: `re, im` pairs), within the memory
/// limit of the commands: the values (flat, `float64`), the values per
/// row, and whether the file held complex numbers. The GIL is released
/// while reading.
#[pyfunction]
pub(crate) fn read_file<'py>(
    py: Python<'py>,
    path: PathBuf,
    what: &str,
    components: usize,
    complex: bool,
) -> PyResult<(Bound<'py, PyArray1<f64>>, usize, bool)> {
    let contents = contents(what, components, complex)?;
    let limit = ferrofmm_field::MemoryLimit::Auto
        .resolve()
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let table = py
        .detach(|| {
            Reader::new()
                .memory_limit(limit)
                .read_table(&path, contents, |n| 0..n)
        })
        .map_err(file_error)?;
    Ok((
        PyArray1::from_vec(py, table.values),
        contents.columns(),
        table.complex,
    ))
}

/// Write `values` (flat, `float64` or `float32`; `re, im` pairs when
/// `complex`) as records of `names.len()` columns to `path`, atomically,
/// as the commands write their outputs (a `.csv` header line of `names`;
/// a `.npy` array, complex when `complex`). Checked first as the commands
/// check `--out` (a `.csv` or `.npy` name, not a directory, in a directory
/// that takes a new file).
#[pyfunction]
pub(crate) fn write_file(
    py: Python<'_>,
    path: PathBuf,
    values: &Bound<'_, PyAny>,
    names: Vec<String>,
    complex: bool,
) -> PyResult<()> {
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let write = |values: Values<'_>| {
        ferrofmm_io::output::check(&path, &[])?;
        if complex {
            ferrofmm_io::write_complex(&path, values, &names)
        } else {
            ferrofmm_io::write(&path, values, &names)
        }
    };
    let written = if let Ok(v) = values.extract::<PyReadonlyArray1<'_, f64>>() {
        let v = v.as_slice()?;
        py.detach(|| write(Values::F64(v)))
    } else if let Ok(v) = values.extract::<PyReadonlyArray1<'_, f32>>() {
        let v = v.as_slice()?;
        py.detach(|| write(Values::F32(v)))
    } else {
        return Err(PyTypeError::new_err(
            "values must be a contiguous float64 or float32 array",
        ));
    };
    written.map_err(file_error)
}

/// The column names of an output with `values_per_target` quantities for
/// a kernel with the components `component_names`: the header of the
/// commands' CSV outputs (`potential`, `grad_x`, ...; `potential_re`,
/// `potential_im`, ... for Helmholtz).
#[pyfunction]
pub(crate) fn column_names(values_per_target: usize, component_names: Vec<String>) -> Vec<String> {
    let components: Vec<&str> = component_names.iter().map(String::as_str).collect();
    ferrofmm_io::column_names(values_per_target, &components)
}
