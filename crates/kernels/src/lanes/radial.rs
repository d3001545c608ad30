//! Dipole sources and Hessians for **radial** kernels `K(x, y) = k(|x - y|)`,
//! composed in one vectorised loop from the kernel's radial derivatives.
//!
//! # The maths
//! Write `d = x - y` (source minus target), `r = |d|`, and define the
//! radial derivatives
//!
//! ```text
//! f_0 = k(r),    f_{m+1} = (1/r) d f_m / dr     (m = 0, 1, 2)
//! ```
//!
//! (Laplace `k = 1/r`: `f_1 = -1/r^3`, `f_2 = 3/r^5`, `f_3 = -15/r^7`).
//! Since `d r / d y_a = -d_a / r` and `d d_a / d y_b = -delta_ab`, every
//! output of every source type follows from `f_0 .. f_3` and `d`
//! (`a, b, c` index coordinates, repeated indices are not summed):
//!
//! ```text
//! charge q:      u = q f_0
//!                d_{y_a} u = -q f_1 d_a
//!                d_{y_a} d_{y_b} u = q (f_2 d_a d_b + f_1 delta_ab)
//! dipole n:      u = n . grad_x k = f_1 p,          p = n . d
//!                d_{y_a} u = -(f_2 p d_a + f_1 n_a)
//!                d_{y_a} d_{y_b} u = f_3 p d_a d_b + f_2 (n_a d_b + n_b d_a + p delta_ab)
//! ```
//!
//! A kernel supplies only `f_0 .. f_M` on registers
//! ([`RadialLaneKernel::radial`]); `M` is the highest one a call needs
//! (0 for charge potentials, up to 3 for dipole Hessians), so a call pays
//! only for what it outputs. The Hessian is stored as
//! `[H11, H22, H33, H12, H13, H23]` after the potential and gradient.
//!
//! # The loop
//! The lane engine's ([`PairKernel`]): each shape `(kind, mode)` is one
//! instance of it, with `NQ = 1, 3, 4` densities per source and `W = 1, 4,
//! 10` outputs per target. With ten outputs one register per block is kept
//! (the engine's default [`PairKernel::TWO_REGISTERS_UP_TO`]), so that
//! accumulators and temporaries nearly fit the 16 AVX2 registers (measured
//! with two: charge Hessians 17% slower for Laplace, 7% for modified
//! Helmholtz, dipole Hessians 8% faster and 4% slower); with one or four
//! outputs, two. Charges with gradients take the kernel's own
//! [`LaneKernel::pair`] instead (the tuned micro-kernel of
//! [`evaluate_with`](super::evaluate_with)); charges with potentials stay
//! here, with `M = 0` (measured against `LaneKernel::pair`: modified
//! Helmholtz 7% faster with AVX-512, Laplace the same; composed gradients
//! were 7% slower for both).

use super::{Charges, LaneFloat, LaneKernel, LaneSources, PairKernel, Simd, run};
use crate::{EvalMode, Real, SimdLevel, SourceKind};

/// A radial kernel `K(x, y) = s_K k(|x - y|)` whose dipole sources and
/// Hessians run in the vectorised loop of this module (see the
/// [module docs](self) for the maths).
///
/// ```
/// use ferrofmm_kernels::lanes;
/// use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d, SourceKind, SimdLevel};
///
/// // A dipole n = (0, 0, 1) at the origin, seen from (0, 0, 2): for
/// // K = 1/(4 pi r), u = n . grad_x K = n . (y - x) / (4 pi r^3) = 1/(16 pi).
/// let mut u = [0.0f64];
/// lanes::evaluate_sources_with(SimdLevel::detected(), &Laplace3d, SourceKind::Dipole,
///     EvalMode::Potential, &[0.0; 3], &[0.0, 0.0, 1.0], &[0.0, 0.0, 2.0], &mut u);
/// assert!((u[0] - 1.0 / (16.0 * std::f64::consts::PI)).abs() < 1e-16);
/// ```
pub trait RadialLaneKernel: LaneKernel {
    /// `[f_0, .., f_M, ..]` at `r2 = r^2` per lane, without the factor
    /// [`LaneKernel::lane_scale`]: `f_0 = k(r)`, `f_{m+1} = (1/r) d f_m/dr`,
    /// for `M <= 3` (entries past `M` are not read). Coincident lanes
    /// (`r2 < T::MIN_POSITIVE`) must hold exactly zero in every entry read.
    /// Mark it `#[inline(always)]`.
    fn radial<T: LaneFloat, S: Simd<T>, const M: usize>(&self, s: S, r2: S::V) -> [S::V; 4];
}

