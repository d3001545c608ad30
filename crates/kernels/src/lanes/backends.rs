//! The instruction-set tokens and their [`Simd`] implementations.
//!
//! * [`Avx512`]: 8 `f64` / 16 `f32` lanes, mask registers; `1/sqrt` from
//!   `vrsqrt14` (relative error `< 2^-14`) refined with the series
//!   `y (1 - e)^(-1/2) = y (1 + e/2 + 3e^2/8 + 5e^3/16 + ...)`,
//!   `e = 1 - r2 y^2`: to `e^3` in `f64` (truncation `< 4.4 * 2^-56`), to
//!   `e` in `f32` (`< 1.5 * 2^-28`), both below half an ulp. Coincident
//!   lanes start from the masked estimate `y = 0` and stay exactly 0.
//! * [`Avx2`] (with FMA): 4 `f64` / 8 `f32` lanes; `f64` `1/sqrt` is an
//!   exact `sqrt` and division (no `f64` estimate in AVX2), `f32` uses
//!   `vrsqrtps` (`< 1.5 * 2^-12`) refined to `e^2` (truncation `~1.3e-10`);
//!   coincident lanes are cleared with a compare mask afterwards.
//! * [`Portable`]: one lane per "register", plain Rust (exact `sqrt` and
//!   division, unfused multiply-add), which the compiler vectorises across
//!   the 64 lanes of a block for the baseline target.

use super::{LaneFloat, Simd};

/// The AVX-512F instruction set. Only this crate makes one, after the CPU
/// was found to support it.
#[derive(Clone, Copy, Debug)]
pub struct Avx512(pub(in crate::lanes) ());

/// The AVX2 + FMA instruction sets. Only this crate makes one, after the
/// CPU was found to support them.
#[derive(Clone, Copy, Debug)]
pub struct Avx2(pub(in crate::lanes) ());

/// Portable Rust, one lane per register: runs everywhere.
#[derive(Clone, Copy, Debug, Default)]
pub struct Portable;

macro_rules! portable_impl {
    ($t:ty, $bits:ty, $exp_bias:expr, $mantissa:expr) => {
        impl Simd<$t> for Portable {
            type V = $t;
            const LANES: usize = 1;
            #[inline(always)]
            fn splat(self, x: $t) -> $t {
                x
            }
            #[inline(always)]
            fn add(self, a: $t, b: $t) -> $t {
                a + b
            }
            #[inline(always)]
            fn sub(self, a: $t, b: $t) -> $t {
                a - b
            }
            #[inline(always)]
            fn mul(self, a: $t, b: $t) -> $t {
                a * b
            }
            #[inline(always)]
            fn mul_add(self, a: $t, b: $t, c: $t) -> $t {
                // Unfused: a fused form would be a library call without FMA.
                a * b + c
            }
            #[inline(always)]
            fn div(self, a: $t, b: $t) -> $t {
                a / b
            }
            #[inline(always)]
            fn sqrt(self, a: $t) -> $t {
                a.sqrt()
            }
            #[inline(always)]
            fn min(self, a: $t, b: $t) -> $t {
                if a < b { a } else { b }
            }
            #[inline(always)]
            fn max(self, a: $t, b: $t) -> $t {
                if a > b { a } else { b }
            }
            #[inline(always)]
            fn rsqrt_or_zero(self, r2: $t) -> $t {
                if r2 >= <$t>::MIN_POSITIVE {
                    1.0 / r2.sqrt()
                } else {
                    0.0
                }
            }
            #[inline(always)]
            fn zero_unless_ge(self, v: $t, x: $t, bound: $t) -> $t {
                if x >= bound { v } else { 0.0 }
            }
            #[inline(always)]
            fn pow2_from_magic(self, t: $t) -> $t {
                let n = t
                    .to_bits()
                    .wrapping_sub(<$t as LaneFloat>::EXP_MAGIC.to_bits());
                <$t>::from_bits(n.wrapping_add($exp_bias) << $mantissa)
            }
            #[inline(always)]
            fn load(self, a: &[$t]) -> $t {
                a[0]
            }
            #[inline(always)]
            fn store(self, v: $t, a: &mut [$t]) {
                a[0] = v;
            }
        }
    };
}

portable_impl!(f64, u64, 1023, 52);
portable_impl!(f32, u32, 127, 23);

