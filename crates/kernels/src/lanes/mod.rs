//! One vectorised P2P loop for every kernel: a kernel supplies a per-pair
//! **micro-kernel** on SIMD registers ([`LaneKernel::pair`]); the loop, the
//! target blocking and the run-time choice of instruction set live here,
//! once (the model is PVFMM's generic kernel).
//!
//! # The loop
//! For sources `x_i` with charges `q_i` and targets `y_j`, every kernel
//! computes
//!
//! ```text
//! out_j[0]    += s_K sum_i q_i K(x_i, y_j)                 (potential)
//! out_j[1..4] += s_K sum_i q_i grad_y K(x_i, y_j)          (gradient, optional)
//! ```
//!
//! with a constant factor `s_K` ([`LaneKernel::lane_scale`], `1 / (4 pi)`
//! for the kernels of this crate) applied once per target at the end.
//! Targets are taken in blocks of `C` registers of `L` lanes (`L` = 8 `f64`
//! / 16 `f32` with AVX-512, 4 / 8 with AVX2; `C` = 2, so that two
//! independent dependency chains hide the latency of a reciprocal square
//! root; the portable backend uses `L` = 1 and `C` = 64 lanes written as
//! plain loops that the compiler vectorises for the baseline target). A
//! block's target coordinates are de-interleaved once into registers, and
//! its accumulators stay in registers for the whole sweep over the sources.
//! Each source costs four broadcasts (`x`, `y`, `z`, `q`) shared by the
//! block; per register the loop forms `d = x_i - y` (source minus target)
//! and `r2 = |d|^2` (fused multiply-adds) and calls the micro-kernel, which
//! adds `q K` to `acc[0]` and, with `GRAD`, `q grad_y K` to `acc[1..4]`.
//! Sources are read in storage order, so each target's sum runs in the same
//! order on every backend.
//!
//! # Instruction sets
//! [`Simd`] is implemented by three zero-sized *tokens*: [`Avx512`],
//! [`Avx2`] and [`Portable`]. A token of an x86 set exists only once the CPU
//! has been found to support it (it cannot be built outside this crate), so
//! its methods, safe to call, may use the set's intrinsics. The loop is
//! compiled once per token inside a `#[target_feature]` function and picked
//! at run time from [`SimdLevel`](crate::SimdLevel); the micro-kernel, generic
//! over the token, is inlined into it.
//!
//! # Coincident points
//! A pair whose `r2` is below the smallest normal number of `T` (`r == 0`,
//! or `r < ~1.5e-154` in `f64`, `~1.1e-19` in `f32`) must contribute
//! exactly zero: [`Simd::rsqrt_or_zero`] returns 0 there, so a micro-kernel
//! that multiplies by it is safe; one that does not uses
//! [`Simd::zero_unless_ge`] with [`LaneFloat::MIN_POSITIVE`].
//!
//! # Writing a kernel
//! ```
//! use ferrofmm_kernels::lanes::{self, LaneFloat, LaneKernel, Simd};
//! use ferrofmm_kernels::{EvalMode, Kernel, Real};
//!
//! /// The Plummer-softened kernel 1 / (4 pi sqrt(r^2 + a^2)).
//! #[derive(Clone, Copy)]
//! struct Softened { a2: f64 }
//!
//! impl LaneKernel for Softened {
//!     #[inline(always)]
//!     fn pair<T: LaneFloat, S: Simd<T>, const GRAD: bool>(
//!         &self, s: S, d: [S::V; 3], r2: S::V, q: S::V, acc: &mut [S::V; 4],
//!     ) {
//!         let rho2 = s.add(r2, s.splat(T::from_f64(self.a2)));
//!         // Coincident points: zero, as for every kernel here.
//!         let rinv = s.zero_unless_ge(s.rsqrt_or_zero(rho2), r2, s.splat(T::MIN_POSITIVE));
//!         let qr = s.mul(q, rinv);
//!         acc[0] = s.add(acc[0], qr);
//!         if GRAD {
//!             // grad_y K = (x - y) / rho^3 = d rinv^3
//!             let c = s.mul(qr, s.mul(rinv, rinv));
//!             lanes::add_radial_gradient(s, c, &d, acc);
//!         }
//!     }
//!     fn lane_scale(&self) -> f64 { 0.25 / std::f64::consts::PI }
//! }
//!
//! impl Kernel for Softened {
//!     fn name(&self) -> String { "softened".into() }
//!     fn parameters(&self) -> Vec<f64> { vec![self.a2] }
//!     fn homogeneity(&self) -> Option<f64> { None }
//!     fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
//!         let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
//!         T::from_f64(0.25 / std::f64::consts::PI) / (r2 + T::from_f64(self.a2)).sqrt()
//!     }
//!     fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
//!         let rho2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + T::from_f64(self.a2);
//!         let c = -T::from_f64(0.25 / std::f64::consts::PI) / (rho2 * rho2.sqrt());
//!         [c * d[0], c * d[1], c * d[2]]
//!     }
//!     // The vectorised loop instead of the pairwise default.
//!     fn evaluate<T: Real>(&self, mode: EvalMode, s: &[T], q: &[T], t: &[T], out: &mut [T]) {
//!         lanes::evaluate(self, mode, s, q, t, out);
//!     }
//! }
//!
//! let mut phi = [0.0f64];
//! Softened { a2: 1.0 }.evaluate(EvalMode::Potential, &[0.0; 3], &[1.0], &[0.0, 0.0, 1.0], &mut phi);
//! assert!((phi[0] - 0.25 / std::f64::consts::PI / 2f64.sqrt()).abs() < 1e-15);
//! ```

