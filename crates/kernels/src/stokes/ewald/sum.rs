//! [`StokesEwaldSum`]: the periodic velocities (and velocity gradients) of
//! point forces, the reference of the periodic Stokes FMM.

use super::split::HasimotoSplit;
use crate::lattice::{
    CellList, EwaldOptions, EwaldParameters, PeriodicCell, ReciprocalLattice, check_indices,
    check_no_hessian, check_points,
};
use crate::{EvalMode, KernelError};
use rayon::prelude::*;

/// The name errors give [`StokesEwaldSum`].
const NAME: &str = "Stokes Ewald sum";
use std::f64::consts::PI;

/// How much tighter than asked the cut-offs are set: the Stokes terms carry
/// factors Laplace's do not (`2 alpha r / sqrt(pi)` in real space, `1 +
/// k^2 / (4 alpha^2)` in Fourier space, each about `s^2 ~ 40` at the
/// cut-offs).
pub(crate) const TOLERANCE_MARGIN: f64 = 1e-2;

/// The Ewald (Hasimoto) sum of point forces in a periodic cell: the
/// velocity
///
/// ```text
/// u(y) = sum_j G_per(y - x_j) f_j
///      = 1/(8 pi mu) sum_j sum_n S_R(y - x_j - n∘L) f_j                 (|..| < r_c)
///      + sum_{k != 0, |k| <= k_c} (1/(mu V)) (1 + k^2/(4 alpha^2)) e^{-k^2/(4 alpha^2)} / k^2
///                                 (I - k k^T / k^2) Re(e^{i k.y} conj(S(k)))
/// ```
///
/// with `S(k) = sum_j f_j e^{i k . x_j}` (a 3-vector) and `S_R` the
/// short-range part of the [module docs](super), and its gradient with
/// respect to `y` (`d_c u_i` at index `3 + 3 c + i`, the layout of
/// [`Stokes3d`](crate::Stokes3d)). The `k = 0` term is dropped: the mean
/// velocity over the cell is zero, and a net force `F = sum_j f_j` is
/// balanced by a uniform pressure gradient `-F / V` (Hasimoto's
/// convention; no neutrality is needed). At a source its own direct term
/// is left out and its images kept; a separate target at zero distance
/// from a source is treated the same way.
///
/// Real space runs over a cell list, Fourier space over the structure
/// factors of the three force components on half of the reciprocal
/// lattice; both are parallel over targets. `alpha` and the cut-offs
/// follow Laplace's rule ([`EwaldParameters`]) at a tolerance 100 times
/// tighter than asked, which covers the Stokes terms' extra factors.
///
/// ```
/// use ferrofmm_kernels::{EvalMode, PeriodicCell, StokesEwaldSum};
/// // A simple cubic array of unit forces: Hasimoto's self-mobility
/// // correction, u = -2.837297 F / (6 pi mu L).
/// let cell = PeriodicCell::cubic([0.0; 3], 1.0).unwrap();
/// let ewald = StokesEwaldSum::new(cell, &[0.5; 3], &[1.0, 0.0, 0.0], 1.0, 1e-14).unwrap();
/// let u = ewald.at_sources(&[0], EvalMode::Potential).unwrap();
/// let expected = -2.837_297_479_480_6 / (6.0 * std::f64::consts::PI);
/// assert!((u[0] - expected).abs() < 1e-12 && u[1].abs() < 1e-14);
/// ```
#[derive(Clone, Debug)]
pub struct StokesEwaldSum {
    cell: PeriodicCell,
    params: EwaldParameters,
    viscosity: f64,
    split: HasimotoSplit,
    /// Wrapped positions relative to the origin, in source order.
    positions: Vec<[f64; 3]>,
    cells: CellList,
    /// The forces in the cell list's storage order.
    forces: Vec<[f64; 3]>,
    lattice: ReciprocalLattice,
    /// Per velocity component `i`: `B_k = c_k sum_j (I - k k^T/k^2)_ij
    /// conj(S_j(k))` as `(re, im)`.
    coefficients: [(Vec<f64>, Vec<f64>); 3],
}

