//! The plumbing for those who implement a kernel: one vectorised P2P loop,
//! the **lane engine**, for every kernel of the crate and kernels written
//! outside it. A kernel supplies a per-pair **micro-kernel** on SIMD
//! registers; the loop over targets and sources, the target blocking, the
//! block sizes and the run-time choice of instruction set live here, once
//! (the model is PVFMM's generic kernel; the layout of this module that of
//! rayon's `iter::plumbing`).
//!
//! # The engine
//! For sources `x_i` with densities `q_i` (`NQ` values each: a charge, a
//! complex charge, a dipole, a force, ...) and targets `y_j`, every kernel
//! computes `W` outputs per target
//!
//! ```text
//! out_j[0..W] += s_K sum_i m(x_i - y_j, q_i)
//! ```
//!
//! with a micro-kernel `m` ([`PairKernel::pair`]) and a constant factor
//! `s_K` ([`PairKernel::lane_scale`]) applied once per target at the end.
//! `NQ` and `W` are compile-time constants (the *shape* of a call), picked
//! by the kernel from the source kind, the outputs and its components
//! ([`LaneSources`]), so each shape compiles to its own loop. Targets are
//! taken in blocks of `C` registers of `L` lanes (`L` = 8 `f64` / 16 `f32`
//! with AVX-512, 4 / 8 with AVX2; `C` = 2 while `W` is small, so that two
//! independent dependency chains hide the latency of a reciprocal square
//! root, else 1; the portable backend uses `L` = 1 and `C` = 64 lanes
//! written as plain loops that the compiler vectorises for the baseline
//! target, or 16 for long micro-kernels: [`PairKernel::TWO_REGISTERS_UP_TO`],
//! [`PairKernel::PORTABLE_LANES`]). A block's target coordinates are
//! de-interleaved once into registers, and its `W` accumulators stay in
//! registers for the whole sweep over the sources: up to 8 outputs they go
//! to the micro-kernel in place; beyond (Hessians) they are copied in and
//! out around each call, which lets the register allocator spill them
//! better (both measured). Each source costs
//! `3 + NQ` broadcasts shared by the block; per register the loop forms
//! `d = x_i - y` (source minus target) and `r2 = |d|^2` (fused
//! multiply-adds) and calls the micro-kernel. Sources are read in storage
//! order, so each target's sum runs in the same order on every backend.
//!
//! # Entry points and layers
//! * [`evaluate_sources_with`] (and [`evaluate_sources`] at
//!   [`SimdLevel::active`]): every kernel of the crate ([`LaneSources`]),
//!   every source kind and output it supports; what their
//!   [`Kernel::evaluate`] and [`Kernel::evaluate_sources`] call.
//! * [`LaneKernel`]: the short way for a scalar kernel with charges: one
//!   micro-kernel for a charge and 1 or 4 outputs, run by [`evaluate_with`]
//!   (see the example below).
//! * [`RadialLaneKernel`]: a radial kernel's derivatives `f_0 .. f_3`,
//!   from which the engine composes dipoles and Hessians (and which makes
//!   the kernel a [`LaneSources`]).
//! * [`PairKernel`] and [`run`]: the engine itself, for a kernel with
//!   several components or its own source kinds ([`Helmholtz3d`] and
//!   [`Stokes3d`] are written this way).
//! * [`SimdTask`] and [`run_task`]: other vectorised work on the same
//!   instruction-set tokens.
//!
//! [`Helmholtz3d`]: crate::Helmholtz3d
//! [`Stokes3d`]: crate::Stokes3d
//!
//! # Instruction sets
//! [`Simd`] is implemented by three zero-sized *tokens*: [`Avx512`],
//! [`Avx2`] and [`Portable`]. A token of an x86 set exists only once the CPU
//! has been found to support it (it cannot be built outside this crate), so
//! its methods, safe to call, may use the set's intrinsics. The loop is
//! compiled once per token inside a `#[target_feature]` function and picked
//! at run time from [`SimdLevel`]; the micro-kernel, generic
//! over the token, is inlined into it.
//!
//! # Coincident points
//! A pair whose `r2` is below the smallest normal number of `T` (`r == 0`,
//! or `r < ~1.5e-154` in `f64`, `~1.1e-19` in `f32`) must contribute
//! exactly zero: [`Simd::rsqrt_or_zero`] returns 0 there, so a micro-kernel
//! that multiplies by it is safe; one that does not uses
//! [`Simd::zero_unless_ge`] with [`Real::MIN_POSITIVE`].
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
mod engine;
pub mod exp;
pub mod radial;

