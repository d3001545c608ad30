//! `exp` written with plain arithmetic and bit operations, so that loops
//! calling it vectorise (a libm call does not).
//!
//! Method (Cody–Waite): `x = n ln2 + f`, `n = round(x / ln2)` found with the
//! "magic number" trick (adding `1.5 * 2^(p-1)` rounds to an integer and
//! leaves it in the low bits), `ln2` split into a short high part and a low
//! part so that `f = x - n ln2` is nearly exact, `|f| <= ln2 / 2`; then
//! `exp(f)` by its Taylor polynomial (degree 13 for `f64`: truncation
//! `< 4.3e-18`; degree 7 for `f32`: `< 5.3e-9`) and the factor `2^n` built
//! directly in the exponent bits. Accurate to a few ulps.
//!
//! Valid for `x <= 0` down to the normal range (`f64`: `x >= -708`,
//! `f32`: `x >= -87`); smaller `x` returns exactly 0 instead of a subnormal
//! (absolute error below the smallest normal number). `x` is clamped above
//! at 0 (the kernels only need `exp(-k r)`).

/// A float type with a vectorisable `exp` for non-positive arguments.
pub(crate) trait FastExp: Copy {
    /// `e^x` for `x <= 0` (see the module docs).
    fn fast_exp(x: Self) -> Self;
}

impl FastExp for f64 {
    #[inline(always)]
    fn fast_exp(x: f64) -> f64 {
        const MAGIC: f64 = 6755399441055744.0; // 1.5 * 2^52
        // fdlibm's split of ln 2: 6.93147180369123816490e-01, 1.90821492927058770002e-10.
        const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
        const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
        const MIN_X: f64 = -708.0;
        let underflow = x < MIN_X;
        let x = if underflow {
            MIN_X
        } else if x > 0.0 {
            0.0
        } else {
            x
        };
        let t = x * std::f64::consts::LOG2_E + MAGIC;
        let n = t - MAGIC;
        let f = (x - n * LN2_HI) - n * LN2_LO;
        // Taylor polynomial of degree 13, Horner form.
        let mut p = 1.0 / 6_227_020_800.0; // 1/13!
        for c in [
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
        ] {
            p = p * f + c;
        }
        // t = MAGIC + n exactly (ulp of MAGIC is 1): n is in the low bits.
        let n_int = t.to_bits().wrapping_sub(MAGIC.to_bits());
        let scale = f64::from_bits(n_int.wrapping_add(1023) << 52);
        if underflow { 0.0 } else { p * scale }
    }
}

impl FastExp for f32 {
    #[inline(always)]
    fn fast_exp(x: f32) -> f32 {
        const MAGIC: f32 = 12_582_912.0; // 1.5 * 2^23
        const LN2_HI: f32 = 0.693_359_4;
        const LN2_LO: f32 = -2.121_944_4e-4;
        const MIN_X: f32 = -87.0;
        let underflow = x < MIN_X;
        let x = if underflow {
            MIN_X
        } else if x > 0.0 {
            0.0
        } else {
            x
        };
        let t = x * std::f32::consts::LOG2_E + MAGIC;
        let n = t - MAGIC;
        let f = (x - n * LN2_HI) - n * LN2_LO;
        // Taylor polynomial of degree 7.
        let mut p = 1.0 / 5_040.0;
        for c in [
            1.0 / 720.0,
            1.0 / 120.0,
            1.0 / 24.0,
            1.0 / 6.0,
            0.5,
            1.0,
            1.0,
        ] {
            p = p * f + c;
        }
        let n_int = t.to_bits().wrapping_sub(MAGIC.to_bits());
        let scale = f32::from_bits(n_int.wrapping_add(127) << 23);
        if underflow { 0.0 } else { p * scale }
    }
}

#[cfg(test)]
mod tests {
    use super::FastExp;

    #[test]
    fn f64_matches_std_exp_to_a_few_ulps() {
        let mut worst = 0.0f64;
        for i in 0..=200_000 {
            let x = -708.0 * (i as f64 / 200_000.0).powi(2);
            let (a, b) = (f64::fast_exp(x), x.exp());
            worst = worst.max(((a - b) / b).abs());
        }
        assert!(worst <= 4.0 * f64::EPSILON, "{} eps", worst / f64::EPSILON);
        assert_eq!(f64::fast_exp(0.0), 1.0);
        assert_eq!(f64::fast_exp(-800.0), 0.0);
        assert_eq!(f64::fast_exp(f64::NEG_INFINITY), 0.0);
    }

    #[test]
    fn f32_matches_f64_exp_to_a_few_ulps() {
        let mut worst = 0.0f64;
        for i in 0..=100_000 {
            let x = -87.0f32 * (i as f32 / 100_000.0).powi(2);
            let (a, b) = (f32::fast_exp(x) as f64, (x as f64).exp());
            worst = worst.max(((a - b) / b).abs());
        }
        assert!(
            worst <= 4.0 * f32::EPSILON as f64,
            "{} eps",
            worst / f32::EPSILON as f64
        );
        assert_eq!(f32::fast_exp(0.0), 1.0);
        assert_eq!(f32::fast_exp(-100.0), 0.0);
    }
}
