//! `e^x` for `x <= 0` on registers, for micro-kernels such as modified
//! Helmholtz's `exp(-k r)`.
//!
//! Method (Cody–Waite, as the scalar `fast_exp` of this crate): `x = n ln2
//! + f` with `n = round(x / ln2)` found by adding the "magic number"
//! `1.5 * 2^(p-1)` (the sum rounds to an integer kept in the low bits),
//! `ln2` split into a short high part and a low part so that
//! `f = x - n ln2` is nearly exact (`|f| <= ln2 / 2`); then `e^f` by its
//! Taylor polynomial (degree 13 in `f64`: truncation `< 4.3e-18`; degree 7
//! in `f32`: `< 5.3e-9`), evaluated as two Horner chains in `f^2` (odd and even part), and the factor `2^n` written into the exponent
//! bits ([`Simd::pow2_from_magic`]). Accurate to a few ulps.
//!
//! `x` is clamped to `[EXP_MIN_X, 0]` (`f64`: `-708`, `f32`: `-87`, where
//! the normal range ends); below it the result is exactly 0 instead of a
//! subnormal (absolute error below the smallest normal number).

use super::{LaneFloat, Simd};

impl LaneFloat for f64 {
    const EXP_MAGIC: f64 = 6_755_399_441_055_744.0; // 1.5 * 2^52
    // fdlibm's split of ln 2.
    const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
    const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
    const EXP_MIN_X: f64 = -708.0;
    const EXP_TAYLOR: &'static [f64] = &[
        1.0 / 6_227_020_800.0,
        1.0 / 479_001_600.0,
        1.0 / 39_916_800.0,
        1.0 / 3_628_800.0,
        1.0 / 362_880.0,
        1.0 / 40_320.0,
        1.0 / 5_040.0,
        1.0 / 720.0,
        1.0 / 120.0,
        1.0 / 24.0,
        1.0 / 6.0,
        0.5,
        1.0,
        1.0,
    ];
    const LOG2_E: f64 = std::f64::consts::LOG2_E;
}

impl LaneFloat for f32 {
    const EXP_MAGIC: f32 = 12_582_912.0; // 1.5 * 2^23
    const LN2_HI: f32 = 0.693_359_4;
    const LN2_LO: f32 = -2.121_944_4e-4;
    const EXP_MIN_X: f32 = -87.0;
    const EXP_TAYLOR: &'static [f32] = &[
        1.0 / 5_040.0,
        1.0 / 720.0,
        1.0 / 120.0,
        1.0 / 24.0,
        1.0 / 6.0,
        0.5,
        1.0,
        1.0,
    ];
    const LOG2_E: f32 = std::f32::consts::LOG2_E;
}

/// `e^x` lane by lane for `x <= 0` (see the [module docs](self)): a few
/// ulps, exactly 0 below the normal range, `x > 0` taken as 0.
#[inline(always)]
pub fn exp_nonpositive<T: LaneFloat, S: Simd<T>>(s: S, x: S::V) -> S::V {
    let min_x = s.splat(T::EXP_MIN_X);
    let xc = s.min(s.max(x, min_x), s.splat(T::ZERO));
    let magic = s.splat(T::EXP_MAGIC);
    let t = s.add(s.mul(xc, s.splat(T::LOG2_E)), magic);
    let n = s.sub(t, magic);
    let f = s.sub(
        s.sub(xc, s.mul(n, s.splat(T::LN2_HI))),
        s.mul(n, s.splat(T::LN2_LO)),
    );
    s.zero_unless_ge(
        s.mul(
            second_order_horner(s, T::EXP_TAYLOR, f),
            s.pow2_from_magic(t),
        ),
        x,
        min_x,
    )
}

/// The polynomial with coefficients `c` (highest degree first, an even
/// number of them) at `f` by second-order Horner: its odd and even parts as
/// two independent Horner chains in `f^2`, `p(f) = f O(f^2) + E(f^2)`. One
/// multiplication more than Horner's rule, and a dependency chain half as
/// long (7 fused multiply-adds instead of 13 in `f64`), which the
/// micro-kernels waiting on `e^x` feel.
#[inline(always)]
fn second_order_horner<T: LaneFloat, S: Simd<T>>(s: S, c: &[T], f: S::V) -> S::V {
    debug_assert!(c.len() >= 2 && c.len().is_multiple_of(2));
    let f2 = s.mul(f, f);
    // Degrees n - 1 (odd) and n - 2 (even).
    let (mut odd, mut even) = (s.splat(c[0]), s.splat(c[1]));
    for pair in c[2..].chunks_exact(2) {
        odd = s.mul_add(odd, f2, s.splat(pair[0]));
        even = s.mul_add(even, f2, s.splat(pair[1]));
    }
    s.mul_add(odd, f, even)
}

#[cfg(test)]
mod tests {
    use super::exp_nonpositive;
    use crate::lanes::{LaneFloat, Portable, Simd};

    /// Worst relative error of `exp_nonpositive` on backend `s` against
    /// `f64::exp`, over `n` points of `[lo, 0]`, quadratically spaced.
    fn worst<T: LaneFloat, S: Simd<T>>(s: S, lo: f64, n: usize) -> f64 {
        let xs: Vec<T> = (0..n)
            .map(|i| T::from_f64(lo * (i as f64 / n as f64).powi(2)))
            .collect();
        let mut out = vec![T::ZERO; n + S::LANES];
        for (i, chunk) in xs.chunks(S::LANES).enumerate() {
            let mut buf = vec![T::ZERO; S::LANES];
            buf[..chunk.len()].copy_from_slice(chunk);
            let v = exp_nonpositive(s, s.load(&buf));
            s.store(v, &mut out[i * S::LANES..]);
        }
        xs.iter()
            .zip(&out)
            .map(|(x, y)| {
                let e = x.to_f64().exp();
                ((y.to_f64() - e) / e).abs()
            })
            .fold(0.0, f64::max)
    }

    fn check<S: Simd<f64> + Simd<f32>>(s: S) {
        let w64 = worst::<f64, S>(s, -708.0, 100_000);
        assert!(w64 <= 4.0 * f64::EPSILON, "f64: {} eps", w64 / f64::EPSILON);
        let w32 = worst::<f32, S>(s, -87.0, 50_000);
        assert!(
            w32 <= 4.0 * f32::EPSILON as f64,
            "f32: {} eps",
            w32 / f32::EPSILON as f64
        );
        // Edges: 1 at 0, exactly 0 below the normal range, NaN and -Inf.
        for (x, y) in [
            (0.0, 1.0),
            (-800.0, 0.0),
            (f64::NEG_INFINITY, 0.0),
            (f64::NAN, 0.0),
        ] {
            let mut buf = vec![x; <S as Simd<f64>>::LANES];
            let v = exp_nonpositive::<f64, S>(s, s.load(&buf));
            s.store(v, &mut buf);
            assert!(buf.iter().all(|&b| b == y), "exp({x}) = {buf:?}");
        }
    }

    #[test]
    fn portable_exp_is_accurate() {
        check(Portable);
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn simd_exp_is_accurate() {
        use crate::SimdLevel;
        use crate::lanes::{Avx2, Avx512};
        let level = SimdLevel::detected();
        if level >= SimdLevel::Avx2 {
            // Made only after detection, as the crate's dispatch does.
            check(Avx2(()));
        }
        if level >= SimdLevel::Avx512 {
            check(Avx512(()));
        }
    }
}