pub use backends::{Avx2, Avx512, Portable};
pub use engine::{PairKernel, run};
pub use exp::exp_nonpositive;
pub use radial::{RadialLaneKernel, composed_with};

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

/// A scalar kernel whose P2P with charges runs in the lane engine: it
/// supplies the contribution of one charge to one register of targets (the
/// engine runs it as a [`PairKernel`] with `NQ = 1` and `W = 1` or 4).
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
/// the lane engine at [`SimdLevel::active`].
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
/// CPU supports, so any value is safe).
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
    check(
        kernel,
        SourceKind::Charge,
        mode,
        [sources, charges, targets, out],
    );
    assert!(
        !mode.has_hessian(),
        "{} P2P: Hessians come from lanes::evaluate_sources (RadialLaneKernel)",
        kernel.name()
    );
    let (s, q, t, o) = (sources, charges, targets, out);
    if mode.has_gradient() {
        run::<_, _, 1, 4>(level, &Charges(kernel), s, q, t, o);
    } else {
        run::<_, _, 1, 1>(level, &Charges(kernel), s, q, t, o);
    }
}

/// A [`LaneKernel`] as the engine's [`PairKernel`]: one charge per source,
/// 1 or 4 outputs per target.
struct Charges<'a, K>(&'a K);

impl<K: LaneKernel> PairKernel for Charges<'_, K> {
    type Regs<T: LaneFloat, S: Simd<T>> = ();

    #[inline(always)]
    fn regs<T: LaneFloat, S: Simd<T>>(&self, _s: S) {}

    #[inline(always)]
    fn pair<T: LaneFloat, S: Simd<T>, const NQ: usize, const W: usize>(
        &self,
        s: S,
        _regs: &(),
        d: &[S::V; 3],
        r2: S::V,
        q: &[S::V; NQ],
        acc: &mut [S::V; W],
    ) {
        if let Ok(a) = <&mut [S::V; 4]>::try_from(&mut acc[..]) {
            self.0.pair::<T, S, true>(s, *d, r2, q[0], a);
        } else {
            let zero = s.splat(T::ZERO);
            let mut a = [acc[0], zero, zero, zero];
            self.0.pair::<T, S, false>(s, *d, r2, q[0], &mut a);
            acc[0] = a[0];
        }
    }

    fn lane_scale(&self) -> f64 {
        self.0.lane_scale()
    }
}

/// A kernel whose every supported `(kind, mode)` runs in the lane engine:
/// it picks the shape `(NQ, W)` and the [`PairKernel`] of each and calls
/// [`run`]. Every [`RadialLaneKernel`] is one; so are
/// [`Helmholtz3d`](crate::Helmholtz3d) and [`Stokes3d`](crate::Stokes3d).
/// [`evaluate_sources_with`] is the entry point.
pub trait LaneSources: Kernel {
    /// Run the engine for `(kind, mode)` at `level`: the pair is
    /// [supported](Kernel::supports) and the lengths are checked.
    #[allow(clippy::too_many_arguments)]
    fn run_sources<T: Real>(
        &self,
        level: SimdLevel,
        kind: SourceKind,
        mode: EvalMode,
        sources: &[T],
        densities: &[T],
        targets: &[T],
        out: &mut [T],
    );
}

/// Accumulate the field of sources of `kind` (densities interleaved,
/// [`Kernel::values_per_source`] per source) at `targets`, outputs of
/// `mode` ([`Kernel::values_per_target`] per target), into `out`, at
/// [`SimdLevel::active`]: what the kernels of this crate run in
/// [`Kernel::evaluate`] and [`Kernel::evaluate_sources`].
///
/// # Panics
/// When a coordinate slice's length is not a multiple of 3, `densities` /
/// `out` do not match the number of sources / targets, or the kernel does
/// not [support](Kernel::supports) `(kind, mode)`.
#[inline]
pub fn evaluate_sources<K: LaneSources, T: Real>(
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &[T],
    densities: &[T],
    targets: &[T],
    out: &mut [T],
) {
    let level = SimdLevel::active();
    evaluate_sources_with(level, kernel, kind, mode, sources, densities, targets, out);
}

