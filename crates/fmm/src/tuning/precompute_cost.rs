//! What precomputing a tree's operators costs, predicted: the term that
//! decides between a small FMM and a direct sum.
//!
//! A tree of depth `D` whose far field starts at level 2 needs, for a
//! kernel without homogeneity (modified Helmholtz, Helmholtz), one set of
//! operators per level `2..=D` (`max(D - 1, 1)` sets); a homogeneous
//! kernel (Laplace, Stokes) needs one set, scaled to every level. With
//! `n` surface points, `c` kernel components and `F` FFT frequencies
//! ([`fft_frequencies`]), one set costs
//!
//! ```text
//! operators   OPERATOR_ENTRY_SECONDS (c n)^2 + OPERATOR_SET_SECONDS (c n)^3
//!                                                   check matrices, pseudo-inverses, M2M, L2L
//! M2L, FFT    FFT_SET_SECONDS c^2 F                 316 kernel transforms (2 F for a complex kernel)
//! M2L, SVD    SVD_ESTIMATE_SHARE svd_precompute_seconds c^3   the truncated SVDs
//! M2L, dense  DENSE_SET_SECONDS 316 (c n)^2        one kernel matrix per transfer vector
//! ```
//!
//! The operators were refitted on the 2-core Intel Xeon (2 threads, cold,
//! `ferrofmm demo --n 100000 --kernel laplace|helmholtz:10 --order P
//! --leaf-size 512 --scheme fft --no-cache`, two Helmholtz sets): Laplace
//! 12.5 / 38 / 125 / 311 ms at `p` = 6 / 8 / 10 / 12 (one set), Helmholtz
//! 45 / 169 / 610 / 1746 ms per set. One curve in `m = c n` holds both
//! within 30% (the cost grows as `m^2` at low orders, the kernel matrices
//! and products, and towards `m^3` at high ones, the pseudo-inverses);
//! the `(c n)^3` law alone (`2e-9`, fitted on the AMD machine's loaded
//! runs) overstated Helmholtz at `p = 12` 3.5x and steered the chooser to
//! a direct sum of 12 s where the FMM took 4 (`k D = 25`, 1e5 points,
//! eps 1e-8). The FFT M2L 0.03 / 0.07 / 0.19 / 0.27 s per real set; the
//! SVD M2L 1.4 / 6.6 / 34 s at `p` = 6 / 8 / 10 with the default SVD
//! tolerance (0.65 / 3.9 / 14 s at `1e-4`), about 0.45 times
//! [`SvdM2l::estimate`](ferrofmm_field::SvdM2l) on the loaded machine.
//! The figures were taken on a loaded machine and scaled to a quiet one;
//! they only need to be right within a factor of two or so: they weigh a
//! precomputation of seconds against a direct sum of seconds.

use ferrofmm_field::{M2lCostShape, fft_frequencies, n_surface_points};
use ferrofmm_kernels::Kernel;

use super::chooser::{ChosenParameters, svd_precompute_seconds};

/// Seconds per `(c n)^3` of one operator set (pseudo-inverses of the
/// check matrices), 2 threads.
pub const OPERATOR_SET_SECONDS: f64 = 3.3e-10;

/// Seconds per `(c n)^2` of one operator set (check matrices, M2M and
/// L2L products), 2 threads.
pub const OPERATOR_ENTRY_SECONDS: f64 = 3.5e-7;

/// Predicted seconds of one operator set of `m = c n` unknowns.
fn operator_set_seconds(m: f64) -> f64 {
    OPERATOR_ENTRY_SECONDS * m * m + OPERATOR_SET_SECONDS * m.powi(3)
}

/// Seconds per FFT frequency (times `c^2`) of one FFT M2L set, 2 threads.
pub const FFT_SET_SECONDS: f64 = 2.0e-5;

/// Seconds per matrix entry (`(c n)^2`, 316 matrices) of one dense M2L
/// set, 2 threads.
pub const DENSE_SET_SECONDS: f64 = 5.0e-9;

/// Share of [`svd_precompute_seconds`] (the SVD scheme's own estimate)
/// that its precomputation takes on a quiet machine.
pub const SVD_ESTIMATE_SHARE: f64 = 0.25;

/// Predicted seconds of precomputing, from nothing, the operators and the
/// M2L scheme (of cost shape `shape`) that `chosen`'s tree needs with
/// `kernel` (see the docs of the module `tuning::precompute_cost`).
pub fn precompute_seconds<K: Kernel>(
    kernel: &K,
    shape: M2lCostShape,
    chosen: &ChosenParameters,
) -> f64 {
    let p = chosen.order.max(2);
    let c = kernel.components() as f64;
    let n = c * n_surface_points(p) as f64;
    let depth = chosen.estimated_work.depth;
    if depth < 2 {
        // No V list: at most one set of operators, no M2L.
        return if depth == 0 {
            0.0
        } else {
            operator_set_seconds(n)
        };
    }
    let sets = match kernel.homogeneity() {
        Some(_) => 1.0,
        None => f64::from(depth - 1),
    };
    let m2l = match shape {
        // A complex kernel: one transform of `N^3` (about `2 F`) values.
        M2lCostShape::Fft if kernel.is_complex() => {
            FFT_SET_SECONDS * 2.0 * fft_frequencies(p) as f64
        }
        M2lCostShape::Fft => FFT_SET_SECONDS * c * c * fft_frequencies(p) as f64,
        M2lCostShape::Dense => DENSE_SET_SECONDS * 316.0 * n * n,
        _ => SVD_ESTIMATE_SHARE * svd_precompute_seconds(chosen) * c.powi(3),
    };
    sets * (operator_set_seconds(n) + m2l)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tuning::Occupancy;
    use crate::tuning::Tuner;
    use ferrofmm_kernels::{Helmholtz3d, Laplace3d, Precision};
    use ferrofmm_tree::DEEPEST_LEVEL;

    #[test]
    fn per_level_kernels_cost_more_and_higher_orders_cost_more() {
        let points: Vec<f64> = crate::Geometry::Cube.points(20_000, 1);
        let occ = Occupancy::new(&points, None, None, DEEPEST_LEVEL).unwrap();
        let tuner = Tuner::new(Precision::F64).for_scheme(M2lCostShape::Fft);
        let at = |p: usize| {
            let mut c = tuner.clone().with_order(p).choose_for(None, &occ).unwrap();
            c.estimated_work.depth = 4;
            c
        };
        let h = Helmholtz3d::new(5.0).unwrap();
        for p in [4, 6, 8, 10] {
            let c = at(p);
            let lap = precompute_seconds(&Laplace3d, M2lCostShape::Fft, &c);
            let helm = precompute_seconds(&h, M2lCostShape::Fft, &c);
            // Three sets (levels 2..=4) against one, each at least twice
            // a real kernel's (the complex FFT path: one transform of `N^3`
            // values; the operators: `(2 n)^3`).
            assert!(lap > 0.0 && helm > 6.0 * lap, "p = {p}: {lap} {helm}");
            let higher = precompute_seconds(&Laplace3d, M2lCostShape::Fft, &at(p + 2));
            assert!(higher > 2.0 * lap, "p = {p}: {lap} then {higher}");
        }
    }
}
