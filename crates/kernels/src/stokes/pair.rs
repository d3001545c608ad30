//! The micro-kernel of the Stokeslet ([`Stokes3d`]) in the lane engine of
//! [`crate::lanes`].
//!
//! The engine hands `d = x - y` (source minus target), the opposite of
//! [`Stokes3d`]'s module. Per pair, with `1/r` from
//! [`Simd::rsqrt_or_zero`] (zero for coincident points, which zeroes the
//! pair), `s = 1 / (8 pi mu r)` and `t = (d . f) / r^2`, the velocity is
//! even in `d` and its gradient odd:
//!
//! ```text
//! u_a     += s (f_a + d_a t)
//! d_c u_a += s / r^2 (f_a d_c - d_a f_c + 3 d_a d_c t - delta_ac (d . f))
//! ```

use crate::lanes::{LaneFloat, LaneSources, PairKernel, Simd, run};
use crate::{EvalMode, Real, SimdLevel, SourceKind, Stokes3d};

impl LaneSources for Stokes3d {
    /// Point forces (`NQ = 3`), velocities (`W = 3`) or velocities and
    /// their gradients (`W = 12`).
    fn run_sources<T: Real>(
        &self,
        level: SimdLevel,
        _kind: SourceKind,
        mode: EvalMode,
        sources: &[T],
        forces: &[T],
        targets: &[T],
        out: &mut [T],
    ) {
        let (s, f, t, o) = (sources, forces, targets, out);
        if mode.has_gradient() {
            run::<_, _, 3, 12>(level, self, s, f, t, o);
        } else {
            run::<_, _, 3, 3>(level, self, s, f, t, o);
        }
    }
}

impl PairKernel for Stokes3d {
    /// `[1 / (8 pi mu), 3]`.
    type Regs<T: LaneFloat, S: Simd<T>> = [S::V; 2];

    #[inline(always)]
    fn regs<T: LaneFloat, S: Simd<T>>(&self, s: S) -> [S::V; 2] {
        [
            s.splat(T::from_f64(self.scale())),
            s.splat(T::from_f64(3.0)),
        ]
    }

    /// The formulas of the module docs (`stokes/pair.rs`); gradients when `W = 12`,
    /// `d_k u_a` stored at `3 + 3 k + a`.
    #[inline(always)]
    fn pair<T: LaneFloat, S: Simd<T>, const NQ: usize, const W: usize>(
        &self,
        s: S,
        &[scale, three]: &[S::V; 2],
        d: &[S::V; 3],
        r2: S::V,
        f: &[S::V; NQ],
        acc: &mut [S::V; W],
    ) {
        let rinv = s.rsqrt_or_zero(r2);
        let rinv2 = s.mul(rinv, rinv);
        let df = s.mul_add(d[2], f[2], s.mul_add(d[1], f[1], s.mul(d[0], f[0])));
        let sc = s.mul(scale, rinv);
        let t = s.mul(df, rinv2);
        for a in 0..3 {
            acc[a] = s.mul_add(sc, s.mul_add(d[a], t, f[a]), acc[a]);
        }
        if W == 12 {
            let s3 = s.mul(sc, rinv2);
            let t3 = s.mul(three, t);
            for k in 0..3 {
                let dk3 = s.mul(d[k], t3);
                for a in 0..3 {
                    let mut v = s.mul(f[a], d[k]);
                    v = s.sub(v, s.mul(d[a], s.sub(f[k], dk3)));
                    if a == k {
                        v = s.sub(v, df);
                    }
                    acc[3 + 3 * k + a] = s.mul_add(s3, v, acc[3 + 3 * k + a]);
                }
            }
        }
    }

    /// One register per target block with SIMD registers...
    const TWO_REGISTERS_UP_TO: usize = 0;
    /// ... and 16 lanes with portable ones.
    const PORTABLE_LANES: usize = 16;
}