mod backends;
mod exp;
mod radial;

pub use backends::{Avx2, Avx512, Portable};
pub use exp::exp_nonpositive;
pub use radial::{RadialLaneKernel, composed_with, evaluate_sources, evaluate_sources_with};

use crate::{EvalMode, Kernel, Real, SimdLevel, SourceKind};

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// The float types of the vectorised loop (`f32`, `f64`; sealed), with the
/// constants of [`exp_nonpositive`].
pub trait LaneFloat: Real + sealed::Sealed {
    /// `1.5 * 2^(p - 1)` for `p` mantissa bits: adding it rounds to an
    /// integer kept in the low bits.
    #[doc(hidden)]
    const EXP_MAGIC: Self;
    /// `ln 2` split into a short high part ...
    #[doc(hidden)]
    const LN2_HI: Self;
    /// ... and the rest.
    #[doc(hidden)]
    const LN2_LO: Self;
    /// Below this `exp` is taken as 0 (the normal range ends).
    #[doc(hidden)]
    const EXP_MIN_X: Self;
    /// Taylor coefficients of `e^f`, highest degree first.
    #[doc(hidden)]
    const EXP_TAYLOR: &'static [Self];
    /// `log2(e)`.
    #[doc(hidden)]
    const LOG2_E: Self;
}

