//! The Laplace kernel `K(x, y) = 1 / (4 pi |x - y|)`.

use crate::laplace_simd::{laplace_assemble_with, laplace_p2p_with};
use crate::{EvalMode, Kernel, Real, SimdLevel, SourceKind};

/// `1 / (4 pi)`: the factor of the 3D Laplace Green's function (and of the
/// modified Helmholtz one), applied once per target by their P2P loops.
pub const INV_4PI: f64 = 0.25 * std::f64::consts::FRAC_1_PI;

/// The 3D Laplace Green's function `K(x, y) = 1 / (4 pi |x - y|)`, the
/// solution of `-Delta u = delta`.
///
/// * homogeneous of degree `-1`: `K(s x, s y) = K(x, y) / s`;
/// * gradient with respect to the target `y`, with `d = y - x` and `r = |d|`:
///   `grad_y K = -d / (4 pi r^3)`.
///
/// [`Kernel::evaluate`] runs the vectorised P2P of
/// [`laplace_p2p_with`] at [`SimdLevel::active`]; [`Kernel::assemble`] the
/// vectorised [`laplace_assemble_with`].
///
/// ```
/// use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d};
/// let sources = [0.0f64, 0.0, 0.0, 1.0, 0.0, 0.0];
/// let charges = [1.0f64, -1.0];
/// let targets = [0.0f64, 0.0, 1.0];
/// let mut phi = [0.0f64];
/// Laplace3d.evaluate(EvalMode::Potential, &sources, &charges, &targets, &mut phi);
/// let k = 1.0 / (4.0 * std::f64::consts::PI);
/// assert!((phi[0] - k * (1.0 - 1.0 / 2f64.sqrt())).abs() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Laplace3d;

impl Kernel for Laplace3d {
    /// `"laplace3d"`.
    fn name(&self) -> String {
        "laplace3d".to_string()
    }

    /// `Some(-1.0)`.
    fn homogeneity(&self) -> Option<f64> {
        Some(-1.0)
    }

    /// `1 / (4 pi |d|)`, computed as `INV_4PI / sqrt(d.d)`.
    #[inline]
    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        T::from_f64(INV_4PI) / r2.sqrt()
    }

    /// `-d / (4 pi |d|^3)`.
    #[inline]
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        let rinv = T::ONE / r2.sqrt();
        let s = -(T::from_f64(INV_4PI) * rinv * rinv * rinv);
        [s * d[0], s * d[1], s * d[2]]
    }

    /// Vectorised P2P ([`laplace_p2p_with`] at [`SimdLevel::active`]).
    ///
    /// # Panics
    /// When lengths are inconsistent (see [`laplace_p2p_with`]).
    #[inline]
    fn evaluate<T: Real>(
        &self,
        mode: EvalMode,
        sources: &[T],
        charges: &[T],
        targets: &[T],
        out: &mut [T],
    ) {
        laplace_p2p_with(SimdLevel::active(), mode, sources, charges, targets, out);
    }

    /// Every source kind and output (charges and dipoles; potentials,
    /// gradients and Hessians), through the composed loop of
    /// [`lanes::RadialLaneKernel`](crate::lanes::RadialLaneKernel).
    fn supports(&self, _kind: SourceKind, _mode: EvalMode) -> bool {
        true
    }

    /// Charges with potentials or gradients take [`Kernel::evaluate`]'s
    /// loop; everything else the composed loop of
    /// [`lanes::evaluate_sources`](crate::lanes::evaluate_sources), at
    /// [`SimdLevel::active`].
    ///
    /// # Panics
    /// When lengths are inconsistent.
    fn evaluate_sources<T: Real>(
        &self,
        kind: SourceKind,
        mode: EvalMode,
        sources: &[T],
        densities: &[T],
        targets: &[T],
        out: &mut [T],
    ) {
        crate::lanes::evaluate_sources_with(
            SimdLevel::active(),
            self,
            kind,
            mode,
            sources,
            densities,
            targets,
            out,
        );
    }

    /// Vectorised, row-parallel assembly ([`laplace_assemble_with`]); equal
    /// to the pairwise reference bit for bit.
    ///
    /// # Panics
    /// When lengths are inconsistent.
    fn assemble<T: Real>(&self, sources: &[T], targets: &[T], matrix: &mut [T]) {
        laplace_assemble_with(SimdLevel::active(), sources, targets, matrix);
    }
}
