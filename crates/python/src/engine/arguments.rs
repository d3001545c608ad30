//! The keyword arguments of `NativeFmm` (and the distributed run's)
//! checked and turned into library values: kernel, source kind, accuracy,
//! periodic cell.

use ferrofmm_fmm::{Periodic, PeriodicAxes, SurfaceTerm};
use ferrofmm_kernels::{KernelChoice, SourceKind};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::errors::fmm_error;

/// The periodic cell of `box=`, `box_origin=`, `periodic=` and `surface=`
/// (as the command line's `--box`, `--box-origin`, `--periodic`,
/// `--surface`), checked; `None` without a box.
pub(super) fn periodic_cell(
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

/// The kernel `kernel` names with its parameter `k` (`(re, im)`: a
/// complex wavenumber for Helmholtz), or `ValueError` saying what is
/// missing or misplaced.
pub(crate) fn kernel_choice(kernel: &str, k: Option<(f64, f64)>) -> PyResult<KernelChoice> {
    match k {
        Some((re, im)) => KernelChoice::from_complex_parts(kernel, re, im),
        None => KernelChoice::from_parts(kernel, None),
    }
    .map_err(|e| {
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