/// Every radial kernel runs every source kind and output in the engine:
/// charges with potentials or gradients through [`LaneKernel::pair`], the
/// rest composed from [`RadialLaneKernel::radial`].
impl<K: RadialLaneKernel> LaneSources for K {
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
        let (s, q, t, o) = (sources, densities, targets, out);
        match (kind, mode) {
            (SourceKind::Charge, EvalMode::PotentialGradient) => {
                run::<_, _, 1, 4>(level, &Charges(self), s, q, t, o)
            }
            _ => composed(level, self, kind, mode, s, q, t, o),
        }
    }
}

/// The composed loop of this module for every `(kind, mode)`, charges with
/// potentials included (tests compare it with [`LaneKernel::pair`]).
///
/// # Panics
/// As [`evaluate_sources`](super::evaluate_sources).
#[doc(hidden)]
#[allow(clippy::too_many_arguments)]
pub fn composed_with<K: RadialLaneKernel, T: Real>(
    level: SimdLevel,
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &[T],
    densities: &[T],
    targets: &[T],
    out: &mut [T],
) {
    super::check(kernel, kind, mode, [sources, densities, targets, out]);
    composed(level, kernel, kind, mode, sources, densities, targets, out);
}

/// The composed micro-kernel with radial derivatives up to `M`.
struct Composed<'a, K, const M: usize>(&'a K);

/// The engine's shape for `(kind, mode)`: `NQ` densities per source, `W`
/// outputs per target, radial derivatives up to `M`.
#[allow(clippy::too_many_arguments)]
fn composed<K: RadialLaneKernel, T: Real>(
    level: SimdLevel,
    k: &K,
    kind: SourceKind,
    mode: EvalMode,
    s: &[T],
    q: &[T],
    t: &[T],
    o: &mut [T],
) {
    use EvalMode::{Potential as P, PotentialGradient as G, PotentialGradientHessian as H};
    use SourceKind::{Charge, ChargeDipole, Dipole};
    match (kind, mode) {
        (Charge, P) => run::<_, _, 1, 1>(level, &Composed::<K, 0>(k), s, q, t, o),
        (Charge, G) => run::<_, _, 1, 4>(level, &Composed::<K, 1>(k), s, q, t, o),
        (Charge, H) => run::<_, _, 1, 10>(level, &Composed::<K, 2>(k), s, q, t, o),
        (Dipole, P) => run::<_, _, 3, 1>(level, &Composed::<K, 1>(k), s, q, t, o),
        (Dipole, G) => run::<_, _, 3, 4>(level, &Composed::<K, 2>(k), s, q, t, o),
        (Dipole, H) => run::<_, _, 3, 10>(level, &Composed::<K, 3>(k), s, q, t, o),
        (ChargeDipole, P) => run::<_, _, 4, 1>(level, &Composed::<K, 1>(k), s, q, t, o),
        (ChargeDipole, G) => run::<_, _, 4, 4>(level, &Composed::<K, 2>(k), s, q, t, o),
        (ChargeDipole, H) => run::<_, _, 4, 10>(level, &Composed::<K, 3>(k), s, q, t, o),
    }
}