impl StokesEwaldSum {
    /// The sum of the point `forces` (three per source, interleaved) at
    /// `sources` (interleaved xyz, wrapped into the cell) in a fluid of
    /// `viscosity`, to relative `tolerance`, tuned for evaluation at every
    /// source.
    ///
    /// # Errors
    /// [`KernelError::NotMultipleOf3`], [`KernelError::ChargesLength`],
    /// [`KernelError::NonFinite`] for bad points or forces;
    /// [`KernelError::InvalidParameter`] for a tolerance outside `(0, 1)`
    /// or a viscosity that is not finite and positive.
    pub fn new(
        cell: PeriodicCell,
        sources: &[f64],
        forces: &[f64],
        viscosity: f64,
        tolerance: f64,
    ) -> Result<Self, KernelError> {
        Self::with_options(
            cell,
            sources,
            forces,
            viscosity,
            EwaldOptions::new(tolerance),
        )
    }

    /// As [`StokesEwaldSum::new`] with [`EwaldOptions`] (the number of
    /// targets expected, a forced `alpha`).
    ///
    /// # Errors
    /// As [`StokesEwaldSum::new`], and [`KernelError::InvalidParameter`]
    /// for a screening other than zero.
    pub fn with_options(
        cell: PeriodicCell,
        sources: &[f64],
        forces: &[f64],
        viscosity: f64,
        options: EwaldOptions,
    ) -> Result<Self, KernelError> {
        check_points("sources", sources)?;
        let n = sources.len() / 3;
        if forces.len() != 3 * n {
            return Err(KernelError::ChargesLength {
                n_sources: 3 * n,
                n_charges: forces.len(),
            });
        }
        if let Some((index, &value)) = forces.iter().enumerate().find(|(_, f)| !f.is_finite()) {
            return Err(KernelError::NonFinite {
                what: "forces",
                index,
                value,
            });
        }
        let viscosity = crate::Stokes3d::new(viscosity)?.viscosity;
        if options.screening != 0.0 {
            return Err(KernelError::InvalidParameter {
                name: "screening",
                value: options.screening,
                expected: "0 for the Stokeslet",
            });
        }
        if !(options.tolerance.is_finite() && options.tolerance > 0.0 && options.tolerance < 1.0) {
            return Err(KernelError::InvalidParameter {
                name: "tolerance",
                value: options.tolerance,
                expected: "finite, > 0 and < 1",
            });
        }
        let tol = options.tolerance * TOLERANCE_MARGIN;
        let params = match options.alpha {
            Some(alpha) => EwaldParameters::with_alpha(&cell, tol, alpha)?,
            None => {
                EwaldParameters::balanced(&cell, tol, n, options.expected_targets.unwrap_or(n))?
            }
        };
        let split = HasimotoSplit::new(params.alpha);
        let positions: Vec<[f64; 3]> = sources
            .chunks_exact(3)
            .map(|p| cell.wrap_relative([p[0], p[1], p[2]]))
            .collect();
        let per_source: Vec<[f64; 3]> =
            forces.chunks_exact(3).map(|f| [f[0], f[1], f[2]]).collect();
        let cells = CellList::new(cell.lengths(), &positions, params.r_cut);
        let sorted = cells.sorted(&per_source);
        // The coefficients are made below from the structure factors.
        let lattice = ReciprocalLattice::new(cell.lengths(), params.kmax, params.k_cut, |_| 0.0);
        let factors: Vec<(Vec<f64>, Vec<f64>)> = (0..3)
            .into_par_iter()
            .map(|j| {
                let q: Vec<f64> = per_source.iter().map(|f| f[j]).collect();
                lattice.structure_factors(&positions, &q)
            })
            .collect();
        let scale = 2.0 / (8.0 * PI * viscosity * cell.volume());
        let wave = lattice.wave_vectors();
        let mut coefficients: [(Vec<f64>, Vec<f64>); 3] = Default::default();
        for (i, (re, im)) in coefficients.iter_mut().enumerate() {
            *re = vec![0.0; wave.len()];
            *im = vec![0.0; wave.len()];
            for (k, kv) in wave.iter().enumerate() {
                let k2 = kv[0] * kv[0] + kv[1] * kv[1] + kv[2] * kv[2];
                let c = scale * split.fourier(k2);
                let (mut sr, mut si) = (0.0, 0.0);
                for (j, (fr, fi)) in factors.iter().enumerate() {
                    let delta = if i == j { 1.0 } else { 0.0 };
                    let p = delta - kv[i] * kv[j] / k2;
                    sr += p * fr[k];
                    si += p * fi[k];
                }
                re[k] = c * sr;
                im[k] = -c * si;
            }
        }
        Ok(Self {
            cell,
            params,
            viscosity,
            split,
            positions,
            cells,
            forces: sorted,
            lattice,
            coefficients,
        })
    }

