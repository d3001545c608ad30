//! Lattice sums pair by pair, for Green's functions evaluated one
//! displacement at a time (slabs and rods, whose reciprocal sums do not
//! factor into structure factors): `sum_j q_j G(t - x_j)` at targets or at
//! sources, and the far-image matrix of the periodisation operator. Many
//! sources within a cell's extent go through `interpolated.rs` instead.

use rayon::prelude::*;

use super::screening::Split;
use crate::lattice::{PeriodicCell, check_charges, check_indices, check_no_hessian, check_points};
use crate::{EvalMode, INV_4PI, KernelError};

/// A Green's function summed pair by pair.
pub(crate) trait PairGreen: Sync {
    /// `[G, dG/dx, dG/dy, dG/dz]` at displacement `r` (target minus
    /// source).
    fn value(&self, r: [f64; 3]) -> [f64; 4];
    /// `lim_{r -> 0} (G(r) - K(r))`.
    fn self_potential(&self) -> f64;
    /// The sum's name, for errors.
    fn name(&self) -> &'static str;
    /// `[G, grad G]` without the images `|n_a| <= m` along the repeating
    /// axes.
    fn far(&self, r: [f64; 3], m: i64) -> [f64; 4];
    /// The screening `kappa` of the kernel `e^{-kappa r} / (4 pi r)`.
    fn kappa(&self) -> f64;
    /// The cell, which axes repeat, and the tolerance.
    fn cell(&self) -> (&PeriodicCell, [bool; 3], f64);
}

/// The real-space part of a Green's function without its near images,
/// with its gradient when `grad`: over the images `(near, d, |d|)` that
/// `images` visits, `-l(|d|)` for the near ones (their long-range part,
/// which the reciprocal sum holds) and `psi(|d|)` for the others within
/// `r_cut`, times `1 / (4 pi)`.
pub(crate) fn far_real(
    split: &Split,
    r_cut: f64,
    grad: bool,
    images: impl FnOnce(&mut dyn FnMut(bool, [f64; 3], f64)),
) -> [f64; 4] {
    let mut real = [0.0; 4];
    images(&mut |near, d, rho| {
        let (v, g) = if near {
            let g = if grad { split.long_gradient(rho) } else { 0.0 };
            (-split.long(rho), -g)
        } else if rho < r_cut {
            split.short(rho, grad)
        } else {
            return;
        };
        real[0] += v;
        for a in 0..3 {
            real[1 + a] -= g * d[a];
        }
    });
    real.map(|v| INV_4PI * v)
}

/// `M[i * n_s + j] = far(t_i - s_j)`, row-major, parallel over rows.
pub(crate) fn far_matrix(
    targets: &[f64],
    sources: &[f64],
    far: impl Fn([f64; 3]) -> f64 + Sync,
) -> Result<Vec<f64>, KernelError> {
    check_points("targets", targets)?;
    check_points("sources", sources)?;
    let ns = sources.len() / 3;
    let mut out = vec![0.0; targets.len() / 3 * ns];
    if ns == 0 {
        return Ok(out);
    }
    out.par_chunks_mut(ns).enumerate().for_each(|(i, row)| {
        let t = &targets[3 * i..3 * i + 3];
        for (v, s) in row.iter_mut().zip(sources.chunks_exact(3)) {
            *v = far([t[0] - s[0], t[1] - s[1], t[2] - s[2]]);
        }
    });
    Ok(out)
}

fn check(
    green: &impl PairGreen,
    sources: &[f64],
    charges: &[f64],
    mode: EvalMode,
) -> Result<usize, KernelError> {
    check_no_hessian(mode, green.name())?;
    check_charges(sources, charges)
}

/// `sum_j q_j G(t - x_j)` (and the gradient) at every target.
pub(crate) fn at_points(
    green: &impl PairGreen,
    sources: &[f64],
    charges: &[f64],
    targets: &[f64],
    mode: EvalMode,
) -> Result<Vec<f64>, KernelError> {
    check(green, sources, charges, mode)?;
    check_points("targets", targets)?;
    let t: Vec<[f64; 3]> = targets
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    Ok(sum(green, sources, charges, &t, None, mode))
}

/// The same at sources, each leaving out only itself.
pub(crate) fn at_sources(
    green: &impl PairGreen,
    sources: &[f64],
    charges: &[f64],
    indices: &[usize],
    mode: EvalMode,
) -> Result<Vec<f64>, KernelError> {
    let n = check(green, sources, charges, mode)?;
    check_indices(indices, n)?;
    let t: Vec<[f64; 3]> = indices
        .iter()
        .map(|&i| [sources[3 * i], sources[3 * i + 1], sources[3 * i + 2]])
        .collect();
    Ok(sum(green, sources, charges, &t, Some(indices), mode))
}

fn sum(
    green: &impl PairGreen,
    sources: &[f64],
    charges: &[f64],
    targets: &[[f64; 3]],
    own: Option<&[usize]>,
    mode: EvalMode,
) -> Vec<f64> {
    let w = if mode.has_gradient() { 4 } else { 1 };
    if let Some(out) = super::interpolated::sum(green, sources, charges, targets, w) {
        return out;
    }
    let mut out = vec![0.0; w * targets.len()];
    out.par_chunks_mut(w).enumerate().for_each(|(i, o)| {
        let t = targets[i];
        let me = own.map(|own| own[i]);
        let mut acc = [0.0f64; 4];
        for (j, (s, &q)) in sources.chunks_exact(3).zip(charges).enumerate() {
            if Some(j) == me {
                acc[0] += q * green.self_potential();
                continue;
            }
            let v = green.value([t[0] - s[0], t[1] - s[1], t[2] - s[2]]);
            for a in 0..4 {
                acc[a] += q * v[a];
            }
        }
        o.copy_from_slice(&acc[..w]);
    });
    out
}
