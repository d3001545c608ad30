//! The float types a run accepts ([`Float`], [`Floats`]) and their flat
//! NumPy arrays, copied without aborting on a failed allocation
//! ([`try_copy`]).

use ferrofmm_kernels::Real;
use numpy::{Element, PyArray1, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::{PyMemoryError, PyTypeError, PyValueError};
use pyo3::prelude::*;

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
    pub(super) fn into_numpy(self, py: Python<'_>) -> Bound<'_, PyAny> {
        match self {
            Floats::F32(v) => PyArray1::from_vec(py, v).into_any(),
            Floats::F64(v) => PyArray1::from_vec(py, v).into_any(),
        }
    }

    /// The values in `f64` (f32 widens exactly).
    pub(crate) fn into_f64(self) -> Vec<f64> {
        f64::unwrap(self)
    }

    pub(super) fn len(&self) -> usize {
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
