//! [`EwaldSum`]: the periodic potentials (and gradients) of a set of
//! charges, the reference of the periodic FMM.

use super::real_space::ShortRange;
use super::screening::Split;
use crate::lattice::{
    EwaldOptions, EwaldParameters, PeriodicCell, ReciprocalLattice, check_charges, check_indices,
    check_no_hessian, check_points,
};
use crate::{EvalMode, INV_4PI, KernelError};
use rayon::prelude::*;

/// The name errors give [`EwaldSum`].
const NAME: &str = "Ewald sum";

/// The Ewald sum of charges in a periodic cell, for the Laplace kernel with
/// conducting ("tin-foil") surroundings or the screened (Yukawa) kernel
/// `e^{-kappa r} / (4 pi r)` ([`EwaldOptions::screening`]). The Laplace
/// potential is
///
/// ```text
/// phi(y) = sum_j q_j G(y - x_j)
///        = 1/(4 pi) sum_j sum_n erfc(alpha |y - x_j - n∘L|) / |y - x_j - n∘L|      (|..| < r_c)
///        + sum_{k != 0, |k| <= k_c} (1/V) exp(-k^2/(4 alpha^2)) / k^2 Re(exp(i k.y) conj(S(k)))
///        - Q / (4 alpha^2 V)
/// ```
///
/// with `S(k) = sum_j q_j exp(i k . x_j)`, `Q = sum_j q_j`, and its gradient
/// with respect to `y`; see the [module docs](crate::ewald) for the conventions
/// (background for `Q != 0`, self terms, the cubic shape term). With
/// screening `kappa > 0` the lattice sum converges absolutely and
///
/// ```text
/// phi(y) = 1/(4 pi) sum_j sum_n q_j psi(|y - x_j - n∘L|)                  (|..| < r_c)
///        + sum_{k != 0, |k| <= k_c} (1/V) exp(-(k^2 + kappa^2)/(4 alpha^2)) / (k^2 + kappa^2)
///                                   Re(exp(i k.y) conj(S(k)))
///        + Q exp(-kappa^2 / (4 alpha^2)) / (V kappa^2)
/// ```
///
/// with `psi` the screened short-range kernel (`erfc(alpha r) / r` at
/// `kappa = 0`; see the module's `screening.rs`), no background and no
/// neutrality needed; `alpha` and the cut-offs are Laplace's. At a source
/// (`at_sources`, `all`, `energy`) its own pair is left out and its images
/// kept, `phi_i = sum_{j != i} q_j G(x_i - x_j) + q_i xi`; at a separate
/// point, a source at zero distance is treated in the same way.
///
/// Real space runs over a cell list, reciprocal space over precomputed
/// structure factors of half of the reciprocal lattice (phase tables by
/// recurrence per axis); both are parallel over targets with rayon, the
/// structure factors over `m_x`. See [`EwaldParameters`] for the cut-offs
/// and the choice of `alpha` (cost `O(N^1.5)` for all `N` targets).
///
/// ```
/// use ferrofmm_kernels::{EvalMode, EwaldSum, PeriodicCell};
/// // NaCl: Madelung constant from the rock-salt conventional cell.
/// let cell = PeriodicCell::cubic([0.0; 3], 2.0).unwrap();
/// let mut pos = Vec::new();
/// let mut q = Vec::new();
/// for i in 0..2 { for j in 0..2 { for k in 0..2 {
///     pos.extend([i as f64, j as f64, k as f64]);
///     q.push(if (i + j + k) % 2 == 0 { 1.0 } else { -1.0 });
/// }}}
/// let ewald = EwaldSum::new(cell, &pos, &q, 1e-15).unwrap();
/// let phi = ewald.at_sources(&[0], EvalMode::Potential).unwrap();
/// let madelung = -phi[0] * 4.0 * std::f64::consts::PI; // nearest neighbour at 1
/// assert!((madelung - 1.747_564_594_633_182).abs() < 1e-12);
/// ```
#[derive(Clone, Debug)]
pub struct EwaldSum {
    cell: PeriodicCell,
    params: EwaldParameters,
    split: Split,
    /// Wrapped positions relative to the origin, in source order.
    positions: Vec<[f64; 3]>,
    charges: Vec<f64>,
    total_charge: f64,
    cells: ShortRange,
    lattice: ReciprocalLattice,
    b_re: Vec<f64>,
    b_im: Vec<f64>,
}

impl EwaldSum {
    /// The Ewald sum of `charges` at `sources` (interleaved xyz, wrapped
    /// into the cell) to relative `tolerance`, tuned for evaluation at every
    /// source.
    ///
    /// # Errors
    /// [`KernelError::NotMultipleOf3`], [`KernelError::ChargesLength`],
    /// [`KernelError::NonFinite`] for bad points or charges;
    /// [`KernelError::InvalidParameter`] for a tolerance outside `(0, 1)` (or,
    /// through [`EwaldSum::with_options`], a screening that is negative or
    /// not finite).
    pub fn new(
        cell: PeriodicCell,
        sources: &[f64],
        charges: &[f64],
        tolerance: f64,
    ) -> Result<Self, KernelError> {
        Self::with_options(cell, sources, charges, EwaldOptions::new(tolerance))
    }