/// Registers of lanes of `T` for one instruction set: the operations a
/// micro-kernel may use (see the [module docs](self)). Implemented by the
/// tokens [`Avx512`], [`Avx2`] and [`Portable`] only.
pub trait Simd<T: LaneFloat>: Copy + Send + Sync + 'static {
    /// One register.
    type V: Copy;
    /// Lanes per register.
    const LANES: usize;
    /// Every lane `x`.
    fn splat(self, x: T) -> Self::V;
    /// `a + b`.
    fn add(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a - b`.
    fn sub(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a * b`.
    fn mul(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a * b + c`, fused where the instruction set has FMA.
    fn mul_add(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// `a / b`, correctly rounded.
    fn div(self, a: Self::V, b: Self::V) -> Self::V;
    /// `sqrt(a)`, correctly rounded.
    fn sqrt(self, a: Self::V) -> Self::V;
    /// Lane-wise minimum.
    fn min(self, a: Self::V, b: Self::V) -> Self::V;
    /// Lane-wise maximum.
    fn max(self, a: Self::V, b: Self::V) -> Self::V;
    /// `1 / sqrt(r2)` to the precision of `T` (within an ulp) where
    /// `r2 >= T::MIN_POSITIVE`, exactly `0` elsewhere (coincident points,
    /// NaN).
    fn rsqrt_or_zero(self, r2: Self::V) -> Self::V;
    /// `v` where `x >= bound`, exactly `0` elsewhere (and where `x` is NaN).
    fn zero_unless_ge(self, v: Self::V, x: Self::V, bound: Self::V) -> Self::V;
    /// `2^n` for `t = EXP_MAGIC + n` (`n` an integer in the exponent range):
    /// the bit step of [`exp_nonpositive`].
    #[doc(hidden)]
    fn pow2_from_magic(self, t: Self::V) -> Self::V;
    /// The first `LANES` values of `a` (`a.len() >= LANES`).
    fn load(self, a: &[T]) -> Self::V;
    /// Write `v` to the first `LANES` values of `a` (`a.len() >= LANES`).
    fn store(self, v: Self::V, a: &mut [T]);
}

/// A kernel whose P2P runs in the vectorised loop of this module: it
/// supplies the contribution of one source to one register of targets.
///
/// Implement [`LaneKernel::pair`] (mark it `#[inline(always)]`, so that it
/// is compiled into each instruction set's loop), and let
/// [`Kernel::evaluate`] call [`evaluate`]. Keep [`Kernel::kernel_value`] and
/// [`Kernel::kernel_gradient`] consistent with it: the operators are
/// precomputed from them, and tests compare the two.
pub trait LaneKernel: Kernel {
    /// Add one source's contribution to a register of targets:
    /// `acc[0] += q K(x, y)` and, when `GRAD`, `acc[1 + k] += q d/dy_k K(x, y)`,
    /// both without the factor [`LaneKernel::lane_scale`]. `d = x - y`
    /// (source minus target) per lane and `r2 = |d|^2`. Coincident lanes
    /// (`r2 < T::MIN_POSITIVE`) must add exactly zero (see the
    /// [module docs](self)).
    fn pair<T: LaneFloat, S: Simd<T>, const GRAD: bool>(
        &self,
        s: S,
        d: [S::V; 3],
        r2: S::V,
        q: S::V,
        acc: &mut [S::V; 4],
    );

    /// The constant factor applied to every output once per target
    /// (default 1).
    fn lane_scale(&self) -> f64 {
        1.0
    }
}

/// `acc[1 + k] += c d[k]` for `k = 0, 1, 2`: the gradient step of a radial
/// kernel `K(r)`, whose `q grad_y K = c (x - y)` with `c = -q K'(r) / r`
/// (for `1/r`: `c = q / r^3`). Three fused multiply-adds; the micro-kernels
/// of [`LaneKernel::pair`] call it under `if GRAD`.
#[inline(always)]
pub fn add_radial_gradient<T: LaneFloat, S: Simd<T>>(
    s: S,
    c: S::V,
    d: &[S::V; 3],
    acc: &mut [S::V; 4],
) {
    acc[1] = s.mul_add(c, d[0], acc[1]);
    acc[2] = s.mul_add(c, d[1], acc[2]);
    acc[3] = s.mul_add(c, d[2], acc[3]);
}

/// Vectorised work other than P2P (an FFT scheme's frequency products, a
/// user's own loop) on the same instruction-set tokens: [`run_task`] picks
/// the token for the CPU and calls [`SimdTask::run`] inside a function
/// compiled for that instruction set.
///
/// Mark `run` `#[inline(always)]` (and everything it calls on registers):
/// only code inlined into the `#[target_feature]` function is compiled with
/// the wider instructions.
///
/// ```
/// use ferrofmm_kernels::SimdLevel;
/// use ferrofmm_kernels::lanes::{run_task, Simd, SimdTask};
///
/// /// `y += a x` on whole registers, the tail in scalars.
/// struct Axpy<'a> { a: f64, x: &'a [f64], y: &'a mut [f64] }
///
/// impl SimdTask<f64> for Axpy<'_> {
///     type Output = ();
///     #[inline(always)]
///     fn run<S: Simd<f64>>(self, s: S) {
///         let l = S::LANES;
///         let whole = self.x.len() / l * l;
///         let a = s.splat(self.a);
///         for i in (0..whole).step_by(l) {
///             let v = s.mul_add(a, s.load(&self.x[i..]), s.load(&self.y[i..]));
///             s.store(v, &mut self.y[i..]);
///         }
///         for i in whole..self.x.len() {
///             self.y[i] += self.a * self.x[i];
///         }
///     }
/// }
///
/// let x = vec![1.0; 19];
/// let mut y = vec![2.0; 19];
/// run_task(SimdLevel::active(), Axpy { a: 3.0, x: &x, y: &mut y });
/// assert!(y.iter().all(|&v| v == 5.0));
/// ```
pub trait SimdTask<T: LaneFloat> {
    /// What the task returns.
    type Output;
    /// The work, on registers of the token `s`.
    fn run<S: Simd<T>>(self, s: S) -> Self::Output;
}

/// Run `task` with the token of `level`, lowered to what the CPU supports
/// (so any `level` is safe): [`Avx512`], [`Avx2`] or [`Portable`].
#[cfg(target_arch = "x86_64")]
pub fn run_task<T: LaneFloat, W: SimdTask<T>>(level: SimdLevel, task: W) -> W::Output
where
    Avx512: Simd<T>,
    Avx2: Simd<T>,
    Portable: Simd<T>,
{
    match level.clamp_supported() {
        SimdLevel::Avx512 => {
            // SAFETY: clamped to `SimdLevel::detected()`, so the CPU
            // supports avx512f, the only feature this function enables.
            unsafe { backends::task_avx512(task) }
        }
        SimdLevel::Avx2 => {
            // SAFETY: clamped to `SimdLevel::detected()`, so the CPU
            // supports avx2 and fma, the features this function enables.
            unsafe { backends::task_avx2(task) }
        }
        SimdLevel::Scalar => task.run(Portable),
    }
}

/// Run `task` with the [`Portable`] token (no other backend on this
/// architecture).
#[cfg(not(target_arch = "x86_64"))]
pub fn run_task<T: LaneFloat, W: SimdTask<T>>(_level: SimdLevel, task: W) -> W::Output
where
    Portable: Simd<T>,
{
    task.run(Portable)
}

/// Runs `$task` (an expression naming the slices `$s, $q, $t, $o`) with
/// [`run_task`] at `$level` on the caller's `Real` slices as `f64` or as
/// `f32`, whichever they are: one place for the float-type split of every
/// vectorised loop (the expression is compiled once per type).
macro_rules! run_on_floats {
    ($level:expr, ($s:ident, $q:ident, $t:ident, $o:ident) => $task:expr) => {
        if let (Some($s), Some($q), Some($t)) = (
            $crate::Real::as_f64_slice($s),
            $crate::Real::as_f64_slice($q),
            $crate::Real::as_f64_slice($t),
        ) {
            let $o = $crate::Real::as_f64_slice_mut($o).expect("same type as the inputs");
            $crate::lanes::run_task($level, $task)
        } else {
            let $s = $crate::Real::as_f32_slice($s).expect("a Real is f32 or f64");
            let $q = $crate::Real::as_f32_slice($q).expect("a Real is f32 or f64");
            let $t = $crate::Real::as_f32_slice($t).expect("a Real is f32 or f64");
            let $o = $crate::Real::as_f32_slice_mut($o).expect("a Real is f32 or f64");
            $crate::lanes::run_task($level, $task)
        }
    };
}
pub(crate) use run_on_floats;

/// Accumulate the kernel's potentials (and gradients) of `sources` with
/// `charges` at `targets` into `out` (layout of [`Kernel::evaluate`]) with
/// the vectorised loop at [`SimdLevel::active`].
///
/// # Panics
/// When a coordinate slice's length is not a multiple of 3, or `charges` /
/// `out` do not match the number of sources / targets, or `mode` asks for
/// Hessians (those come from a [`RadialLaneKernel`] through
/// [`evaluate_sources`]).
#[inline]
pub fn evaluate<K: LaneKernel, T: Real>(
    kernel: &K,
    mode: EvalMode,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &mut [T],
) {
    evaluate_with(
        SimdLevel::active(),
        kernel,
        mode,
        sources,
        charges,
        targets,
        out,
    );
}

/// [`evaluate`] at a given instruction-set `level` (lowered to what the
/// CPU supports, so any value is safe). Float types other than `f32` and
/// `f64` use the pairwise reference.
///
/// # Panics
/// As [`evaluate`].
pub fn evaluate_with<K: LaneKernel, T: Real>(
    level: SimdLevel,
    kernel: &K,
    mode: EvalMode,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &mut [T],
) {
    if let Err(e) =
        crate::direct::check_lengths(1, SourceKind::Charge, mode, sources, charges, targets, out)
    {
        panic!("{} P2P: {e}", kernel.name());
    }
    assert!(
        !mode.has_hessian(),
        "{} P2P: Hessians come from lanes::evaluate_sources (RadialLaneKernel)",
        kernel.name()
    );
    if sources.is_empty() || targets.is_empty() {
        return;
    }
    let level = level.clamp_supported();
    let grad = mode == EvalMode::PotentialGradient;
    if let (Some(s), Some(q), Some(t)) = (
        T::as_f64_slice(sources),
        T::as_f64_slice(charges),
        T::as_f64_slice(targets),
    ) {
        let o = T::as_f64_slice_mut(out).expect("same type as the inputs");
        dispatch(level, grad, kernel, s, q, t, o);
    } else if let (Some(s), Some(q), Some(t)) = (
        T::as_f32_slice(sources),
        T::as_f32_slice(charges),
        T::as_f32_slice(targets),
    ) {
        let o = T::as_f32_slice_mut(out).expect("same type as the inputs");
        dispatch(level, grad, kernel, s, q, t, o);
    } else {
        crate::reference::evaluate_pairwise(kernel, mode, sources, charges, targets, out);
    }
}

/// The loop for `level` (which the CPU supports: callers clamp it).
#[cfg(target_arch = "x86_64")]
fn dispatch<T: LaneFloat, K: LaneKernel>(
    level: SimdLevel,
    grad: bool,
    kernel: &K,
    s: &[T],
    q: &[T],
    t: &[T],
    o: &mut [T],
) where
    Avx512: Simd<T>,
    Avx2: Simd<T>,
    Portable: Simd<T>,
{
    match (level, grad) {
        #[cfg(target_arch = "x86_64")]
        (SimdLevel::Avx512, true) => {
            // SAFETY: `level` was clamped to `SimdLevel::detected()`, so the
            // CPU supports avx512f, the only feature this function enables.
            unsafe { backends::run_avx512::<T, K, true>(kernel, s, q, t, o) }
        }
        #[cfg(target_arch = "x86_64")]
        (SimdLevel::Avx512, false) => {
            // SAFETY: as above.
            unsafe { backends::run_avx512::<T, K, false>(kernel, s, q, t, o) }
        }
        #[cfg(target_arch = "x86_64")]
        (SimdLevel::Avx2, true) => {
            // SAFETY: `level` was clamped to `SimdLevel::detected()`, so the
            // CPU supports avx2 and fma, the features this function enables.
            unsafe { backends::run_avx2::<T, K, true>(kernel, s, q, t, o) }
        }
        #[cfg(target_arch = "x86_64")]
        (SimdLevel::Avx2, false) => {
            // SAFETY: as above.
            unsafe { backends::run_avx2::<T, K, false>(kernel, s, q, t, o) }
        }
        (_, true) => p2p::<T, Portable, K, PORTABLE_BLOCK, true>(Portable, kernel, s, q, t, o),
        (_, false) => p2p::<T, Portable, K, PORTABLE_BLOCK, false>(Portable, kernel, s, q, t, o),
    }
}

/// The portable loop (no other backend on this architecture).
#[cfg(not(target_arch = "x86_64"))]
fn dispatch<T: LaneFloat, K: LaneKernel>(
    _level: SimdLevel,
    grad: bool,
    kernel: &K,
    s: &[T],
    q: &[T],
    t: &[T],
    o: &mut [T],
) where
    Portable: Simd<T>,
{
    if grad {
        p2p::<T, Portable, K, PORTABLE_BLOCK, true>(Portable, kernel, s, q, t, o)
    } else {
        p2p::<T, Portable, K, PORTABLE_BLOCK, false>(Portable, kernel, s, q, t, o)
    }
}

/// Registers per target block of the SIMD backends.
const SIMD_BLOCK: usize = 2;
/// Lanes per target block of the portable backend (one lane per register).
const PORTABLE_BLOCK: usize = 64;
/// Largest block, in targets (`C * LANES`): 2 x 16 `f32` or 64 x 1.
const MAX_BLOCK: usize = 64;

/// The loop over all targets, `C` registers at a time (`GRAD`: 4 values per
/// target, else 1); inlined into each backend's `target_feature` function.
/// Mismatched lengths only truncate the loops.
#[inline(always)]
fn p2p<T: LaneFloat, S: Simd<T>, K: LaneKernel, const C: usize, const GRAD: bool>(
    s: S,
    kernel: &K,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &mut [T],
) {
    let w = w_of::<GRAD>();
    let block = C * S::LANES;
    debug_assert!(block <= MAX_BLOCK);
    for (tb, ob) in targets.chunks(3 * block).zip(out.chunks_mut(w * block)) {
        if C > 1 && tb.len() <= 3 * S::LANES {
            // One register suffices for the last few targets.
            block_of::<T, S, K, 1, GRAD>(s, kernel, sources, charges, tb, ob);
        } else {
            block_of::<T, S, K, C, GRAD>(s, kernel, sources, charges, tb, ob);
        }
    }
}

/// Up to `C * LANES` targets (`tb`, interleaved) against all sources.
#[inline(always)]
fn block_of<T: LaneFloat, S: Simd<T>, K: LaneKernel, const C: usize, const GRAD: bool>(
    s: S,
    kernel: &K,
    sources: &[T],
    charges: &[T],
    tb: &[T],
    ob: &mut [T],
) {
    let l = S::LANES;
    // De-interleave the block's targets, zero-padded.
    let mut buf = [[T::ZERO; MAX_BLOCK]; 3];
    for (k, p) in tb.chunks_exact(3).enumerate() {
        buf[0][k] = p[0];
        buf[1][k] = p[1];
        buf[2][k] = p[2];
    }
    let zero = s.splat(T::ZERO);
    let mut tx = [zero; C];
    let mut ty = [zero; C];
    let mut tz = [zero; C];
    for c in 0..C {
        tx[c] = s.load(&buf[0][c * l..]);
        ty[c] = s.load(&buf[1][c * l..]);
        tz[c] = s.load(&buf[2][c * l..]);
    }
    // Accumulators by output, then register: with one lane per register
    // (portable) the loop over registers is then unit-stride, which the
    // compiler vectorises; with SIMD registers it is all in registers.
    let mut acc = [[zero; C]; 4];
    for (x, &q) in sources.chunks_exact(3).zip(charges) {
        let sx = s.splat(x[0]);
        let sy = s.splat(x[1]);
        let sz = s.splat(x[2]);
        let vq = s.splat(q);
        for c in 0..C {
            let dx = s.sub(sx, tx[c]);
            let dy = s.sub(sy, ty[c]);
            let dz = s.sub(sz, tz[c]);
            let r2 = s.mul_add(dz, dz, s.mul_add(dy, dy, s.mul(dx, dx)));
            let mut a = [acc[0][c], acc[1][c], acc[2][c], acc[3][c]];
            kernel.pair::<T, S, GRAD>(s, [dx, dy, dz], r2, vq, &mut a);
            for (k, v) in a.into_iter().enumerate() {
                acc[k][c] = v;
            }
        }
    }
    let scale = s.splat(T::from_f64(kernel.lane_scale()));
    let mut res = [[T::ZERO; MAX_BLOCK]; 4];
    for c in 0..C {
        for v in 0..w_of::<GRAD>() {
            s.store(s.mul(acc[v][c], scale), &mut res[v][c * l..]);
        }
    }
    for (j, o) in ob.chunks_exact_mut(w_of::<GRAD>()).enumerate() {
        for (v, r) in o.iter_mut().zip(&res) {
            *v += r[j];
        }
    }
}

/// Values per target: 4 with gradients, else 1.
#[inline(always)]
const fn w_of<const GRAD: bool>() -> usize {
    if GRAD { 4 } else { 1 }
}