/// [`evaluate_sources`] at a given instruction-set `level` (lowered to
/// what the CPU supports, so any value is safe): the one entry point of
/// every kernel's P2P at a chosen level, for tests and benchmarks.
///
/// ```
/// use ferrofmm_kernels::{lanes, EvalMode, SimdLevel, SourceKind, Stokes3d};
/// // A unit force along x at the origin, seen from (2, 0, 0): 2 / (8 pi 2).
/// let mut u = [0.0f64; 3];
/// lanes::evaluate_sources_with(SimdLevel::Scalar, &Stokes3d::default(), SourceKind::Charge,
///     EvalMode::Potential, &[0.0; 3], &[1.0, 0.0, 0.0], &[2.0, 0.0, 0.0], &mut u);
/// assert!((u[0] - 1.0 / (8.0 * std::f64::consts::PI)).abs() < 1e-16);
/// ```
///
/// # Panics
/// As [`evaluate_sources`].
#[allow(clippy::too_many_arguments)]
pub fn evaluate_sources_with<K: LaneSources, T: Real>(
    level: SimdLevel,
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &[T],
    densities: &[T],
    targets: &[T],
    out: &mut [T],
) {
    let slices = [sources, densities, targets, &*out];
    let context = || format!("{} P2P", kernel.name());
    crate::direct::assert_evaluation(context, kernel, kind, mode, slices);
    kernel.run_sources(level, kind, mode, sources, densities, targets, out);
}

/// The [`Kernel::evaluate`] and [`Kernel::evaluate_sources`] of a
/// [`LaneSources`] kernel of this crate: the lane engine at
/// [`SimdLevel::active`] ([`evaluate_sources`]), written once.
macro_rules! kernel_entry_points {
    () => {
        /// The lane engine at [`SimdLevel::active`](crate::SimdLevel::active)
        /// ([`lanes::evaluate_sources`](crate::lanes::evaluate_sources)
        /// with charges; [`lanes::evaluate_sources_with`](crate::lanes::evaluate_sources_with)
        /// takes the level).
        ///
        /// # Panics
        /// When lengths are inconsistent or the kernel does not
        /// [support](crate::Kernel::supports) `mode` with charges.
        #[inline]
        fn evaluate<T: crate::Real>(
            &self,
            mode: crate::EvalMode,
            sources: &[T],
            charges: &[T],
            targets: &[T],
            out: &mut [T],
        ) {
            let (kind, q) = (crate::SourceKind::Charge, charges);
            crate::lanes::evaluate_sources(self, kind, mode, sources, q, targets, out);
        }

        /// The lane engine at [`SimdLevel::active`](crate::SimdLevel::active)
        /// ([`lanes::evaluate_sources`](crate::lanes::evaluate_sources)).
        ///
        /// # Panics
        /// When lengths are inconsistent or the kernel does not
        /// [support](crate::Kernel::supports) `(kind, mode)`.
        #[inline]
        fn evaluate_sources<T: crate::Real>(
            &self,
            kind: crate::SourceKind,
            mode: crate::EvalMode,
            sources: &[T],
            densities: &[T],
            targets: &[T],
            out: &mut [T],
        ) {
            crate::lanes::evaluate_sources(self, kind, mode, sources, densities, targets, out);
        }
    };
}
pub(crate) use kernel_entry_points;

/// Panic unless the lengths of `[sources, densities, targets, out]` fit
/// `kernel`'s components, `kind` and `mode`.
fn check<K: Kernel, T: Real>(kernel: &K, kind: SourceKind, mode: EvalMode, slices: [&[T]; 4]) {
    let c = kernel.components();
    if let Err(e) = crate::direct::check_lengths(c, kind, mode, slices) {
        panic!("{} P2P: {e}", kernel.name());
    }
}
