//! The vectorised P2P of the Stokeslet ([`Stokes3d`](crate::Stokes3d)):
//! target lanes as in [`lanes`](crate::lanes).
//!
//! Per pair, with `d = y - x`, `1/r` from [`Simd::rsqrt_or_zero`] (zero for
//! coincident points, which zeroes the pair), `s = 1 / (8 pi mu r)` and
//! `t = (d . f) / r^2`:
//!
//! ```text
//! u_a     += s (f_a + d_a t)
//! d_c u_a += s / r^2 (d_a f_c - f_a d_c - 3 d_a d_c t + delta_ac (d . f))
//! ```

use crate::lanes::{LaneFloat, Simd, SimdTask, run_on_floats};
use crate::{EvalMode, Real, SimdLevel};

/// Largest target block, in targets.
const MAX_BLOCK: usize = 16;
/// Registers per block with one-lane (portable) registers.
const PORTABLE_BLOCK: usize = 16;

/// Accumulate the velocities (and gradients) of point forces at `targets`
/// into `out` (layout of [`Stokes3d`](crate::Stokes3d)), vectorised at
/// `level`, with `scale = 1 / (8 pi mu)`. Lengths are the caller's to check.
pub(crate) fn stokes_p2p_with<T: Real>(
    level: SimdLevel,
    scale: f64,
    mode: EvalMode,
    sources: &[T],
    forces: &[T],
    targets: &[T],
    out: &mut [T],
) {
    if sources.is_empty() || targets.is_empty() {
        return;
    }
    let grad = mode.has_gradient();
    let (s, f, t, o) = (sources, forces, targets, out);
    run_on_floats!(level, (s, f, t, o) => Task::new(scale, grad, s, f, t, o));
}

/// One P2P call as a [`SimdTask`].
struct Task<'a, T> {
    scale: f64,
    grad: bool,
    sources: &'a [T],
    forces: &'a [T],
    targets: &'a [T],
    out: &'a mut [T],
}

impl<'a, T: LaneFloat> Task<'a, T> {
    fn new(
        scale: f64,
        grad: bool,
        sources: &'a [T],
        forces: &'a [T],
        targets: &'a [T],
        out: &'a mut [T],
    ) -> Self {
        Task {
            scale,
            grad,
            sources,
            forces,
            targets,
            out,
        }
    }

    #[inline(always)]
    fn go<S: Simd<T>, const G: bool>(self, s: S) {
        if S::LANES == 1 {
            self.blocks::<S, PORTABLE_BLOCK, G>(s);
        } else {
            self.blocks::<S, 1, G>(s);
        }
    }

    #[inline(always)]
    fn blocks<S: Simd<T>, const C: usize, const G: bool>(self, s: S) {
        let block = C * S::LANES;
        debug_assert!(block <= MAX_BLOCK);
        let w = if G { 12 } else { 3 };
        let scale = s.splat(T::from_f64(self.scale));
        for (tb, ob) in self
            .targets
            .chunks(3 * block)
            .zip(self.out.chunks_mut(w * block))
        {
            block_of::<T, S, C, G>(s, scale, self.sources, self.forces, tb, ob);
        }
    }
}

impl<T: LaneFloat> SimdTask<T> for Task<'_, T> {
    type Output = ();

    #[inline(always)]
    fn run<S: Simd<T>>(self, s: S) {
        if self.grad {
            self.go::<S, true>(s);
        } else {
            self.go::<S, false>(s);
        }
    }
}

/// Up to `C * LANES` targets (`tb`, interleaved) against all sources.
#[inline(always)]
fn block_of<T: LaneFloat, S: Simd<T>, const C: usize, const G: bool>(
    s: S,
    scale: S::V,
    sources: &[T],
    forces: &[T],
    tb: &[T],
    ob: &mut [T],
) {
    let l = S::LANES;
    let w = if G { 12 } else { 3 };
    let mut buf = [[T::ZERO; MAX_BLOCK]; 3];
    for (j, p) in tb.chunks_exact(3).enumerate() {
        buf[0][j] = p[0];
        buf[1][j] = p[1];
        buf[2][j] = p[2];
    }
    let zero = s.splat(T::ZERO);
    let three = s.splat(T::from_f64(3.0));
    let mut tx = [zero; C];
    let mut ty = [zero; C];
    let mut tz = [zero; C];
    for c in 0..C {
        tx[c] = s.load(&buf[0][c * l..]);
        ty[c] = s.load(&buf[1][c * l..]);
        tz[c] = s.load(&buf[2][c * l..]);
    }
    let mut acc = [[zero; C]; 12];
    for (x, f) in sources.chunks_exact(3).zip(forces.chunks_exact(3)) {
        let sx = s.splat(x[0]);
        let sy = s.splat(x[1]);
        let sz = s.splat(x[2]);
        let f = [s.splat(f[0]), s.splat(f[1]), s.splat(f[2])];
        for c in 0..C {
            let d = [s.sub(tx[c], sx), s.sub(ty[c], sy), s.sub(tz[c], sz)];
            let r2 = s.mul_add(d[2], d[2], s.mul_add(d[1], d[1], s.mul(d[0], d[0])));
            let rinv = s.rsqrt_or_zero(r2);
            let rinv2 = s.mul(rinv, rinv);
            let df = s.mul_add(d[2], f[2], s.mul_add(d[1], f[1], s.mul(d[0], f[0])));
            let sc = s.mul(scale, rinv);
            let t = s.mul(df, rinv2);
            for a in 0..3 {
                acc[a][c] = s.mul_add(sc, s.mul_add(d[a], t, f[a]), acc[a][c]);
            }
            if G {
                let s3 = s.mul(sc, rinv2);
                let t3 = s.mul(three, t);
                for k in 0..3 {
                    // d_k u_a, stored at 3 + 3 k + a.
                    let dk3 = s.mul(d[k], t3);
                    for a in 0..3 {
                        let mut v = s.mul(d[a], s.sub(f[k], dk3));
                        v = s.sub(v, s.mul(f[a], d[k]));
                        if a == k {
                            v = s.add(v, df);
                        }
                        acc[3 + 3 * k + a][c] = s.mul_add(s3, v, acc[3 + 3 * k + a][c]);
                    }
                }
            }
        }
    }
    let mut res = [[T::ZERO; MAX_BLOCK]; 12];
    for c in 0..C {
        for v in 0..w {
            s.store(acc[v][c], &mut res[v][c * l..]);
        }
    }
    for (j, o) in ob.chunks_exact_mut(w).enumerate() {
        for (v, r) in o.iter_mut().zip(&res) {
            *v += r[j];
        }
    }
}
