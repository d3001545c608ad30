//! Modified Helmholtz (Yukawa) P2P: the micro-kernel of
//! [`ModifiedHelmholtz3d`] in the vectorised loop of [`crate::lanes`], with
//! a polynomial `exp` on registers ([`crate::lanes::exp_nonpositive`]).

use crate::lanes::{self, LaneFloat, LaneKernel, RadialLaneKernel, Simd, exp_nonpositive};
use crate::{EvalMode, ModifiedHelmholtz3d, Real, SimdLevel};

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
/// `r`), `1/r` comes from [`Simd::rsqrt_or_zero`], and `exp` from a
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
    let kernel = ModifiedHelmholtz3d { k };
    lanes::evaluate_sources_with(
        level,
        &kernel,
        crate::SourceKind::Charge,
        mode,
        sources,
        charges,
        targets,
        out,
    );
}

impl LaneKernel for ModifiedHelmholtz3d {
    /// `qer = q exp(-k r) / r` into the potential and, with gradients,
    /// `qer (1 + k r) / r^2 (x - y)` (that is `q grad_y K` without
    /// `1/(4 pi)`); `1/r = 0` makes coincident lanes zero.
    #[inline(always)]
    fn pair<T: LaneFloat, S: Simd<T>, const GRAD: bool>(
        &self,
        s: S,
        d: [S::V; 3],
        r2: S::V,
        q: S::V,
        acc: &mut [S::V; 4],
    ) {
        let rinv = s.rsqrt_or_zero(r2);
        let kr = s.mul(s.splat(T::from_f64(self.k)), s.sqrt(r2));
        let e = exp_nonpositive(s, s.sub(s.splat(T::ZERO), kr));
        let qer = s.mul(s.mul(q, e), rinv);
        acc[0] = s.add(acc[0], qer);
        if GRAD {
            let c = s.mul(s.mul(qer, s.add(s.splat(T::ONE), kr)), s.mul(rinv, rinv));
            lanes::add_radial_gradient(s, c, &d, acc);
        }
    }

    /// `1 / (4 pi)`.
    fn lane_scale(&self) -> f64 {
        crate::INV_4PI
    }
}

impl RadialLaneKernel for ModifiedHelmholtz3d {
    /// `k(r) = e^{-kr} / r`, with `x = k r`:
    ///
    /// ```text
    /// f_0 =  e^{-x} / r
    /// f_1 = -e^{-x} (1 + x) / r^3
    /// f_2 =  e^{-x} (3 + 3x + x^2) / r^5
    /// f_3 = -e^{-x} (15 + 15x + 6x^2 + x^3) / r^7
    /// ```
    ///
    /// (`k = 0` gives Laplace's); `1/r = 0` makes coincident lanes zero.
    #[inline(always)]
    fn radial<T: LaneFloat, S: Simd<T>, const M: usize>(&self, s: S, r2: S::V) -> [S::V; 4] {
        let rinv = s.rsqrt_or_zero(r2);
        let x = s.mul(s.splat(T::from_f64(self.k)), s.sqrt(r2));
        let e = exp_nonpositive(s, s.sub(s.splat(T::ZERO), x));
        let er = s.mul(e, rinv);
        let zero = s.splat(T::ZERO);
        let mut f = [er, zero, zero, zero];
        // Polynomials in x, lowest degree first, and the sign of each f_m.
        const POLY: [[f64; 4]; 3] = [
            [1.0, 1.0, 0.0, 0.0],
            [3.0, 3.0, 1.0, 0.0],
            [15.0, 15.0, 6.0, 1.0],
        ];
        let rinv2 = s.mul(rinv, rinv);
        let mut scale = er;
        for m in 1..=M.min(3) {
            scale = s.mul(scale, rinv2);
            let c = &POLY[m - 1];
            let mut p = s.splat(T::from_f64(c[m]));
            for j in (0..m).rev() {
                p = s.mul_add(p, x, s.splat(T::from_f64(c[j])));
            }
            let sign = if m % 2 == 1 { -1.0 } else { 1.0 };
            f[m] = s.mul(s.mul(s.splat(T::from_f64(sign)), p), scale);
        }
        f
    }
}
