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
//! in complex arithmetic on `(re, im)` registers. With Hessians (`W = 20`)
//! a separate micro-kernel (`hessian_pair`) uses the radial functions
//! `f0 .. f3` of [`Helmholtz3d`]'s module with this `d` (the convention of
//! [`crate::lanes::radial`]): `f1 = -g1`, `f3 = f0 ((-15 + 6 k^2 r^2) +
//! i (15 kr - k^3 r^3)) / r^6`, `p = n . d`, and
//!
//! ```text
//! u    += q f0 + f1 p
//! u_a  += -(q f1 + f2 p) d_a - f1 n_a
//! H_ab += (q f2 + f3 p) d_a d_b + (q f1 + f2 p) delta_ab + f2 (n_a d_b + n_b d_a)
//! ```
//!
//! Coincident pairs get `1/r = 0` from [`Simd::rsqrt_or_zero`], which
//! zeroes `f0 .. f3`.
//!
//! # Damped waves
//! A complex wavenumber `k = a + i b` (`b > 0`) runs the same micro-kernels
//! through [`Damped`], with `const DAMPED: bool` set: `f0` takes the factor
//! `e^{-br}` ([`exp_nonpositive`]) and the polynomials of the radial
//! functions take the complex `z = ikr = -br + i ar` (the module docs of
//! [`Helmholtz3d`]: `1 - z`, `z^2 - 3z + 3`, `z^3 - 6z^2 + 15z - 15`, by
//! Horner in complex arithmetic). With `DAMPED` unset the code is the
//! undamped one (`z = i ar`, whose real part is never formed), so a real
//! `k` pays nothing for the damped path.
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

use crate::lanes::{LaneFloat, LaneSources, PairKernel, Simd, exp_nonpositive, run};
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
    /// `NQ = 2, 6, 8` (complex charge, dipole, both) and `W = 2, 8, 20`
    /// (complex potential, with the gradient, with the gradient and the
    /// Hessian); a complex wavenumber through the damped micro-kernels (`Damped`).
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
        let data = (sources, densities, targets, out);
        if self.is_damped() {
            run_shape(&Damped(*self), level, kind, mode, data);
        } else {
            run_shape(self, level, kind, mode, data);
        }
    }
}

/// The lane engine for the shape of `(kind, mode)` with micro-kernel `p`.
fn run_shape<T: Real, P: PairKernel>(
    p: &P,
    level: SimdLevel,
    kind: SourceKind,
    mode: EvalMode,
    (s, q, t, o): (&[T], &[T], &[T], &mut [T]),
) {
    use EvalMode::{Potential as P, PotentialGradient as G, PotentialGradientHessian as H};
    use SourceKind::{Charge, ChargeDipole, Dipole};
    match (kind, mode) {
        (Charge, P) => run::<_, _, 2, 2>(level, p, s, q, t, o),
        (Charge, G) => run::<_, _, 2, 8>(level, p, s, q, t, o),
        (Charge, H) => run::<_, _, 2, 20>(level, p, s, q, t, o),
        (Dipole, P) => run::<_, _, 6, 2>(level, p, s, q, t, o),
        (Dipole, G) => run::<_, _, 6, 8>(level, p, s, q, t, o),
        (Dipole, H) => run::<_, _, 6, 20>(level, p, s, q, t, o),
        (ChargeDipole, P) => run::<_, _, 8, 2>(level, p, s, q, t, o),
        (ChargeDipole, G) => run::<_, _, 8, 8>(level, p, s, q, t, o),
        (ChargeDipole, H) => run::<_, _, 8, 20>(level, p, s, q, t, o),
    }
}

/// [`Helmholtz3d`] with a complex wavenumber: the micro-kernels with
/// `DAMPED` set (module docs).
struct Damped(Helmholtz3d);

/// The registers every pair uses, splatted once per call
/// ([`PairKernel::Regs`] of [`Helmholtz3d`]).
pub struct Consts<V> {
    k: V,
    /// `Im k` (read by the damped micro-kernels only).
    k_im: V,
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
    fn new<T: LaneFloat, S: Simd<T, V = V>>(s: S, k: f64, k_im: f64) -> Self {
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
            k_im: s.splat(T::from_f64(k_im)),
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
        Consts::new(s, self.k, 0.0)
    }

