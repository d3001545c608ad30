//! The modified Helmholtz (Yukawa, screened Coulomb) kernel
//! `K(x, y) = exp(-k |x - y|) / (4 pi |x - y|)`: its maths and [`Kernel`]
//! impl (here) and its micro-kernels in the lane engine of [`crate::lanes`]
//! (`pair.rs`).
//!
//! # Maths
//! With `d = x - y` (source minus target), `r = |d|` and `x = k r`,
//!
//! ```text
//! K        = e^{-x} / (4 pi r)
//! grad_y K = e^{-x} (1 + x) d / (4 pi r^3)
//! ```
//!
//! and the radial derivatives of `k(r) = e^{-kr} / r` behind dipoles and
//! Hessians ([`lanes::RadialLaneKernel`]), `f_{m+1} = (1/r) d f_m / dr`:
//!
//! ```text
//! f_0 =  e^{-x} / r
//! f_1 = -e^{-x} (1 + x) / r^3
//! f_2 =  e^{-x} (3 + 3x + x^2) / r^5
//! f_3 = -e^{-x} (15 + 15x + 6x^2 + x^3) / r^7
//! ```
//!
//! (`k = 0` gives Laplace's). On registers `r` is the correctly rounded
//! `sqrt(r^2)`, `1/r` comes from [`lanes::Simd::rsqrt_or_zero`] (zero for
//! coincident points) and `e^{-x}` from [`lanes::exp_nonpositive`].

mod pair;

use crate::lanes;
use crate::{EvalMode, INV_4PI, Kernel, KernelError, Real, SimdLevel, SourceKind};

/// The 3D modified Helmholtz Green's function
/// `K(x, y) = exp(-k r) / (4 pi r)`, `r = |x - y|`, the solution of
/// `(-Delta + k^2) u = delta`.
///
/// * not scale invariant for `k > 0` ([`Kernel::homogeneity`] is `None`), so
///   the FMM builds its operators per tree level; with `k = 0` it is the
///   Laplace kernel and reports degree `-1`;
/// * gradient with respect to the target, `d = y - x`:
///   `grad_y K = -exp(-k r) (1 + k r) d / (4 pi r^3)`.
///
/// [`Kernel::evaluate`] and [`Kernel::evaluate_sources`] run the lane engine
/// with a polynomial `exp`, vectorised for the detected instruction set
/// (see the module docs, `modified_helmholtz/mod.rs`).
///
/// ```
/// use ferrofmm_kernels::{EvalMode, Kernel, ModifiedHelmholtz3d};
/// let yukawa = ModifiedHelmholtz3d::new(2.0).unwrap();
/// let mut phi = [0.0f64];
/// yukawa.evaluate(EvalMode::Potential, &[0.0, 0.0, 0.0], &[1.0], &[0.5, 0.0, 0.0], &mut phi);
/// let expected = (-1.0f64).exp() / (4.0 * std::f64::consts::PI * 0.5);
/// assert!((phi[0] - expected).abs() < 1e-15);
/// assert!(ModifiedHelmholtz3d::new(-1.0).is_err());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModifiedHelmholtz3d {
    /// The screening wavenumber `k >= 0` (inverse length).
    pub k: f64,
}

impl ModifiedHelmholtz3d {
    /// The kernel with wavenumber `k`.
    ///
    /// # Errors
    /// [`KernelError::InvalidParameter`] when `k` is negative, NaN or
    /// infinite.
    pub fn new(k: f64) -> Result<Self, KernelError> {
        crate::error::check_wavenumber(k).map(|k| ModifiedHelmholtz3d { k })
    }
}

impl Kernel for ModifiedHelmholtz3d {
    /// `"modified_helmholtz3d"`.
    fn name(&self) -> String {
        "modified_helmholtz3d".to_string()
    }

    /// `vec![k]`.
    fn parameters(&self) -> Vec<f64> {
        vec![self.k]
    }

    /// `None` for `k > 0`; `Some(-1.0)` for `k = 0` (Laplace).
    fn homogeneity(&self) -> Option<f64> {
        if self.k == 0.0 { Some(-1.0) } else { None }
    }

    /// `exp(-k r) / (4 pi r)`.
    #[inline]
    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        T::from_f64(INV_4PI) * (-(T::from_f64(self.k) * r)).exp() / r
    }

    /// `-exp(-k r) (1 + k r) d / (4 pi r^3)`.
    #[inline]
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let kr = T::from_f64(self.k) * r;
        let rinv = T::ONE / r;
        let s = -(T::from_f64(INV_4PI) * (-kr).exp() * (T::ONE + kr) * rinv * rinv * rinv);
        [s * d[0], s * d[1], s * d[2]]
    }

    crate::lanes::kernel_entry_points!();

    /// Every source kind and output (charges and dipoles; potentials,
    /// gradients and Hessians), through the composed loop of
    /// [`lanes::RadialLaneKernel`](crate::lanes::RadialLaneKernel).
    fn supports(&self, _kind: SourceKind, _mode: EvalMode) -> bool {
        true
    }
}

/// Accumulate the modified Helmholtz potential (and gradient) with
/// wavenumber `k >= 0` using instruction-set `level` (clamped to what the CPU
/// supports):
///
/// ```text
/// phi(y_j)   += sum_i q_i exp(-k r_ij) / (4 pi r_ij)
/// grad phi_j += sum_i -q_i exp(-k r_ij) (1 + k r_ij) (y_j - x_i) / (4 pi r_ij^3)
/// ```
///
/// Layout, accumulation and the coincidence rule (`r^2` below the smallest
/// normal number contributes exactly zero) are those of
/// [`laplace_p2p_with`](crate::laplace_p2p_with). `r` is the correctly
/// rounded `sqrt(r^2)` (the error of `exp(-k r)` is `k r` times that of
/// `r`), `1/r` comes from [`lanes::Simd::rsqrt_or_zero`], and `exp` from a
/// polynomial accurate to a few ulps, which returns 0 once `exp(-k r)`
/// drops below the smallest normal number. This is what
/// [`ModifiedHelmholtz3d`]'s `evaluate` calls at [`SimdLevel::active`].
///
/// # Panics
/// When lengths are inconsistent, or `k` is negative or not finite.
///
/// ```
/// use ferrofmm_kernels::{modified_helmholtz_p2p_with, EvalMode, SimdLevel};
/// let mut phi = [0.0f64];
/// modified_helmholtz_p2p_with(SimdLevel::detected(), 2.0, EvalMode::Potential,
///     &[0.0, 0.0, 0.0], &[1.0], &[0.5, 0.0, 0.0], &mut phi);
/// let expected = (-1.0f64).exp() / (4.0 * std::f64::consts::PI * 0.5);
/// assert!((phi[0] - expected).abs() < 1e-15);
/// ```
pub fn modified_helmholtz_p2p_with<T: Real>(
    level: SimdLevel,
    k: f64,
    mode: EvalMode,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &mut [T],
) {
    assert!(
        k.is_finite() && k >= 0.0,
        "modified_helmholtz_p2p: k = {k} must be finite and >= 0"
    );
    let (kernel, kind) = (ModifiedHelmholtz3d { k }, SourceKind::Charge);
    lanes::evaluate_sources_with(level, &kernel, kind, mode, sources, charges, targets, out);
}
