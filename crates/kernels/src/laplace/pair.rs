//! The micro-kernels of [`Laplace3d`](crate::Laplace3d) in the lane
//! engine of [`crate::lanes`]: charges ([`LaneKernel::pair`]) and the
//! radial derivatives behind dipoles and Hessians
//! ([`RadialLaneKernel::radial`]). The maths is in the
//! [parent module](super).

use crate::Laplace3d;
use crate::lanes::{self, LaneFloat, LaneKernel, RadialLaneKernel, Simd};

impl LaneKernel for Laplace3d {
    /// `qr = q / r` into the potential and, with gradients, `qr / r^2 (x - y)`
    /// (`q grad_y K` without `1/(4 pi)`, written without a negation so that
    /// it stays three fused multiply-adds); `1/r = 0` makes coincident lanes
    /// zero.
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
        let qr = s.mul(q, rinv);
        acc[0] = s.add(acc[0], qr);
        if GRAD {
            let qr3 = s.mul(qr, s.mul(rinv, rinv));
            lanes::add_radial_gradient(s, qr3, &d, acc);
        }
    }

    /// `1 / (4 pi)`.
    fn lane_scale(&self) -> f64 {
        crate::INV_4PI
    }
}

impl RadialLaneKernel for Laplace3d {
    /// `k = 1/r`: `f_0 = 1/r`, `f_1 = -1/r^3`, `f_2 = 3/r^5`,
    /// `f_3 = -15/r^7` (each `-(2m - 1)/r^2` times the one before);
    /// `1/r = 0` makes coincident lanes zero.
    #[inline(always)]
    fn radial<T: LaneFloat, S: Simd<T>, const M: usize>(&self, s: S, r2: S::V) -> [S::V; 4] {
        let rinv = s.rsqrt_or_zero(r2);
        let zero = s.splat(T::ZERO);
        let mut f = [rinv, zero, zero, zero];
        if M >= 1 {
            let rinv2 = s.mul(rinv, rinv);
            for m in 1..=M.min(3) {
                let c = s.splat(T::from_f64(-(2.0 * m as f64 - 1.0)));
                f[m] = s.mul(s.mul(c, f[m - 1]), rinv2);
            }
        }
        f
    }
}