    /// The formulas of the module docs (`helmholtz/pair.rs`): charges unless `NQ = 6`,
    /// dipoles when `NQ >= 6`, gradients when `W = 8`, gradients and
    /// Hessians when `W = 20` (`hessian_pair`).
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
        pair::<T, S, NQ, W, false>(s, k, d, r2, q, acc);
    }

    /// One register per target block with SIMD registers (the micro-kernel
    /// is long)...
    const TWO_REGISTERS_UP_TO: usize = 0;
    /// ... and 16 lanes with portable ones.
    const PORTABLE_LANES: usize = 16;
}

impl PairKernel for Damped {
    type Regs<T: LaneFloat, S: Simd<T>> = Consts<S::V>;

    #[inline(always)]
    fn regs<T: LaneFloat, S: Simd<T>>(&self, s: S) -> Consts<S::V> {
        Consts::new(s, self.0.k, self.0.k_im)
    }

    /// [`Helmholtz3d`]'s micro-kernel with `DAMPED` set.
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
        pair::<T, S, NQ, W, true>(s, k, d, r2, q, acc);
    }

    const TWO_REGISTERS_UP_TO: usize = 0;
    const PORTABLE_LANES: usize = 16;
}

/// What every micro-kernel needs of one pair first ([`radial_f0`]).
struct RadialF0<V> {
    /// `Re f0`, `f0 = e^{ikr} / (4 pi r)`.
    re: V,
    /// `Im f0`.
    im: V,
    /// `1 / r` (0 for coincident points).
    rinv: V,
    /// `a r`, the imaginary part of `z = ikr`.
    kr: V,
    /// `1 - Re z = 1 + br` when damped, else 1.
    mz: V,
}

/// `f0 = e^{ikr} / (4 pi r)` as `(Re, Im)`, with `1/r`, `a r` (the
/// imaginary part of `z = ikr`) and, when `DAMPED`, `1 - Re z = 1 + br`
/// (else `1`).
#[inline(always)]
fn radial_f0<T: LaneFloat, S: Simd<T>, const DAMPED: bool>(
    s: S,
    k: &Consts<S::V>,
    r2: S::V,
) -> RadialF0<S::V> {
    let rinv = s.rsqrt_or_zero(r2);
    let r = s.mul(r2, rinv);
    let kr = s.mul(k.k, r);
    let (sn, cs) = sin_cos(s, k, kr);
    let mut a = s.mul(k.scale, rinv);
    let mut one_minus_zr = k.one;
    if DAMPED {
        let br = s.mul(k.k_im, r);
        a = s.mul(a, exp_nonpositive(s, s.sub(s.splat(T::ZERO), br)));
        one_minus_zr = s.add(k.one, br);
    }
    RadialF0 {
        re: s.mul(cs, a),
        im: s.mul(sn, a),
        rinv,
        kr,
        mz: one_minus_zr,
    }
}

/// `z^2 - 3z + 3` for `z = ikr` as `(Re, Im)`, from `kr` (`Im z`) and
/// `m = 1 - Re z`: `(3 - (kr)^2, -3 kr)` undamped.
#[inline(always)]
fn poly2<T: LaneFloat, S: Simd<T>, const DAMPED: bool>(
    s: S,
    k: &Consts<S::V>,
    kr: S::V,
    m: S::V,
) -> (S::V, S::V) {
    let zero = s.splat(T::ZERO);
    if DAMPED {
        // Re z = 1 - m; z^2 - 3z + 3 = (Re z (Re z - 3) + 3 - kr^2) + i kr (2 Re z - 3)
        let zr = s.sub(k.one, m);
        let re = s.sub(s.mul_add(zr, s.sub(zr, k.three), k.three), s.mul(kr, kr));
        let im = s.mul(kr, s.sub(s.add(zr, zr), k.three));
        (re, im)
    } else {
        (
            s.sub(k.three, s.mul(kr, kr)),
            s.sub(zero, s.mul(k.three, kr)),
        )
    }
}

