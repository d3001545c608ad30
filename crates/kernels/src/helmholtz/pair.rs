//! The micro-kernel of the complex Helmholtz kernel ([`Helmholtz3d`]) in
//! the lane engine of [`crate::lanes`], with `sin` and `cos` on registers.
//!
//! # Per pair
//! The engine hands `d = x - y` (source minus target), so with `r = |d|`,
//! `f0 = e^{ikr} / (4 pi r)` and `g1 = -f1 = f0 (1 - ikr) / r^2`,
//! `f2 = f0 (3 - 3ikr - k^2 r^2) / r^4` (see [`Helmholtz3d`]'s module, whose
//! `d` is `y - x`):
//!
//! ```text
//! u      += q f0 - g1 (n . d)
//! grad u += (q g1 - f2 (n . d)) d + g1 n
//! ```
//!
//! in complex arithmetic on `(re, im)` registers. Coincident pairs get
//! `1/r = 0` from [`Simd::rsqrt_or_zero`], which zeroes `f0`, `g1`, `f2`.
//!
//! # `sin` and `cos` of `x = kr >= 0`
//! `n = round(x / 2 pi)` (the round-to-integer step of adding and
//! subtracting `1.5 2^(p-1)`), `y = x - 2 pi n` in `[-pi, pi]` with `2 pi`
//! split in three parts (Cody-Waite; the first with 24 significant bits, so
//! that its product with `n` is exact without FMA), `h = y / 2` in `[-pi/2, pi/2]`, Taylor
//! polynomials `sin h = h sum_{j<10} (-h^2)^j / (2j+1)!` and `cos h =
//! sum_{j<11} (-h^2)^j / (2j)!` (truncation below `3e-16` on that
//! interval), then `sin y = 2 sin h cos h` and `cos y = 1 - 2 sin^2 h`:
//! absolute errors of a few `1e-16` for `kr` up to the FMM's low-frequency
//! limit (tests compare with `f64::sin_cos`).
//!
//! [`Helmholtz3d`]: crate::Helmholtz3d

use crate::lanes::{LaneFloat, LaneSources, PairKernel, Simd, run};
use crate::{EvalMode, Helmholtz3d, INV_4PI, Real, SimdLevel, SourceKind};

/// Taylor coefficients of `sin(h) / h` in `h^2`, highest degree first.
const SIN_TAYLOR: [f64; 10] = [
    -1.0 / 121_645_100_408_832_000.0,
    1.0 / 355_687_428_096_000.0,
    -1.0 / 1_307_674_368_000.0,
    1.0 / 6_227_020_800.0,
    -1.0 / 39_916_800.0,
    1.0 / 362_880.0,
    -1.0 / 5_040.0,
    1.0 / 120.0,
    -1.0 / 6.0,
    1.0,
];

/// Taylor coefficients of `cos(h)` in `h^2`, highest degree first.
const COS_TAYLOR: [f64; 11] = [
    1.0 / 2_432_902_008_176_640_000.0,
    -1.0 / 6_402_373_705_728_000.0,
    1.0 / 20_922_789_888_000.0,
    -1.0 / 87_178_291_200.0,
    1.0 / 479_001_600.0,
    -1.0 / 3_628_800.0,
    1.0 / 40_320.0,
    -1.0 / 720.0,
    1.0 / 24.0,
    -1.0 / 2.0,
    1.0,
];

/// `2 pi - fl64(2 pi)`.
const TWO_PI_F64_LO: f64 = 2.449_293_598_294_706_4e-16;

impl LaneSources for Helmholtz3d {
    /// `NQ = 2, 6, 8` (complex charge, dipole, both) and `W = 2, 8`
    /// (complex potential, with the gradient).
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
        use SourceKind::{Charge, ChargeDipole, Dipole};
        let (s, q, t, o) = (sources, densities, targets, out);
        match (kind, mode.has_gradient()) {
            (Charge, false) => run::<_, _, 2, 2>(level, self, s, q, t, o),
            (Charge, true) => run::<_, _, 2, 8>(level, self, s, q, t, o),
            (Dipole, false) => run::<_, _, 6, 2>(level, self, s, q, t, o),
            (Dipole, true) => run::<_, _, 6, 8>(level, self, s, q, t, o),
            (ChargeDipole, false) => run::<_, _, 8, 2>(level, self, s, q, t, o),
            (ChargeDipole, true) => run::<_, _, 8, 8>(level, self, s, q, t, o),
        }
    }
}