    /// As [`EwaldSum::new`], with [`EwaldOptions`] (e.g. the number of
    /// targets expected).
    ///
    /// # Errors
    /// As [`EwaldSum::new`].
    pub fn with_options(
        cell: PeriodicCell,
        sources: &[f64],
        charges: &[f64],
        options: EwaldOptions,
    ) -> Result<Self, KernelError> {
        let n = check_charges(sources, charges)?;
        let kappa = crate::error::check_wavenumber(options.screening)?;
        let params = match options.alpha {
            Some(alpha) => EwaldParameters::with_alpha(&cell, options.tolerance, alpha)?,
            None => EwaldParameters::balanced(
                &cell,
                options.tolerance,
                n,
                options.expected_targets.unwrap_or(n),
            )?,
        };
        let split = Split::new(params.alpha, kappa);
        let positions: Vec<[f64; 3]> = sources
            .chunks_exact(3)
            .map(|p| cell.wrap_relative([p[0], p[1], p[2]]))
            .collect();
        let cells = ShortRange::new(cell.lengths(), &positions, charges, params.r_cut, split);
        let lattice = ReciprocalLattice::new(cell.lengths(), params.kmax, params.k_cut, |k2| {
            split.fourier(k2)
        });
        let (b_re, b_im) = lattice.coefficients(&positions, charges);
        Ok(Self {
            cell,
            params,
            split,
            positions,
            charges: charges.to_vec(),
            total_charge: charges.iter().sum(),
            cells,
            lattice,
            b_re,
            b_im,
        })
    }

    /// The cell.
    pub fn cell(&self) -> &PeriodicCell {
        &self.cell
    }

    /// The splitting parameter and cut-offs in use.
    pub fn parameters(&self) -> &EwaldParameters {
        &self.params
    }

    /// The screening wavenumber `kappa` (`0`: Laplace).
    pub fn screening(&self) -> f64 {
        self.split.kappa()
    }

    /// The number of sources.
    pub fn n_sources(&self) -> usize {
        self.positions.len()
    }

    /// The number of wave vectors summed (half of the reciprocal lattice
    /// within `k_c`).
    pub fn n_wave_vectors(&self) -> usize {
        self.lattice.len()
    }

    /// `Q = sum_j q_j`; when not zero, the Laplace potentials include a
    /// uniform background of total charge `-Q` (screened ones need none).
    pub fn total_charge(&self) -> f64 {
        self.total_charge
    }

    /// The potential (and gradient, `mode`) at the sources `indices`, each
    /// without its own direct term (its images kept); `mode` values per
    /// index, interleaved.
    ///
    /// # Errors
    /// [`KernelError::SourceIndex`] for an index out of range,
    /// [`KernelError::Unsupported`] for Hessians.
    pub fn at_sources(&self, indices: &[usize], mode: EvalMode) -> Result<Vec<f64>, KernelError> {
        check_no_hessian(mode, NAME)?;
        check_indices(indices, self.n_sources())?;
        Ok(self.evaluate(indices.len(), |k| self.positions[indices[k]], mode))
    }

    /// The potential (and gradient) at separate `targets` (interleaved
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

    /// [`EwaldSum::at_sources`] at every source, in source order.
    ///
    /// # Errors
    /// [`KernelError::Unsupported`] for Hessians.
    pub fn all(&self, mode: EvalMode) -> Result<Vec<f64>, KernelError> {
        check_no_hessian(mode, NAME)?;
        Ok(self.evaluate(self.n_sources(), |k| self.positions[k], mode))
    }

    /// The energy `E = 1/2 sum_i q_i phi_i` (Laplace: tin-foil, with the
    /// background when `Q != 0`).
    pub fn energy(&self) -> f64 {
        let phi = self.evaluate(self.n_sources(), |k| self.positions[k], EvalMode::Potential);
        0.5 * phi
            .iter()
            .zip(&self.charges)
            .map(|(p, q)| p * q)
            .sum::<f64>()
    }

    /// Values at `count` targets given relative to the origin by `target`.
    fn evaluate<F>(&self, count: usize, target: F, mode: EvalMode) -> Vec<f64>
    where
        F: Fn(usize) -> [f64; 3] + Sync,
    {
        let grad = mode.has_gradient();
        let vpt = mode.values_per_target();
        // The `k = 0` term: Laplace's background, or the screened constant.
        let background = self.total_charge * self.split.k_zero(self.cell.volume());
        let mut out = vec![0.0; vpt * count];
        out.par_chunks_mut(vpt).enumerate().for_each_init(
            || self.lattice.scratch(),
            |scratch, (k, o)| {
                let t = target(k);
                let real = self.cells.sum(t, grad);
                let recip = self
                    .lattice
                    .evaluate(&self.b_re, &self.b_im, t, grad, scratch);
                for (v, (a, b)) in o.iter_mut().zip(real.iter().zip(&recip)) {
                    *v = INV_4PI * a + b;
                }
                o[0] += background;
            },
        );
        out
    }
}
