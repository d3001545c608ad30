//! The Laplace kernel `K(x, y) = 1 / (4 pi |x - y|)`: its maths and
//! [`Kernel`] impl (here), its micro-kernels in the lane engine of
//! [`crate::lanes`] (`pair.rs`) and its dense assembly (`assemble.rs`).
//!
//! # Maths
//! With `d = x - y` (source minus target) and `r = |d|`,
//!
//! ```text
//! K = 1 / (4 pi r),    grad_y K = d / (4 pi r^3)
//! ```
//!
//! and the radial derivatives behind dipoles and Hessians
//! ([`crate::lanes::RadialLaneKernel`]) are
//! `f_0 = 1/r`, `f_1 = -1/r^3`, `f_2 = 3/r^5`, `f_3 = -15/r^7`.
//!
//! # P2P
//! Per pair: `r2 = |d|^2` (FMA), `rinv ~ 1/sqrt(r2)`, `phi += q rinv`, and
//! with gradients `g += q rinv^3 d` (`= -q (y - x) / r^3`, written without a
//! negation so that the compiler keeps plain FMAs). The factor `1/(4 pi)` is
//! applied once per target at the end.
//!
//! # Reciprocal square root
//! * AVX-512: `vrsqrt14` (relative error `< 2^-14`) refined to full precision.
//!   With `e = 1 - r2 y^2` the exact value is `y (1 - e)^(-1/2)
//!   = y (1 + e/2 + 3e^2/8 + 5e^3/16 + ...)`. `f64` uses the terms up to
//!   `e^3` (truncation `< 4.4 * 2^-56`), `f32` one Newton step `y (1 + e/2)`
//!   (truncation `< 1.5 * 2^-28`); both are below half an ulp.
//! * AVX2 `f32`: `vrsqrtps` (`< 1.5 * 2^-12`) refined with the terms up to
//!   `e^2` (truncation `< 2.5 (1.5 * 2^-12)^3 ~ 1.3e-10`).
//! * AVX2 `f64` and the portable path: exact `sqrt` and division.
//!
//! # Coincident points and ranges
//! A pair counts as coincident when `r2` is below the smallest normal number
//! of `T` (`|d| < ~1.1e-19` in `f32`, `~1.5e-154` in `f64`, which includes
//! `d == 0` and `r2` underflowing to zero) and contributes exactly zero in
//! every path: the SIMD paths zero it with a mask (on the estimate for
//! AVX-512, after the reciprocal for AVX2), so no NaN or Inf can reach the
//! sums (`vrsqrtps` would flush such subnormal `r2` to zero and produce NaN).
//! A NaN `r2` also contributes zero (ordered comparisons); validate input
//! with [`check_inputs`](crate::check_inputs) where that matters.

mod assemble;
pub mod ewald;
mod pair;

pub use assemble::laplace_assemble_with;

use crate::{EvalMode, Kernel, Real, SimdLevel, SourceKind, lanes};

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

    crate::lanes::kernel_entry_points!();

    /// Every source kind and output (charges and dipoles; potentials,
    /// gradients and Hessians), through the composed loop of
    /// [`lanes::RadialLaneKernel`](crate::lanes::RadialLaneKernel).
    fn supports(&self, _kind: SourceKind, _mode: EvalMode) -> bool {
        true
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

/// Accumulate the Laplace potential (and gradient) of `sources` with
/// `charges` at `targets` into `out`, using [`SimdLevel::active`].
///
/// This is what [`Laplace3d`]'s `evaluate` calls; see
/// [`laplace_p2p_with`] for the maths, layout and panics.
#[inline]
pub fn laplace_p2p<T: Real>(
    mode: EvalMode,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &mut [T],
) {
    laplace_p2p_with(SimdLevel::active(), mode, sources, charges, targets, out);
}

/// Accumulate the Laplace potential (and gradient) using a given
/// instruction-set `level` (lowered to the best one the CPU supports, so any
/// value is safe).
///
/// For every target `y_j`,
///
/// ```text
/// phi(y_j)    += sum_i q_i / (4 pi |y_j - x_i|)
/// grad phi_j  += sum_i -q_i (y_j - x_i) / (4 pi |y_j - x_i|^3)
/// ```
///
/// skipping coincident pairs (`|y_j - x_i| == 0`). Points are interleaved
/// `[x0, y0, z0, x1, ...]`; `out` holds `mode.values_per_target()` values per
/// target (`[phi, gx, gy, gz]` for gradients, then the six Hessian entries
/// for [`EvalMode::PotentialGradientHessian`], which runs the composed loop
/// of [`lanes::RadialLaneKernel`]) and is **added to**.
///
/// # Method and accuracy
/// Targets are processed in register blocks of 8 (`f64`) / 16 (`f32`) lanes
/// with AVX-512, 4 / 8 with AVX2, two blocks at a time; each source is
/// broadcast to all lanes. `1/r` comes from
/// * AVX-512: the `vrsqrt14` estimate `y` (relative error `< 2^-14`) refined
///   with the series `y (1 - e)^(-1/2) = y (1 + e/2 + 3e^2/8 + 5e^3/16 + ..)`,
///   `e = 1 - r^2 y^2`, to `e^3` for `f64` (truncation `< 4.4 * 2^-56`) and
///   to `e` for `f32` (`< 1.5 * 2^-28`): below half an ulp;
/// * AVX2: exact `sqrt` and division for `f64`; `vrsqrtps` refined to `e^2`
///   for `f32` (truncation `~1.3e-10`);
/// * [`SimdLevel::Scalar`]: exact `sqrt` and division, portable code.
///
/// Every level agrees with the scalar reference to a few ulps per
/// interaction (tested: `<= 6 eps` per pair, and `(n_sources + 8) eps`
/// relative to `sum |q K|` per target).
///
/// # Coincident pairs
/// Pairs with `r^2` below the smallest normal number of `T` (`r == 0`, or
/// `r < ~1.1e-19` in `f32`, `~1.5e-154` in `f64`) contribute exactly zero in
/// every path (masked, never NaN or Inf).
///
/// # Panics
/// When a coordinate slice's length is not a multiple of 3, or `charges` /
/// `out` do not match the number of sources / targets.
///
/// ```
/// use ferrofmm_kernels::{laplace_p2p_with, EvalMode, SimdLevel};
/// let sources = [0.0f64, 0.0, 0.0];
/// let charges = [1.0f64];
/// let targets = [2.0f64, 0.0, 0.0, 0.0, 0.0, 0.0]; // the second coincides
/// let mut out = [0.0f64; 8];
/// laplace_p2p_with(SimdLevel::Scalar, EvalMode::PotentialGradient, &sources, &charges, &targets, &mut out);
/// let k = 1.0 / (4.0 * std::f64::consts::PI);
/// assert!((out[0] - k / 2.0).abs() < 1e-16);
/// assert!((out[1] + k / 4.0).abs() < 1e-16); // d/dx of 1/(4 pi x) at x = 2
/// assert_eq!(&out[4..], &[0.0; 4]);
/// ```
pub fn laplace_p2p_with<T: Real>(
    level: SimdLevel,
    mode: EvalMode,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &mut [T],
) {
    let kind = SourceKind::Charge;
    lanes::evaluate_sources_with(
        level, &Laplace3d, kind, mode, sources, charges, targets, out,
    );
}
