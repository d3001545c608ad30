//! What every Ewald sum here shares, whatever its kernel: the periodic
//! cell and the choice of the splitting parameter and cut-offs
//! ([`PeriodicCell`], [`EwaldOptions`], [`EwaldParameters`]), the cell list
//! that visits the sources within the real-space cut-off, the reciprocal
//! lattice with its structure factors and phase tables, and the loops over
//! images. The kernels' own splits and sums live with them:
//! `laplace/ewald/` (Laplace and Yukawa) and `stokes/ewald/` (Hasimoto's
//! Stokes sum).

mod cell_list;
mod images;
mod octant;
mod parameters;
mod reciprocal;
pub(crate) mod special;

pub(crate) use cell_list::CellList;
pub(crate) use images::{for_images, image_range, near_images, norm};
pub(crate) use octant::Octant;
pub(crate) use parameters::reduced_cutoff;
pub use parameters::{EwaldOptions, EwaldParameters, PeriodicCell};
pub(crate) use reciprocal::{ReciprocalLattice, phase_table};

use crate::{EvalMode, KernelError};

/// Interleaved points: a multiple of 3, all finite.
pub(crate) fn check_points(what: &'static str, points: &[f64]) -> Result<(), KernelError> {
    if !points.len().is_multiple_of(3) {
        return Err(KernelError::NotMultipleOf3 {
            what,
            len: points.len(),
        });
    }
    if let Some((index, &value)) = points.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(KernelError::NonFinite { what, index, value });
    }
    Ok(())
}

/// Interleaved `sources` and one finite charge for each: the number of
/// sources.
pub(crate) fn check_charges(sources: &[f64], charges: &[f64]) -> Result<usize, KernelError> {
    check_points("sources", sources)?;
    let n = sources.len() / 3;
    if charges.len() != n {
        return Err(KernelError::ChargesLength {
            n_sources: n,
            n_charges: charges.len(),
        });
    }
    if let Some((index, &value)) = charges.iter().enumerate().find(|(_, q)| !q.is_finite()) {
        return Err(KernelError::NonFinite {
            what: "charges",
            index,
            value,
        });
    }
    Ok(n)
}

/// Source indices below `n_sources`.
pub(crate) fn check_indices(indices: &[usize], n_sources: usize) -> Result<(), KernelError> {
    match indices.iter().find(|&&i| i >= n_sources) {
        Some(&index) => Err(KernelError::SourceIndex { index, n_sources }),
        None => Ok(()),
    }
}

/// An Ewald sum gives potentials and gradients, not Hessians.
pub(crate) fn check_no_hessian(mode: EvalMode, sum: &str) -> Result<(), KernelError> {
    if mode.has_hessian() {
        return Err(KernelError::Unsupported {
            kernel: sum.to_string(),
            kind: "charge",
            mode: mode.name(),
        });
    }
    Ok(())
}
