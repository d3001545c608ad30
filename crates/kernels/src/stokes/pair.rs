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
//!
//! A force dipole `D` (`D_kc`: direction `k`, force component `c`; see
//! [`Stokes3d`]'s module docs) adds, with `De = D d`, `D^T d`, `tr = tr D`,
//! `Q = d . D d`, `g = (D + D^T) d` and `s3 = s / r^2`:
//!
//! ```text
//! u_a     += s3 (De_a - (D^T d)_a + d_a (tr - 3 Q / r^2))
//! d_m u_a += s3 (D_ma - D_am + 3 / r^2 (d_a (g_m + d_m (tr - 5 Q / r^2)) - ((D^T - D) d)_a d_m)
//!                + delta_am (3 Q / r^2 - tr))
//! ```
//!
//! (the module's formulas with `d -> -d`: the velocity is odd, its gradient
//! even).

use crate::lanes::{LaneFloat, LaneSources, PairKernel, Simd, run};
use crate::{EvalMode, Real, SimdLevel, SourceKind, Stokes3d};

impl LaneSources for Stokes3d {
    /// Point forces (`NQ = 3`), force dipoles (`NQ = 9`) or both
    /// (`NQ = 12`); velocities (`W = 3`) or velocities and their gradients
    /// (`W = 12`).
    fn run_sources<T: Real>(
        &self,
        level: SimdLevel,
        kind: SourceKind,
        mode: EvalMode,
        sources: &[T],
        densities: &[T],
        targets: &[T],
        out: &mut [T],
    ) {
        let (s, f, t, o) = (sources, densities, targets, out);
        match (kind, mode.has_gradient()) {
            (SourceKind::Charge, true) => run::<_, _, 3, 12>(level, self, s, f, t, o),
            (SourceKind::Charge, false) => run::<_, _, 3, 3>(level, self, s, f, t, o),
            (SourceKind::Dipole, true) => run::<_, _, 9, 12>(level, self, s, f, t, o),
            (SourceKind::Dipole, false) => run::<_, _, 9, 3>(level, self, s, f, t, o),
            (SourceKind::ChargeDipole, true) => run::<_, _, 12, 12>(level, self, s, f, t, o),
            (SourceKind::ChargeDipole, false) => run::<_, _, 12, 3>(level, self, s, f, t, o),
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

    /// The formulas of the module docs (`stokes/pair.rs`): forces in the
    /// first three densities unless `NQ = 9`, a force dipole in the last
    /// nine when `NQ >= 9`; gradients when `W = 12`, `d_k u_a` stored at
    /// `3 + 3 k + a`.
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
        let sc = s.mul(scale, rinv);
        if NQ != 9 {
            let df = s.mul_add(d[2], f[2], s.mul_add(d[1], f[1], s.mul(d[0], f[0])));
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
        if NQ >= 9 {
            force_dipole::<T, S, NQ, W>(s, three, d, rinv2, s.mul(sc, rinv2), f, acc);
        }
    }

    /// One register per target block with SIMD registers...
    const TWO_REGISTERS_UP_TO: usize = 0;
    /// ... and 16 lanes with portable ones.
    const PORTABLE_LANES: usize = 16;
}

/// The force dipole `D_kc = f[NQ - 9 + 3 k + c]` of one pair (module docs),
/// `s3 = 1 / (8 pi mu r^3)` (zero for coincident points).
#[inline(always)]
fn force_dipole<T: LaneFloat, S: Simd<T>, const NQ: usize, const W: usize>(
    s: S,
    three: S::V,
    d: &[S::V; 3],
    rinv2: S::V,
    s3: S::V,
    f: &[S::V; NQ],
    acc: &mut [S::V; W],
) {
    let o = NQ - 9;
    let dm = |k: usize, c: usize| f[o + 3 * k + c];
    let dot = |a: [S::V; 3]| s.mul_add(a[2], d[2], s.mul_add(a[1], d[1], s.mul(a[0], d[0])));
    // (D d)_k and (D^T d)_c.
    let de: [S::V; 3] = std::array::from_fn(|k| dot([dm(k, 0), dm(k, 1), dm(k, 2)]));
    let dte: [S::V; 3] = std::array::from_fn(|c| dot([dm(0, c), dm(1, c), dm(2, c)]));
    let tr = s.add(s.add(dm(0, 0), dm(1, 1)), dm(2, 2));
    let q = dot(de);
    let t3 = s.mul(three, rinv2);
    let tq = s.mul(t3, q);
    let radial = s.sub(tr, tq);
    for a in 0..3 {
        let v = s.mul_add(d[a], radial, s.sub(de[a], dte[a]));
        acc[a] = s.mul_add(s3, v, acc[a]);
    }
    if W == 12 {
        // tr - 5 Q / r^2 and 3 Q / r^2 - tr.
        let five_q = s.mul(s.splat(T::from_f64(5.0 / 3.0)), tq);
        let along = s.sub(tr, five_q);
        let diag = s.sub(tq, tr);
        for m in 0..3 {
            let gm = s.add(de[m], dte[m]);
            let gm_along = s.mul_add(d[m], along, gm);
            for a in 0..3 {
                // (D^T - D) d at a, times d_m.
                let ae = s.sub(dte[a], de[a]);
                let inner = s.sub(s.mul(d[a], gm_along), s.mul(ae, d[m]));
                let mut v = s.mul_add(t3, inner, s.sub(dm(m, a), dm(a, m)));
                if a == m {
                    v = s.add(v, diag);
                }
                acc[3 + 3 * m + a] = s.mul_add(s3, v, acc[3 + 3 * m + a]);
            }
        }
    }
}