/// The registers every pair uses, splatted once per call
/// ([`PairKernel::Regs`] of [`Helmholtz3d`]).
pub struct Consts<V> {
    k: V,
    scale: V,
    one: V,
    two: V,
    three: V,
    half: V,
    inv_two_pi: V,
    magic: V,
    neg_two_pi: [V; 3],
    sin: [V; 10],
    cos: [V; 11],
}

impl<V: Copy> Consts<V> {
    #[inline(always)]
    fn new<T: LaneFloat, S: Simd<T, V = V>>(s: S, k: f64) -> Self {
        // 2 pi = hi + mid + lo: `hi` has 24 significant bits, so `n hi` is
        // exact for the `n` met here even without FMA (the portable
        // backend), `mid` is the rest of the f64 value, `lo` what rounding
        // 2 pi to f64 left out.
        let tau = std::f64::consts::TAU;
        let hi = f64::from(tau as f32);
        let mid = tau - hi;
        let mid_t = T::from_f64(mid);
        let lo = (mid - mid_t.to_f64()) + TWO_PI_F64_LO;
        Consts {
            k: s.splat(T::from_f64(k)),
            scale: s.splat(T::from_f64(INV_4PI)),
            one: s.splat(T::ONE),
            two: s.splat(T::from_f64(2.0)),
            three: s.splat(T::from_f64(3.0)),
            half: s.splat(T::from_f64(0.5)),
            inv_two_pi: s.splat(T::from_f64(1.0 / tau)),
            magic: s.splat(T::EXP_MAGIC),
            neg_two_pi: [
                s.splat(T::from_f64(-hi)),
                s.splat(-mid_t),
                s.splat(T::from_f64(-lo)),
            ],
            sin: SIN_TAYLOR.map(|c| s.splat(T::from_f64(c))),
            cos: COS_TAYLOR.map(|c| s.splat(T::from_f64(c))),
        }
    }
}

/// `(sin x, cos x)` for `0 <= x` well below `2^(p-2) 2 pi` (module docs).
#[inline(always)]
fn sin_cos<T: LaneFloat, S: Simd<T>>(s: S, c: &Consts<S::V>, x: S::V) -> (S::V, S::V) {
    let n = s.sub(s.mul_add(x, c.inv_two_pi, c.magic), c.magic);
    let mut y = x;
    for &part in &c.neg_two_pi {
        y = s.mul_add(n, part, y);
    }
    let h = s.mul(y, c.half);
    let h2 = s.mul(h, h);
    let mut ps = c.sin[0];
    for &a in &c.sin[1..] {
        ps = s.mul_add(ps, h2, a);
    }
    let sh = s.mul(ps, h);
    let mut ch = c.cos[0];
    for &a in &c.cos[1..] {
        ch = s.mul_add(ch, h2, a);
    }
    let sin = s.mul(s.mul(c.two, sh), ch);
    let cos = s.sub(c.one, s.mul(s.mul(c.two, sh), sh));
    (sin, cos)
}

/// Complex product `(a + ib)(c + id)` on registers.
#[inline(always)]
fn cmul<T: LaneFloat, S: Simd<T>>(s: S, a: S::V, b: S::V, c: S::V, d: S::V) -> (S::V, S::V) {
    (
        s.sub(s.mul(a, c), s.mul(b, d)),
        s.mul_add(a, d, s.mul(b, c)),
    )
}

impl PairKernel for Helmholtz3d {
    type Regs<T: LaneFloat, S: Simd<T>> = Consts<S::V>;

    #[inline(always)]
    fn regs<T: LaneFloat, S: Simd<T>>(&self, s: S) -> Consts<S::V> {
        Consts::new(s, self.k)
    }

