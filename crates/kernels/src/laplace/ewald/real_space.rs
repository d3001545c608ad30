//! The real-space part of the Laplace and Yukawa Ewald sums: the scalar
//! short-range pair sum `sum_j sum_n q_j psi(r)`, `r = |y - x_j - n∘L| <
//! r_c` (`psi(r) = erfc(alpha r) / r` for Laplace, the screened kernel's
//! in [`Split`]), over the shared [`CellList`].

use super::screening::Split;
use crate::lattice::CellList;

/// The scalar short-range sum of Laplace and Yukawa: a [`CellList`] with
/// the charges in its storage order and the kernel's [`Split`].
#[derive(Clone, Debug)]
pub(crate) struct ShortRange {
    cells: CellList,
    q: Vec<f64>,
    split: Split,
}

impl ShortRange {
    /// The sum over `positions` (relative, in `[0, L)`) with `charges`.
    pub(crate) fn new(
        lengths: [f64; 3],
        positions: &[[f64; 3]],
        charges: &[f64],
        r_cut: f64,
        split: Split,
    ) -> Self {
        let cells = CellList::new(lengths, positions, r_cut);
        let q = cells.sorted(charges);
        Self { cells, q, split }
    }

    /// `[sum, gx, gy, gz]` of `q_j psi(r)` over the sources and their
    /// images within `r_c` of `t` (relative, in `[0, L)`), **without** the
    /// factor `1/(4 pi)`; the gradient (with respect to `t`) only when
    /// `grad`. A pair at zero distance contributes its regular part
    /// `lim_{r->0} (psi(r) - e^{-kappa r} / r) = -l(0)` (Laplace: `-2 alpha
    /// / sqrt(pi)`) and no gradient.
    pub(crate) fn sum(&self, t: [f64; 3], grad: bool) -> [f64; 4] {
        let split = self.split;
        let mut acc = [0.0f64; 4];
        self.cells.visit(t, |k, d, r2| {
            let qj = self.q[k];
            if r2 < f64::MIN_POSITIVE {
                acc[0] -= qj * split.long(0.0);
                return;
            }
            let (psi, g) = split.short(r2.sqrt(), grad);
            acc[0] += qj * psi;
            if grad {
                let g = g * qj;
                acc[1] -= g * d[0];
                acc[2] -= g * d[1];
                acc[3] -= g * d[2];
            }
        });
        acc
    }
}
