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
//! As in [`crate::lanes`]: blocks of target registers de-interleaved once,
//! accumulators in registers, sources streamed in storage order (each
//! source's 3 coordinates and 1, 3 or 4 densities broadcast once per block).
//! With ten outputs per target one register per block is kept (`C = 1`),
//! so that accumulators and temporaries nearly fit the 16 AVX2 registers
//! (measured with two: charge Hessians 17% slower for Laplace, 7% for
//! modified Helmholtz, dipole Hessians 8% faster and 4% slower); with one
//! or four outputs, two. Charges with potentials or gradients take the kernel's
//! own [`LaneKernel::pair`] instead (the tuned path of [`evaluate_with`]).

use super::{
    LaneFloat, LaneKernel, MAX_BLOCK, PORTABLE_BLOCK, SIMD_BLOCK, Simd, SimdTask, evaluate_with,
};
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

/// Accumulate the field of sources of `kind` (densities interleaved,
/// [`SourceKind::values_per_source`] per source) at `targets`, outputs of
/// `mode`, into `out`, at [`SimdLevel::active`]. See the
/// [module docs](self) for the maths.
///
/// # Panics
/// When a coordinate slice's length is not a multiple of 3, or `densities`
/// / `out` do not match the number of sources / targets.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn evaluate_sources<K: RadialLaneKernel, T: Real>(
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &[T],
    densities: &[T],
    targets: &[T],
    out: &mut [T],
) {
    evaluate_sources_with(
        SimdLevel::active(),
        kernel,
        kind,
        mode,
        sources,
        densities,
        targets,
        out,
    );
}

/// [`evaluate_sources`] at a given instruction-set `level` (lowered to
/// what the CPU supports, so any value is safe).
///
/// # Panics
/// As [`evaluate_sources`].
#[allow(clippy::too_many_arguments)]
pub fn evaluate_sources_with<K: RadialLaneKernel, T: Real>(
    level: SimdLevel,
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &[T],
    densities: &[T],
    targets: &[T],
    out: &mut [T],
) {
    if kind == SourceKind::Charge && !mode.has_hessian() {
        evaluate_with(level, kernel, mode, sources, densities, targets, out);
        return;
    }
    composed_with(level, kernel, kind, mode, sources, densities, targets, out);
}

/// The composed loop of this module for every `(kind, mode)`, charges with
/// potentials included (tests compare it with [`LaneKernel::pair`]).
///
/// # Panics
/// As [`evaluate_sources`].
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
    if let Err(e) = crate::direct::check_lengths(1, kind, mode, sources, densities, targets, out) {
        panic!("{} P2P: {e}", kernel.name());
    }
    if sources.is_empty() || targets.is_empty() {
        return;
    }
    let (s, q, t, o) = (sources, densities, targets, out);
    super::run_on_floats!(level, (s, q, t, o) => Composed::new(kernel, kind, mode, s, q, t, o));
}

/// One composed P2P call as a [`SimdTask`].
struct Composed<'a, T, K> {
    kernel: &'a K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &'a [T],
    densities: &'a [T],
    targets: &'a [T],
    out: &'a mut [T],
}

impl<'a, T: LaneFloat, K: RadialLaneKernel> Composed<'a, T, K> {
    #[allow(clippy::too_many_arguments)]
    fn new(
        kernel: &'a K,
        kind: SourceKind,
        mode: EvalMode,
        sources: &'a [T],
        densities: &'a [T],
        targets: &'a [T],
        out: &'a mut [T],
    ) -> Self {
        Composed {
            kernel,
            kind,
            mode,
            sources,
            densities,
            targets,
            out,
        }
    }

    /// All targets with `NQ` densities per source, `W` outputs per target
    /// and radial derivatives up to `M`.
    #[inline(always)]
    fn go<S: Simd<T>, const NQ: usize, const W: usize, const M: usize>(self, s: S) {
        if S::LANES == 1 {
            self.blocks::<S, PORTABLE_BLOCK, NQ, W, M>(s);
        } else if W <= 4 {
            self.blocks::<S, SIMD_BLOCK, NQ, W, M>(s);
        } else {
            self.blocks::<S, 1, NQ, W, M>(s);
        }
    }

    #[inline(always)]
    fn blocks<S: Simd<T>, const C: usize, const NQ: usize, const W: usize, const M: usize>(
        self,
        s: S,
    ) {
        let block = C * S::LANES;
        debug_assert!(block <= MAX_BLOCK);
        for (tb, ob) in self
            .targets
            .chunks(3 * block)
            .zip(self.out.chunks_mut(W * block))
        {
            block_of::<T, S, K, C, NQ, W, M>(s, self.kernel, self.sources, self.densities, tb, ob);
        }
    }
}