impl<K: RadialLaneKernel, const M: usize> PairKernel for Composed<'_, K, M> {
    type Regs<T: LaneFloat, S: Simd<T>> = ();

    #[inline(always)]
    fn regs<T: LaneFloat, S: Simd<T>>(&self, _s: S) {}

    /// `f_0 .. f_M` from the kernel, then the formulas of the
    /// [module docs](self) for `NQ` densities and `W` outputs.
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
        let f = self.0.radial::<T, S, M>(s, r2);
        add_source::<T, S, NQ, W>(s, &f, d, q, acc);
    }

    fn lane_scale(&self) -> f64 {
        self.0.lane_scale()
    }

    /// 16 lanes for dipole Hessians (`M = 3`, the longest micro-kernel),
    /// else 64; measured on the portable backend: 64 lanes left the `f64`
    /// dipole Hessian 7% slower than 16.
    const PORTABLE_LANES: usize = if M == 3 { 16 } else { 64 };
}

/// Add one source's contribution (see the [module docs](self)) to the
/// `W` accumulators of one register of targets.
#[inline(always)]
fn add_source<T: LaneFloat, S: Simd<T>, const NQ: usize, const W: usize>(
    s: S,
    f: &[S::V; 4],
    d: &[S::V; 3],
    q: &[S::V; NQ],
    a: &mut [S::V; W],
) {
    let has_charge = NQ != 3;
    let has_dipole = NQ >= 3;
    if has_charge {
        a[0] = s.mul_add(q[0], f[0], a[0]);
        if W >= 4 {
            // -q f_1 d_a (the negation is shared by the block's registers)
            let neg_q = s.sub(s.splat(T::ZERO), q[0]);
            let g = s.mul(neg_q, f[1]);
            for k in 0..3 {
                a[1 + k] = s.mul_add(g, d[k], a[1 + k]);
            }
        }
        if W == 10 {
            // q (f_2 d_a d_b + f_1 delta_ab)
            let h2 = s.mul(q[0], f[2]);
            let h1 = s.mul(q[0], f[1]);
            let hd = [s.mul(h2, d[0]), s.mul(h2, d[1]), s.mul(h2, d[2])];
            for k in 0..3 {
                a[4 + k] = s.mul_add(hd[k], d[k], s.add(a[4 + k], h1));
            }
            a[7] = s.mul_add(hd[0], d[1], a[7]);
            a[8] = s.mul_add(hd[0], d[2], a[8]);
            a[9] = s.mul_add(hd[1], d[2], a[9]);
        }
    }
    if has_dipole {
        let n = &q[NQ - 3..];
        let p = s.mul_add(n[2], d[2], s.mul_add(n[1], d[1], s.mul(n[0], d[0])));
        a[0] = s.mul_add(f[1], p, a[0]);
        if W >= 4 {
            // -(f_2 p d_a + f_1 n_a)
            let u = s.mul(f[2], p);
            for k in 0..3 {
                a[1 + k] = s.sub(a[1 + k], s.mul_add(u, d[k], s.mul(f[1], n[k])));
            }
        }
        if W == 10 {
            // f_3 p d_a d_b + f_2 (n_a d_b + n_b d_a + p delta_ab)
            let v = s.mul(f[3], p);
            let vd = [s.mul(v, d[0]), s.mul(v, d[1]), s.mul(v, d[2])];
            let f2 = f[2];
            for k in 0..3 {
                let nd = s.mul(n[k], d[k]);
                let sym = s.add(s.add(nd, nd), p);
                a[4 + k] = s.mul_add(vd[k], d[k], s.mul_add(f2, sym, a[4 + k]));
            }
            for (slot, (i, j)) in [(7, (0, 1)), (8, (0, 2)), (9, (1, 2))] {
                let sym = s.mul_add(n[i], d[j], s.mul(n[j], d[i]));
                a[slot] = s.mul_add(vd[i], d[j], s.mul_add(f2, sym, a[slot]));
            }
        }
    }
}