/// The micro-kernel of [`Helmholtz3d`] (`DAMPED` unset) and of [`Damped`]
/// (set): charges unless `NQ = 6`, dipoles when `NQ >= 6`, gradients when
/// `W = 8`, gradients and Hessians when `W = 20` (`hessian_pair`).
#[inline(always)]
fn pair<T: LaneFloat, S: Simd<T>, const NQ: usize, const W: usize, const DAMPED: bool>(
    s: S,
    k: &Consts<S::V>,
    d: &[S::V; 3],
    r2: S::V,
    q: &[S::V; NQ],
    acc: &mut [S::V; W],
) {
    if W == 20 {
        hessian_pair::<T, S, NQ, W, DAMPED>(s, k, d, r2, q, acc);
        return;
    }
    let (has_q, has_n, grad) = (NQ != 6, NQ >= 6, W == 8);
    let zero = s.splat(T::ZERO);
    let RadialF0 {
        re: gr,
        im: gi,
        rinv,
        kr,
        mz,
    } = radial_f0::<T, S, DAMPED>(s, k, r2);
    let rinv2 = s.mul(rinv, rinv);
    // g1 = f0 (1 - z) / r^2, 1 - z = mz - i kr (mz = 1 undamped)
    let (g1r, g1i) = if grad || has_n {
        let (a, b) = if DAMPED {
            (
                s.mul_add(gi, kr, s.mul(gr, mz)),
                s.sub(s.mul(gi, mz), s.mul(gr, kr)),
            )
        } else {
            (s.mul_add(gi, kr, gr), s.sub(gi, s.mul(gr, kr)))
        };
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
            // f2 = f0 (z^2 - 3z + 3) / r^4
            let (re, im) = poly2::<T, S, DAMPED>(s, k, kr, mz);
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

/// One source's potential, gradient and Hessian (`W = 20`, complex pairs
/// in the order `u, u_x, u_y, u_z, H_xx, H_yy, H_zz, H_xy, H_xz, H_yz`) for
/// `NQ` densities: the complex radial functions `f_0 .. f_3` of the module
/// docs (`f_3` only with dipoles), then
///
/// ```text
/// A = q f2 + f3 p,   B = q f1 + f2 p,   m_a = f2 n_a,   p = n . d
/// u      += q f0 + f1 p
/// u_a    += -B d_a - f1 n_a
/// H_ab   += A d_a d_b + B delta_ab + m_a d_b + m_b d_a
/// ```
///
/// (the terms in `q` without dipoles, in `n` without charges).
#[inline(always)]
fn hessian_pair<T: LaneFloat, S: Simd<T>, const NQ: usize, const W: usize, const DAMPED: bool>(
    s: S,
    k: &Consts<S::V>,
    d: &[S::V; 3],
    r2: S::V,
    q: &[S::V; NQ],
    acc: &mut [S::V; W],
) {
    let (has_q, has_n) = (NQ != 6, NQ >= 6);
    let zero = s.splat(T::ZERO);
    // f0 = e^{ikr} / (4 pi r)
    let RadialF0 {
        re: f0r,
        im: f0i,
        rinv,
        kr,
        mz,
    } = radial_f0::<T, S, DAMPED>(s, k, r2);
    let rinv2 = s.mul(rinv, rinv);
    let kr2 = s.mul(kr, kr);
    // f1 = f0 (z - 1) / r^2, z - 1 = -mz + i kr (mz = 1 undamped)
    let (f1r, f1i) = {
        let (a, b) = if DAMPED {
            (
                s.mul_add(f0i, kr, s.mul(f0r, mz)),
                s.sub(s.mul(f0r, kr), s.mul(f0i, mz)),
            )
        } else {
            (s.mul_add(f0i, kr, f0r), s.sub(s.mul(f0r, kr), f0i))
        };
        (s.sub(zero, s.mul(a, rinv2)), s.mul(b, rinv2))
    };
    // f2 = f0 (z^2 - 3z + 3) / r^4
    let rinv4 = s.mul(rinv2, rinv2);
    let (f2r, f2i) = {
        let (re, im) = poly2::<T, S, DAMPED>(s, k, kr, mz);
        let (a, b) = cmul(s, f0r, f0i, re, im);
        (s.mul(a, rinv4), s.mul(b, rinv4))
    };
    let (mut ur, mut ui) = (zero, zero);
    let (mut ar, mut ai) = (zero, zero);
    let (mut br, mut bi) = (zero, zero);
    if has_q {
        (ur, ui) = cmul(s, f0r, f0i, q[0], q[1]);
        (ar, ai) = cmul(s, f2r, f2i, q[0], q[1]);
        (br, bi) = cmul(s, f1r, f1i, q[0], q[1]);
    }
    let n = &q[NQ - 6.min(NQ)..];
    // m_a = f2 n_a and f1 n_a (dipoles only).
    let mut m = [[zero; 2]; 3];
    let mut f1n = [[zero; 2]; 3];
    if has_n {
        let pr = s.mul_add(n[4], d[2], s.mul_add(n[2], d[1], s.mul(n[0], d[0])));
        let pi = s.mul_add(n[5], d[2], s.mul_add(n[3], d[1], s.mul(n[1], d[0])));
        // f3 = f0 (z^3 - 6z^2 + 15z - 15) / r^6: undamped
        // (-15 + 6 k^2 r^2) + i (15 kr - k^3 r^3)
        let fifteen = s.splat(T::from_f64(15.0));
        let six = s.splat(T::from_f64(6.0));
        let (f3r, f3i) = {
            let (re, im) = if DAMPED {
                // Horner in complex z: ((z - 6) z + 15) z - 15
                let zr = s.sub(k.one, mz);
                let (mut er, mut ei) = (s.sub(zr, six), kr);
                (er, ei) = cmul(s, er, ei, zr, kr);
                er = s.add(er, fifteen);
                (er, ei) = cmul(s, er, ei, zr, kr);
                (s.sub(er, fifteen), ei)
            } else {
                (
                    s.mul_add(six, kr2, s.sub(zero, fifteen)),
                    s.mul(kr, s.sub(fifteen, kr2)),
                )
            };
            let (a, b) = cmul(s, f0r, f0i, re, im);
            let rinv6 = s.mul(rinv4, rinv2);
            (s.mul(a, rinv6), s.mul(b, rinv6))
        };
        let (a, b) = cmul(s, f1r, f1i, pr, pi);
        ur = s.add(ur, a);
        ui = s.add(ui, b);
        let (a, b) = cmul(s, f3r, f3i, pr, pi);
        ar = s.add(ar, a);
        ai = s.add(ai, b);
        let (a, b) = cmul(s, f2r, f2i, pr, pi);
        br = s.add(br, a);
        bi = s.add(bi, b);
        for c in 0..3 {
            let (a, b) = cmul(s, f2r, f2i, n[2 * c], n[2 * c + 1]);
            m[c] = [a, b];
            let (a, b) = cmul(s, f1r, f1i, n[2 * c], n[2 * c + 1]);
            f1n[c] = [a, b];
        }
    }
    acc[0] = s.add(acc[0], ur);
    acc[1] = s.add(acc[1], ui);
    let b = [br, bi];
    let ad = [
        [s.mul(ar, d[0]), s.mul(ar, d[1]), s.mul(ar, d[2])],
        [s.mul(ai, d[0]), s.mul(ai, d[1]), s.mul(ai, d[2])],
    ];
    for c in 0..3 {
        for part in 0..2 {
            // -B d_c - f1 n_c
            let mut g = s.sub(acc[2 + 2 * c + part], s.mul(b[part], d[c]));
            if has_n {
                g = s.sub(g, f1n[c][part]);
            }
            acc[2 + 2 * c + part] = g;
            // H_cc = A d_c d_c + B + 2 m_c d_c
            let mut h = s.mul_add(ad[part][c], d[c], s.add(acc[8 + 2 * c + part], b[part]));
            if has_n {
                let md = s.mul(m[c][part], d[c]);
                h = s.add(h, s.add(md, md));
            }
            acc[8 + 2 * c + part] = h;
        }
    }
    for (slot, (i, j)) in [(14, (0, 1)), (16, (0, 2)), (18, (1, 2))] {
        for part in 0..2 {
            let mut h = s.mul_add(ad[part][i], d[j], acc[slot + part]);
            if has_n {
                h = s.mul_add(m[i][part], d[j], s.mul_add(m[j][part], d[i], h));
            }
            acc[slot + part] = h;
        }
    }
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
                let c = Consts::new(s, 1.0, 0.0);
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
