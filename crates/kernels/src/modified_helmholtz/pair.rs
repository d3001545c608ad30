//! The micro-kernels of [`ModifiedHelmholtz3d`] in the lane engine of
//! [`crate::lanes`]: charges ([`LaneKernel::pair`]) and the radial
//! derivatives behind dipoles and Hessians ([`RadialLaneKernel::radial`]),
//! with a polynomial `exp` on registers ([`exp_nonpositive`]). The maths is
//! in the [parent module](super).

use crate::ModifiedHelmholtz3d;
use crate::lanes::{self, LaneFloat, LaneKernel, RadialLaneKernel, Simd, exp_nonpositive};

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