impl<T: LaneFloat, K: RadialLaneKernel> SimdTask<T> for Composed<'_, T, K> {
    type Output = ();

    #[inline(always)]
    fn run<S: Simd<T>>(self, s: S) {
        use EvalMode::{Potential as P, PotentialGradient as G, PotentialGradientHessian as H};
        use SourceKind::{Charge, ChargeDipole, Dipole};
        match (self.kind, self.mode) {
            (Charge, P) => self.go::<S, 1, 1, 0>(s),
            (Charge, G) => self.go::<S, 1, 4, 1>(s),
            (Charge, H) => self.go::<S, 1, 10, 2>(s),
            (Dipole, P) => self.go::<S, 3, 1, 1>(s),
            (Dipole, G) => self.go::<S, 3, 4, 2>(s),
            (Dipole, H) => self.go::<S, 3, 10, 3>(s),
            (ChargeDipole, P) => self.go::<S, 4, 1, 1>(s),
            (ChargeDipole, G) => self.go::<S, 4, 4, 2>(s),
            (ChargeDipole, H) => self.go::<S, 4, 10, 3>(s),
        }
    }
}

/// Up to `C * LANES` targets (`tb`, interleaved) against all sources.
///
/// The target de-interleave and the scaled write-back repeat those of the
/// tuned loop (`lanes::block_of`) on purpose: moving them into shared
/// helpers measured 8-20% slower P2P (f32 gradients, charge Hessians).
#[inline(always)]
fn block_of<
    T: LaneFloat,
    S: Simd<T>,
    K: RadialLaneKernel,
    const C: usize,
    const NQ: usize,
    const W: usize,
    const M: usize,
>(
    s: S,
    kernel: &K,
    sources: &[T],
    densities: &[T],
    tb: &[T],
    ob: &mut [T],
) {
    let l = S::LANES;
    let mut buf = [[T::ZERO; MAX_BLOCK]; 3];
    for (k, p) in tb.chunks_exact(3).enumerate() {
        buf[0][k] = p[0];
        buf[1][k] = p[1];
        buf[2][k] = p[2];
    }
    let zero = s.splat(T::ZERO);
    let mut ty = [[zero; C]; 3];
    for c in 0..C {
        for (a, row) in ty.iter_mut().enumerate() {
            row[c] = s.load(&buf[a][c * l..]);
        }
    }
    let mut acc = [[zero; C]; W];
    for (x, q) in sources.chunks_exact(3).zip(densities.chunks_exact(NQ)) {
        let sx = [s.splat(x[0]), s.splat(x[1]), s.splat(x[2])];
        let dens = Densities::<S::V>::broadcast::<T, S, NQ>(s, q);
        for c in 0..C {
            let d = [
                s.sub(sx[0], ty[0][c]),
                s.sub(sx[1], ty[1][c]),
                s.sub(sx[2], ty[2][c]),
            ];
            let r2 = s.mul_add(d[2], d[2], s.mul_add(d[1], d[1], s.mul(d[0], d[0])));
            let f = kernel.radial::<T, S, M>(s, r2);
            let mut a = [zero; W];
            for (v, row) in a.iter_mut().zip(&acc) {
                *v = row[c];
            }
            add_source::<T, S, NQ, W>(s, &f, &d, &dens, &mut a);
            for (v, row) in a.into_iter().zip(acc.iter_mut()) {
                row[c] = v;
            }
        }
    }
    let scale = s.splat(T::from_f64(kernel.lane_scale()));
    let mut res = [[T::ZERO; MAX_BLOCK]; W];
    for c in 0..C {
        for (row, out) in acc.iter().zip(res.iter_mut()) {
            s.store(s.mul(row[c], scale), &mut out[c * l..]);
        }
    }
    for (j, o) in ob.chunks_exact_mut(W).enumerate() {
        for (v, r) in o.iter_mut().zip(&res) {
            *v += r[j];
        }
    }
}

/// One source's densities broadcast to registers: `-q` (the charge,
/// negated for the fused gradient step) and the dipole vector `n`.
struct Densities<V> {
    q: V,
    neg_q: V,
    n: [V; 3],
}

impl<V: Copy> Densities<V> {
    #[inline(always)]
    fn broadcast<T: LaneFloat, S: Simd<T, V = V>, const NQ: usize>(s: S, q: &[T]) -> Self {
        let zero = s.splat(T::ZERO);
        let (charge, n) = match NQ {
            1 => (q[0], None),
            3 => (T::ZERO, Some(&q[..3])),
            _ => (q[0], Some(&q[1..4])),
        };
        Densities {
            q: s.splat(charge),
            neg_q: s.splat(-charge),
            n: n.map_or([zero; 3], |n| [s.splat(n[0]), s.splat(n[1]), s.splat(n[2])]),
        }
    }
}

/// Add one source's contribution (see the [module docs](self)) to the
/// `W` accumulators of one register of targets.
#[inline(always)]
fn add_source<T: LaneFloat, S: Simd<T>, const NQ: usize, const W: usize>(
    s: S,
    f: &[S::V; 4],
    d: &[S::V; 3],
    dens: &Densities<S::V>,
    a: &mut [S::V; W],
) {
    let has_charge = NQ != 3;
    let has_dipole = NQ >= 3;
    if has_charge {
        a[0] = s.mul_add(dens.q, f[0], a[0]);
        if W >= 4 {
            // -q f_1 d_a
            let g = s.mul(dens.neg_q, f[1]);
            for k in 0..3 {
                a[1 + k] = s.mul_add(g, d[k], a[1 + k]);
            }
        }
        if W == 10 {
            // q (f_2 d_a d_b + f_1 delta_ab)
            let h2 = s.mul(dens.q, f[2]);
            let h1 = s.mul(dens.q, f[1]);
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
        let n = &dens.n;
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