#[cfg(target_arch = "x86_64")]
pub(super) use x86::{task_avx2, task_avx512};

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use super::super::{LaneFloat, Simd, SimdTask};
    use super::{Avx2, Avx512};

    /// Run an intrinsic of the token's instruction set.
    macro_rules! simd {
        ($e:expr) => {
            // SAFETY: a token (`Avx512`, `Avx2`) is only made by the
            // `task_*` functions below, which callers enter only after
            // `SimdLevel` detection confirmed the CPU supports the
            // instruction set; the pointer intrinsics (loads, stores) get
            // slices checked to hold `LANES` values.
            unsafe { $e }
        };
    }

    /// The [`Simd`] items whose intrinsics differ only in name between
    /// the x86 instruction sets and float types: `V`, `LANES`, and
    /// `splat, add, sub, mul, mul_add (fused), div, sqrt, min, max, load,
    /// store`, each one intrinsic (the arguments, in that order).
    macro_rules! x86_common {
        ($t:ty, $v:ty, $lanes:literal,
         $splat:ident, $add:ident, $sub:ident, $mul:ident, $fma:ident, $div:ident,
         $sqrt:ident, $min:ident, $max:ident, $load:ident, $store:ident) => {
            type V = $v;
            const LANES: usize = $lanes;
            #[inline(always)]
            fn splat(self, x: $t) -> $v {
                simd!($splat(x))
            }
            #[inline(always)]
            fn add(self, a: $v, b: $v) -> $v {
                simd!($add(a, b))
            }
            #[inline(always)]
            fn sub(self, a: $v, b: $v) -> $v {
                simd!($sub(a, b))
            }
            #[inline(always)]
            fn mul(self, a: $v, b: $v) -> $v {
                simd!($mul(a, b))
            }
            #[inline(always)]
            fn mul_add(self, a: $v, b: $v, c: $v) -> $v {
                simd!($fma(a, b, c))
            }
            #[inline(always)]
            fn div(self, a: $v, b: $v) -> $v {
                simd!($div(a, b))
            }
            #[inline(always)]
            fn sqrt(self, a: $v) -> $v {
                simd!($sqrt(a))
            }
            #[inline(always)]
            fn min(self, a: $v, b: $v) -> $v {
                simd!($min(a, b))
            }
            #[inline(always)]
            fn max(self, a: $v, b: $v) -> $v {
                simd!($max(a, b))
            }
            #[inline(always)]
            fn load(self, a: &[$t]) -> $v {
                let a = &a[..$lanes];
                simd!($load(a.as_ptr()))
            }
            #[inline(always)]
            fn store(self, v: $v, a: &mut [$t]) {
                let a = &mut a[..$lanes];
                simd!($store(a.as_mut_ptr(), v))
            }
        };
    }

    /// A [`SimdTask`] compiled for AVX-512F.
    #[target_feature(enable = "avx512f")]
    pub(in crate::lanes) fn task_avx512<T: LaneFloat, W: SimdTask<T>>(task: W) -> W::Output
    where
        Avx512: Simd<T>,
    {
        task.run(Avx512(()))
    }

    /// A [`SimdTask`] compiled for AVX2 + FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(in crate::lanes) fn task_avx2<T: LaneFloat, W: SimdTask<T>>(task: W) -> W::Output
    where
        Avx2: Simd<T>,
    {
        task.run(Avx2(()))
    }

    impl Simd<f64> for Avx512 {
        x86_common!(
            f64,
            __m512d,
            8,
            _mm512_set1_pd,
            _mm512_add_pd,
            _mm512_sub_pd,
            _mm512_mul_pd,
            _mm512_fmadd_pd,
            _mm512_div_pd,
            _mm512_sqrt_pd,
            _mm512_min_pd,
            _mm512_max_pd,
            _mm512_loadu_pd,
            _mm512_storeu_pd
        );
        #[inline(always)]
        fn rsqrt_or_zero(self, r2: __m512d) -> __m512d {
            simd!({
                let nonzero =
                    _mm512_cmp_pd_mask::<_CMP_GE_OQ>(r2, _mm512_set1_pd(f64::MIN_POSITIVE));
                let y = _mm512_maskz_rsqrt14_pd(nonzero, r2);
                let ry = _mm512_mul_pd(r2, y);
                let e = _mm512_fnmadd_pd(ry, y, _mm512_set1_pd(1.0));
                let p = _mm512_fmadd_pd(_mm512_set1_pd(5.0 / 16.0), e, _mm512_set1_pd(3.0 / 8.0));
                let p = _mm512_fmadd_pd(p, e, _mm512_set1_pd(0.5));
                let ye = _mm512_mul_pd(y, e);
                _mm512_fmadd_pd(ye, p, y)
            })
        }
        #[inline(always)]
        fn zero_unless_ge(self, v: __m512d, x: __m512d, bound: __m512d) -> __m512d {
            simd!(_mm512_maskz_mov_pd(
                _mm512_cmp_pd_mask::<_CMP_GE_OQ>(x, bound),
                v
            ))
        }
        #[inline(always)]
        fn pow2_from_magic(self, t: __m512d) -> __m512d {
            simd!({
                let magic = _mm512_set1_epi64(<f64 as LaneFloat>::EXP_MAGIC.to_bits() as i64);
                let n = _mm512_sub_epi64(_mm512_castpd_si512(t), magic);
                let e = _mm512_add_epi64(n, _mm512_set1_epi64(1023));
                _mm512_castsi512_pd(_mm512_slli_epi64::<52>(e))
            })
        }
    }

    impl Simd<f32> for Avx512 {
        x86_common!(
            f32,
            __m512,
            16,
            _mm512_set1_ps,
            _mm512_add_ps,
            _mm512_sub_ps,
            _mm512_mul_ps,
            _mm512_fmadd_ps,
            _mm512_div_ps,
            _mm512_sqrt_ps,
            _mm512_min_ps,
            _mm512_max_ps,
            _mm512_loadu_ps,
            _mm512_storeu_ps
        );
        #[inline(always)]
        fn rsqrt_or_zero(self, r2: __m512) -> __m512 {
            simd!({
                let nonzero =
                    _mm512_cmp_ps_mask::<_CMP_GE_OQ>(r2, _mm512_set1_ps(f32::MIN_POSITIVE));
                let y = _mm512_maskz_rsqrt14_ps(nonzero, r2);
                let ry = _mm512_mul_ps(r2, y);
                let e = _mm512_fnmadd_ps(ry, y, _mm512_set1_ps(1.0));
                let ye = _mm512_mul_ps(y, e);
                _mm512_fmadd_ps(ye, _mm512_set1_ps(0.5), y)
            })
        }
        #[inline(always)]
        fn zero_unless_ge(self, v: __m512, x: __m512, bound: __m512) -> __m512 {
            simd!(_mm512_maskz_mov_ps(
                _mm512_cmp_ps_mask::<_CMP_GE_OQ>(x, bound),
                v
            ))
        }
        #[inline(always)]
        fn pow2_from_magic(self, t: __m512) -> __m512 {
            simd!({
                let magic = _mm512_set1_epi32(<f32 as LaneFloat>::EXP_MAGIC.to_bits() as i32);
                let n = _mm512_sub_epi32(_mm512_castps_si512(t), magic);
                let e = _mm512_add_epi32(n, _mm512_set1_epi32(127));
                _mm512_castsi512_ps(_mm512_slli_epi32::<23>(e))
            })
        }
    }

    impl Simd<f64> for Avx2 {
        x86_common!(
            f64,
            __m256d,
            4,
            _mm256_set1_pd,
            _mm256_add_pd,
            _mm256_sub_pd,
            _mm256_mul_pd,
            _mm256_fmadd_pd,
            _mm256_div_pd,
            _mm256_sqrt_pd,
            _mm256_min_pd,
            _mm256_max_pd,
            _mm256_loadu_pd,
            _mm256_storeu_pd
        );
        #[inline(always)]
        fn rsqrt_or_zero(self, r2: __m256d) -> __m256d {
            simd!({
                let nonzero = _mm256_cmp_pd::<_CMP_GE_OQ>(r2, _mm256_set1_pd(f64::MIN_POSITIVE));
                // 1/sqrt(0) = Inf: the mask turns it into exactly 0.
                _mm256_and_pd(
                    nonzero,
                    _mm256_div_pd(_mm256_set1_pd(1.0), _mm256_sqrt_pd(r2)),
                )
            })
        }
        #[inline(always)]
        fn zero_unless_ge(self, v: __m256d, x: __m256d, bound: __m256d) -> __m256d {
            simd!(_mm256_and_pd(_mm256_cmp_pd::<_CMP_GE_OQ>(x, bound), v))
        }
        #[inline(always)]
        fn pow2_from_magic(self, t: __m256d) -> __m256d {
            simd!({
                let magic = _mm256_set1_epi64x(<f64 as LaneFloat>::EXP_MAGIC.to_bits() as i64);
                let n = _mm256_sub_epi64(_mm256_castpd_si256(t), magic);
                let e = _mm256_add_epi64(n, _mm256_set1_epi64x(1023));
                _mm256_castsi256_pd(_mm256_slli_epi64::<52>(e))
            })
        }
    }

    impl Simd<f32> for Avx2 {
        x86_common!(
            f32,
            __m256,
            8,
            _mm256_set1_ps,
            _mm256_add_ps,
            _mm256_sub_ps,
            _mm256_mul_ps,
            _mm256_fmadd_ps,
            _mm256_div_ps,
            _mm256_sqrt_ps,
            _mm256_min_ps,
            _mm256_max_ps,
            _mm256_loadu_ps,
            _mm256_storeu_ps
        );
        #[inline(always)]
        fn rsqrt_or_zero(self, r2: __m256) -> __m256 {
            simd!({
                let nonzero = _mm256_cmp_ps::<_CMP_GE_OQ>(r2, _mm256_set1_ps(f32::MIN_POSITIVE));
                // vrsqrtps flushes subnormal input to 0 and gives Inf, the
                // refinement NaN: the mask turns it into exactly 0.
                let y = _mm256_rsqrt_ps(r2);
                let ry = _mm256_mul_ps(r2, y);
                let e = _mm256_fnmadd_ps(ry, y, _mm256_set1_ps(1.0));
                let p = _mm256_fmadd_ps(_mm256_set1_ps(3.0 / 8.0), e, _mm256_set1_ps(0.5));
                let ye = _mm256_mul_ps(y, e);
                _mm256_and_ps(nonzero, _mm256_fmadd_ps(ye, p, y))
            })
        }
        #[inline(always)]
        fn zero_unless_ge(self, v: __m256, x: __m256, bound: __m256) -> __m256 {
            simd!(_mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(x, bound), v))
        }
        #[inline(always)]
        fn pow2_from_magic(self, t: __m256) -> __m256 {
            simd!({
                let magic = _mm256_set1_epi32(<f32 as LaneFloat>::EXP_MAGIC.to_bits() as i32);
                let n = _mm256_sub_epi32(_mm256_castps_si256(t), magic);
                let e = _mm256_add_epi32(n, _mm256_set1_epi32(127));
                _mm256_castsi256_ps(_mm256_slli_epi32::<23>(e))
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Simd, SimdTask, run_task};
    use crate::simd::SimdLevel;

    /// `rsqrt_or_zero` of every value, in blocks of the token's lanes.
    struct Rsqrt<'a>(&'a [f64]);

    impl SimdTask<f64> for Rsqrt<'_> {
        type Output = Vec<f64>;
        fn run<S: Simd<f64>>(self, s: S) -> Vec<f64> {
            let mut out = vec![0.0; self.0.len()];
            for (x, y) in self
                .0
                .chunks_exact(S::LANES)
                .zip(out.chunks_exact_mut(S::LANES))
            {
                s.store(s.rsqrt_or_zero(s.load(x)), y);
            }
            out
        }
    }

    /// Every level's `f64` `1/sqrt(r2)` is within 2 ulps of the correctly
    /// rounded value over the whole exponent range, in blocks that mix
    /// magnitudes (AVX-512's estimate, refined, and AVX2's quotient), and
    /// exactly 0 below the smallest normal number (0, subnormals).
    #[test]
    fn f64_rsqrt_is_within_two_ulps_at_every_magnitude() {
        let (lo, hi) = (1e-36, 1e36);
        let mut values: Vec<f64> = Vec::new();
        let mut k = 0u64;
        for e in -1020..1020 {
            // A few mantissas per exponent (a cheap generator).
            for _ in 0..3 {
                k = k
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let m = 1.0 + (k >> 11) as f64 / (1u64 << 53) as f64;
                values.push(m * 2f64.powi(e));
            }
        }
        values.extend([lo, hi, lo * 0.999, hi * 1.001, 1.0, 4.0, 0.25, 3.0]);
        // Blocks of four: all in range, then each with one zero or one far value.
        for far in [0.0, 1e-300, f64::MIN_POSITIVE, 1e300, 5e-324] {
            values.extend([1.0, 2.0, far, 0.5]);
        }
        while !values.len().is_multiple_of(8) {
            values.push(1.0);
        }
        for level in [SimdLevel::Scalar, SimdLevel::Avx2, SimdLevel::Avx512] {
            let got = run_task(level, Rsqrt(&values));
            for (&r2, &y) in values.iter().zip(&got) {
                if r2 < f64::MIN_POSITIVE {
                    assert_eq!(y.to_bits(), 0, "{level:?}: 1/sqrt({r2:e}) = {y:e}, want 0");
                    continue;
                }
                let want = 1.0 / r2.sqrt();
                let ulp = f64::EPSILON * want;
                assert!(
                    (y - want).abs() <= 2.0 * ulp,
                    "{level:?}: 1/sqrt({r2:e}) = {y:e}, want {want:e} ({:.1} ulp)",
                    (y - want).abs() / ulp
                );
            }
        }
    }
}