    /// The formulas of the module docs (`helmholtz/pair.rs`): charges unless `NQ = 6`,
    /// dipoles when `NQ >= 6`, gradients when `W = 8`.
    #[inline(always)]
    fn pair<T: LaneFloat, S: Simd<T>, const NQ: usize, const W: usize>(
        &self,
        s: S,
        k: &Consts<S::V>,
        d: &[S::V; 3],
        r2: S::V,
        q: &[S::V; NQ],
        acc: &mut [S::V; W],
    ) {
        let (has_q, has_n, grad) = (NQ != 6, NQ >= 6, W == 8);
        let zero = s.splat(T::ZERO);
        let rinv = s.rsqrt_or_zero(r2);
        let kr = s.mul(k.k, s.mul(r2, rinv));
        let (sn, cs) = sin_cos(s, k, kr);
        let a = s.mul(k.scale, rinv);
        let (gr, gi) = (s.mul(cs, a), s.mul(sn, a));
        let rinv2 = s.mul(rinv, rinv);
        // g1 = f0 (1 - i kr) / r^2
        let (g1r, g1i) = if grad || has_n {
            let (a, b) = (s.mul_add(gi, kr, gr), s.sub(gi, s.mul(gr, kr)));
            (s.mul(a, rinv2), s.mul(b, rinv2))
        } else {
            (zero, zero)
        };
        let (mut pr, mut pi) = (zero, zero);
        let (mut cr, mut ci) = (zero, zero);
        if has_q {
            (pr, pi) = cmul(s, gr, gi, q[0], q[1]);
            if grad {
                (cr, ci) = cmul(s, g1r, g1i, q[0], q[1]);
            }
        }
        let n = &q[NQ - 6.min(NQ)..];
        if has_n {
            let ndr = s.mul_add(n[4], d[2], s.mul_add(n[2], d[1], s.mul(n[0], d[0])));
            let ndi = s.mul_add(n[5], d[2], s.mul_add(n[3], d[1], s.mul(n[1], d[0])));
            let (a, b) = cmul(s, g1r, g1i, ndr, ndi);
            pr = s.sub(pr, a);
            pi = s.sub(pi, b);
            if grad {
                // f2 = f0 ((3 - k^2 r^2) - 3i kr) / r^4
                let re = s.sub(k.three, s.mul(kr, kr));
                let im = s.sub(zero, s.mul(k.three, kr));
                let (a, b) = cmul(s, gr, gi, re, im);
                let rinv4 = s.mul(rinv2, rinv2);
                let (f2r, f2i) = (s.mul(a, rinv4), s.mul(b, rinv4));
                let (a, b) = cmul(s, f2r, f2i, ndr, ndi);
                cr = s.sub(cr, a);
                ci = s.sub(ci, b);
            }
        }
        acc[0] = s.add(acc[0], pr);
        acc[1] = s.add(acc[1], pi);
        if grad {
            for m in 0..3 {
                let mut gre = s.mul_add(cr, d[m], acc[2 + 2 * m]);
                let mut gim = s.mul_add(ci, d[m], acc[3 + 2 * m]);
                if has_n {
                    let (a, b) = cmul(s, g1r, g1i, n[2 * m], n[2 * m + 1]);
                    gre = s.add(gre, a);
                    gim = s.add(gim, b);
                }
                acc[2 + 2 * m] = gre;
                acc[3 + 2 * m] = gim;
            }
        }
    }

    /// One register per target block with SIMD registers (the micro-kernel
    /// is long)...
    const TWO_REGISTERS_UP_TO: usize = 0;
    /// ... and 16 lanes with portable ones.
    const PORTABLE_LANES: usize = 16;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lanes::{SimdTask, run_task};

    /// The register `sin` and `cos` against `f64::sin_cos` over the range
    /// the FMM uses (`kr` up to 100), at every level the CPU has.
    #[test]
    fn register_sin_cos_matches_the_library() {
        struct Probe<'a>(&'a [f64], &'a mut [f64], &'a mut [f64]);
        impl SimdTask<f64> for Probe<'_> {
            type Output = ();
            fn run<S: Simd<f64>>(self, s: S) {
                let c = Consts::new(s, 1.0);
                let l = S::LANES;
                for ((x, sn), cs) in self
                    .0
                    .chunks_exact(l)
                    .zip(self.1.chunks_exact_mut(l))
                    .zip(self.2.chunks_exact_mut(l))
                {
                    let (a, b) = sin_cos(s, &c, s.load(x));
                    s.store(a, sn);
                    s.store(b, cs);
                }
            }
        }
        let x: Vec<f64> = (0..16_000)
            .map(|i| i as f64 * 0.00625 + 1e-3 * (i % 7) as f64)
            .collect();
        for level in [SimdLevel::Scalar, SimdLevel::Avx2, SimdLevel::Avx512] {
            let mut sn = vec![0.0; x.len()];
            let mut cs = vec![0.0; x.len()];
            run_task(level, Probe(&x, &mut sn, &mut cs));
            for (i, &v) in x.iter().enumerate() {
                let (a, b) = v.sin_cos();
                assert!(
                    (sn[i] - a).abs() < 2e-15,
                    "{level:?} sin({v}): {} vs {a}",
                    sn[i]
                );
                assert!(
                    (cs[i] - b).abs() < 2e-15,
                    "{level:?} cos({v}): {} vs {b}",
                    cs[i]
                );
            }
        }
    }
}