    /// The cell.
    pub fn cell(&self) -> &PeriodicCell {
        &self.cell
    }

    /// The splitting parameter and cut-offs in use (at the tightened
    /// tolerance).
    pub fn parameters(&self) -> &EwaldParameters {
        &self.params
    }

    /// The viscosity `mu`.
    pub fn viscosity(&self) -> f64 {
        self.viscosity
    }

    /// The number of sources.
    pub fn n_sources(&self) -> usize {
        self.positions.len()
    }

    /// The velocity (and gradient, `mode`) at the sources `indices`, each
    /// without its own direct term (its images kept): `3` (or `12`) values
    /// per index, interleaved.
    ///
    /// # Errors
    /// [`KernelError::SourceIndex`] for an index out of range,
    /// [`KernelError::Unsupported`] for Hessians.
    pub fn at_sources(&self, indices: &[usize], mode: EvalMode) -> Result<Vec<f64>, KernelError> {
        check_no_hessian(mode, NAME)?;
        check_indices(indices, self.n_sources())?;
        Ok(self.evaluate(indices.len(), |k| self.positions[indices[k]], mode))
    }

    /// The velocity (and gradient) at separate `targets` (interleaved
    /// xyz); a source at zero distance from a target leaves out its direct
    /// term (as at a source).
    ///
    /// # Errors
    /// [`KernelError::NotMultipleOf3`] or [`KernelError::NonFinite`] for
    /// bad targets, [`KernelError::Unsupported`] for Hessians.
    pub fn at_points(&self, targets: &[f64], mode: EvalMode) -> Result<Vec<f64>, KernelError> {
        check_no_hessian(mode, NAME)?;
        check_points("targets", targets)?;
        Ok(self.evaluate(
            targets.len() / 3,
            |k| {
                self.cell
                    .wrap_relative([targets[3 * k], targets[3 * k + 1], targets[3 * k + 2]])
            },
            mode,
        ))
    }

    /// [`StokesEwaldSum::at_sources`] at every source, in source order.
    ///
    /// # Errors
    /// [`KernelError::Unsupported`] for Hessians.
    pub fn all(&self, mode: EvalMode) -> Result<Vec<f64>, KernelError> {
        check_no_hessian(mode, NAME)?;
        Ok(self.evaluate(self.n_sources(), |k| self.positions[k], mode))
    }

    /// Values at `count` targets given relative to the origin by `target`.
    fn evaluate<F>(&self, count: usize, target: F, mode: EvalMode) -> Vec<f64>
    where
        F: Fn(usize) -> [f64; 3] + Sync,
    {
        let grad = mode.has_gradient();
        let w = 3 * mode.values_per_target();
        let inv = 1.0 / (8.0 * PI * self.viscosity);
        let at_zero = self.split.long(0.0).a;
        let mut out = vec![0.0; w * count];
        out.par_chunks_mut(w).enumerate().for_each_init(
            || self.lattice.scratch(),
            |scratch, (k, o)| {
                let t = target(k);
                let mut acc = [0.0f64; 12];
                self.cells.visit(t, |j, d, r2| {
                    let f = self.forces[j];
                    if r2 < f64::MIN_POSITIVE {
                        // The pair's regular part: -S_L(0) = -(4 alpha / sqrt(pi)) I.
                        for i in 0..3 {
                            acc[i] -= at_zero * f[i];
                        }
                        return;
                    }
                    self.split
                        .short(r2.sqrt(), grad)
                        .apply(d, f, grad, &mut acc);
                });
                for (i, v) in o.iter_mut().take(3).enumerate() {
                    *v = inv * acc[i];
                }
                if grad {
                    for (v, a) in o[3..].iter_mut().zip(&acc[3..]) {
                        *v = inv * a;
                    }
                }
                for (i, (re, im)) in self.coefficients.iter().enumerate() {
                    let r = self.lattice.evaluate(re, im, t, grad, scratch);
                    o[i] += r[0];
                    if grad {
                        for c in 0..3 {
                            o[3 + 3 * c + i] += r[1 + c];
                        }
                    }
                }
            },
        );
        out
    }
}
