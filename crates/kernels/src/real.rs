//! The floating-point types ferrofmm computes in.
//!
//! Everything in the workspace is generic over [`Real`], implemented for
//! `f32` and `f64` only. The trait carries the handful of operations the FMM
//! needs plus a zero-cost way to recover the concrete slice type, so that a
//! kernel can dispatch to a hand-vectorised path for each precision without
//! `unsafe` or `TypeId` tricks.

use std::fmt::{Debug, Display};
use std::iter::Sum;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// Which concrete float type a [`Real`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Precision {
    /// IEEE 754 binary32.
    F32,
    /// IEEE 754 binary64.
    F64,
}

impl Precision {
    /// Short lower-case name (`"f32"` / `"f64"`), as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
}

/// A real floating-point scalar: `f32` or `f64`.
pub trait Real:
    Copy
    + Clone
    + Send
    + Sync
    + Debug
    + Display
    + Default
    + PartialEq
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
    + Sum
    + bytemuck::Pod
    + 'static
{
    /// Which concrete type this is.
    const PRECISION: Precision;
    /// Machine epsilon.
    const EPSILON: Self;
    /// Smallest positive normal number.
    const MIN_POSITIVE: Self;
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;

    /// Conversion from `f64` (rounding for `f32`).
    fn from_f64(x: f64) -> Self;
    /// Conversion to `f64` (exact).
    fn to_f64(self) -> f64;
    /// Square root.
    fn sqrt(self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// `e^self`.
    fn exp(self) -> Self;
    /// `(sin self, cos self)`.
    fn sin_cos(self) -> (Self, Self);
    /// True unless NaN or infinite.
    fn is_finite(self) -> bool;
    /// Larger of two values (NaN-ignoring, as `f64::max`).
    fn max(self, other: Self) -> Self;
    /// Smaller of two values.
    fn min(self, other: Self) -> Self;

    /// The slice as `&[f64]` when `Self = f64`, else `None`.
    fn as_f64_slice(s: &[Self]) -> Option<&[f64]>;
    /// The slice as `&[f32]` when `Self = f32`, else `None`.
    fn as_f32_slice(s: &[Self]) -> Option<&[f32]>;
    /// Mutable version of [`Real::as_f64_slice`].
    fn as_f64_slice_mut(s: &mut [Self]) -> Option<&mut [f64]>;
    /// Mutable version of [`Real::as_f32_slice`].
    fn as_f32_slice_mut(s: &mut [Self]) -> Option<&mut [f32]>;
}

macro_rules! impl_real {
    ($t:ty, $prec:expr, $as_self:ident, $as_self_mut:ident, $as_other:ident, $as_other_mut:ident, $other:ty) => {
        impl Real for $t {
            const PRECISION: Precision = $prec;
            const EPSILON: Self = <$t>::EPSILON;
            const MIN_POSITIVE: Self = <$t>::MIN_POSITIVE;
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;

            #[inline(always)]
            fn from_f64(x: f64) -> Self {
                x as $t
            }
            #[inline(always)]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn exp(self) -> Self {
                <$t>::exp(self)
            }
            #[inline(always)]
            fn sin_cos(self) -> (Self, Self) {
                <$t>::sin_cos(self)
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
            #[inline(always)]
            fn max(self, other: Self) -> Self {
                <$t>::max(self, other)
            }
            #[inline(always)]
            fn min(self, other: Self) -> Self {
                <$t>::min(self, other)
            }
            #[inline(always)]
            fn $as_self(s: &[Self]) -> Option<&[$t]> {
                Some(s)
            }
            #[inline(always)]
            fn $as_other(_s: &[Self]) -> Option<&[$other]> {
                None
            }
            #[inline(always)]
            fn $as_self_mut(s: &mut [Self]) -> Option<&mut [$t]> {
                Some(s)
            }
            #[inline(always)]
            fn $as_other_mut(_s: &mut [Self]) -> Option<&mut [$other]> {
                None
            }
        }
    };
}

impl_real!(
    f64,
    Precision::F64,
    as_f64_slice,
    as_f64_slice_mut,
    as_f32_slice,
    as_f32_slice_mut,
    f32
);
impl_real!(
    f32,
    Precision::F32,
    as_f32_slice,
    as_f32_slice_mut,
    as_f64_slice,
    as_f64_slice_mut,
    f64
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slice_recovery_matches_type() {
        let a = [1.0f64, 2.0];
        assert!(f64::as_f64_slice(&a).is_some());
        assert!(f64::as_f32_slice(&a).is_none());
        let b = [1.0f32];
        assert!(f32::as_f32_slice(&b).is_some());
        assert!(f32::as_f64_slice(&b).is_none());
    }
}
