//! The lane engine: the one target-blocking loop of every P2P, its task,
//! and its block sizes (see the [module docs](super) for the design).

use super::{LaneFloat, Simd, SimdTask};
use crate::{Real, SimdLevel};

/// Registers per target block of the SIMD backends while a target has at
/// most [`PairKernel::TWO_REGISTERS_UP_TO`] outputs (one register beyond).
const SIMD_BLOCK: usize = 2;
/// Lanes per target block of the portable backend (one lane per register),
/// unless the kernel asks for [`PairKernel::PORTABLE_LANES`] = 16.
const PORTABLE_BLOCK: usize = 64;
/// Outputs per target up to which a SIMD block's accumulators go to the
/// micro-kernel in place (by register, then output); beyond, and on the
/// portable backend, they are laid out by output, then register, and
/// copied in and out around each call. Measured on AVX2 and AVX-512: in
/// place keeps Helmholtz's eight gradient accumulators in registers
/// (copied, they lived on the stack: 9% slower), while the copies let the
/// register allocator spill the ten or twenty accumulators of a Hessian
/// better (in place, the radial Hessian on AVX2 was 6-9% slower).
const IN_PLACE_UP_TO: usize = 8;
/// Largest block, in targets (`C * LANES`): 2 x 16 `f32` or 64 x 1.
const MAX_BLOCK: usize = 64;

/// A per-pair micro-kernel of the lane engine: the contribution of one
/// source, with `NQ` densities, to `W` outputs of one register of targets.
///
/// The engine calls [`PairKernel::pair`] for every source and every
/// register of a target block, with `d = x - y` (source minus target) per
/// lane, `r2 = |d|^2`, the source's densities broadcast to registers and
/// the block's accumulators. It multiplies the sums by
/// [`PairKernel::lane_scale`] once per target at the end. A kernel picks
/// the shape `(NQ, W)` of a call from its source kind and outputs (its
/// [`LaneSources`](super::LaneSources) impl) and reads `NQ` and `W` in
/// `pair` as compile-time constants, so each shape is its own loop.
///
/// Coincident lanes (`r2 < T::MIN_POSITIVE`) must add exactly zero (see
/// the [module docs](super)). Mark `pair` and `regs` `#[inline(always)]`:
/// they are compiled into each instruction set's loop. Keep closures
/// (`array::map` and the like) out of `pair`: they are not inlined into
/// that loop, and each register operation in one becomes a call (measured:
/// one `.map` made the Helmholtz Hessian micro-kernel 3x slower).
pub trait PairKernel {
    /// Registers a call computes once (splatted constants).
    type Regs<T: LaneFloat, S: Simd<T>>;

    /// Splat the constants of [`PairKernel::Regs`] (once per call, inside
    /// the instruction set's function).
    fn regs<T: LaneFloat, S: Simd<T>>(&self, s: S) -> Self::Regs<T, S>;

    /// Add the contribution of one source with densities `q` (`NQ` values)
    /// to the `W` accumulators `acc` of one register of targets, without
    /// the factor [`PairKernel::lane_scale`].
    #[allow(clippy::too_many_arguments)]
    fn pair<T: LaneFloat, S: Simd<T>, const NQ: usize, const W: usize>(
        &self,
        s: S,
        regs: &Self::Regs<T, S>,
        d: &[S::V; 3],
        r2: S::V,
        q: &[S::V; NQ],
        acc: &mut [S::V; W],
    );

    /// The constant factor applied to every output once per target
    /// (default 1).
    fn lane_scale(&self) -> f64 {
        1.0
    }

    /// Outputs per target up to which a SIMD target block holds two
    /// registers (two independent dependency chains); beyond, one (so that
    /// accumulators and temporaries fit the register file). Default 4.
    const TWO_REGISTERS_UP_TO: usize = 4;

    /// Lanes per target block of the portable backend: 64 (the default)
    /// or 16 (for long micro-kernels, whose temporaries then stay in
    /// cache).
    const PORTABLE_LANES: usize = PORTABLE_BLOCK;
}

/// Accumulate, with the micro-kernel `p`, the field of `sources` with `NQ`
/// `densities` each at `targets` into `out` (`W` values per target), at
/// `level` (lowered to what the CPU supports): the one entry to the loop.
/// Lengths are the caller's to check; mismatched ones only truncate the
/// loops.
pub fn run<P: PairKernel, T: Real, const NQ: usize, const W: usize>(
    level: SimdLevel,
    p: &P,
    sources: &[T],
    densities: &[T],
    targets: &[T],
    out: &mut [T],
) {
    if sources.is_empty() || targets.is_empty() {
        return;
    }
    let (s, q, t, o) = (sources, densities, targets, out);
    super::run_on_floats!(level, (s, q, t, o) => Task::<_, P, NQ, W> {
        p,
        sources: s,
        densities: q,
        targets: t,
        out: o,
    });
}

/// One call of the engine as a [`SimdTask`].
struct Task<'a, T, P, const NQ: usize, const W: usize> {
    p: &'a P,
    sources: &'a [T],
    densities: &'a [T],
    targets: &'a [T],
    out: &'a mut [T],
}

impl<T: LaneFloat, P: PairKernel, const NQ: usize, const W: usize> SimdTask<T>
    for Task<'_, T, P, NQ, W>
{
    type Output = ();

    #[inline(always)]
    fn run<S: Simd<T>>(self, s: S) {
        if S::LANES > 1 && W <= P::TWO_REGISTERS_UP_TO {
            self.blocks::<S, SIMD_BLOCK>(s);
        } else if S::LANES > 1 {
            self.blocks::<S, 1>(s);
        } else if P::PORTABLE_LANES == 16 {
            self.blocks::<S, 16>(s);
        } else {
            self.blocks::<S, PORTABLE_BLOCK>(s);
        }
    }
}

impl<T: LaneFloat, P: PairKernel, const NQ: usize, const W: usize> Task<'_, T, P, NQ, W> {
    /// All targets, `C` registers at a time.
    #[inline(always)]
    fn blocks<S: Simd<T>, const C: usize>(self, s: S) {
        let (p, regs) = (self.p, self.p.regs::<T, S>(s));
        let (x, q) = (self.sources, self.densities);
        let block = C * S::LANES;
        debug_assert!(block <= MAX_BLOCK);
        for (tb, ob) in self
            .targets
            .chunks(3 * block)
            .zip(self.out.chunks_mut(W * block))
        {
            if C > 1 && tb.len() <= 3 * S::LANES {
                // One register suffices for the last few targets.
                block_of::<T, S, P, 1, NQ, W>(s, p, &regs, x, q, tb, ob);
            } else {
                block_of::<T, S, P, C, NQ, W>(s, p, &regs, x, q, tb, ob);
            }
        }
    }
}

/// Up to `C * LANES` targets (`tb`, interleaved) against all sources.
#[inline(always)]
fn block_of<
    T: LaneFloat,
    S: Simd<T>,
    P: PairKernel,
    const C: usize,
    const NQ: usize,
    const W: usize,
>(
    s: S,
    p: &P,
    regs: &P::Regs<T, S>,
    sources: &[T],
    densities: &[T],
    tb: &[T],
    ob: &mut [T],
) {
    let l = S::LANES;
    // De-interleave the block's targets, zero-padded.
    let mut buf = [[T::ZERO; MAX_BLOCK]; 3];
    for (k, y) in tb.chunks_exact(3).enumerate() {
        buf[0][k] = y[0];
        buf[1][k] = y[1];
        buf[2][k] = y[2];
    }
    let zero = s.splat(T::ZERO);
    let mut ty = [[zero; C]; 3];
    for c in 0..C {
        for (a, row) in ty.iter_mut().enumerate() {
            row[c] = s.load(&buf[a][c * l..]);
        }
    }
    let mut res = [[T::ZERO; MAX_BLOCK]; W];
    if S::LANES > 1 && W <= IN_PLACE_UP_TO {
        // Accumulators by register, then output: each register's `W`
        // accumulators go to the micro-kernel in place, with no copy.
        let mut acc = [[zero; W]; C];
        for (x, q) in sources.chunks_exact(3).zip(densities.chunks_exact(NQ)) {
            let (sx, vq) = broadcast::<T, S, NQ>(s, x, q);
            for (c, a) in acc.iter_mut().enumerate() {
                let (d, r2) = separation(s, &sx, &ty, c);
                p.pair::<T, S, NQ, W>(s, regs, &d, r2, &vq, a);
            }
        }
        let scale = s.splat(T::from_f64(p.lane_scale()));
        for (c, a) in acc.iter().enumerate() {
            for (v, out) in a.iter().zip(res.iter_mut()) {
                s.store(s.mul(*v, scale), &mut out[c * l..]);
            }
        }
    } else {
        // Accumulators by output, then register: with one lane per
        // register (portable) the loop over registers is unit-stride, which
        // the compiler vectorises. The source's broadcasts and separation
        // are written out here: through `broadcast` and `separation` the
        // portable dipole Hessian and Stokes gradient ran 4-8% slower.
        let mut acc = [[zero; C]; W];
        for (x, q) in sources.chunks_exact(3).zip(densities.chunks_exact(NQ)) {
            let sx = [s.splat(x[0]), s.splat(x[1]), s.splat(x[2])];
            let mut vq = [zero; NQ];
            for (v, &q) in vq.iter_mut().zip(q) {
                *v = s.splat(q);
            }
            for c in 0..C {
                let d = [
                    s.sub(sx[0], ty[0][c]),
                    s.sub(sx[1], ty[1][c]),
                    s.sub(sx[2], ty[2][c]),
                ];
                let r2 = s.mul_add(d[2], d[2], s.mul_add(d[1], d[1], s.mul(d[0], d[0])));
                let mut a = [zero; W];
                for (v, row) in a.iter_mut().zip(&acc) {
                    *v = row[c];
                }
                p.pair::<T, S, NQ, W>(s, regs, &d, r2, &vq, &mut a);
                for (v, row) in a.into_iter().zip(acc.iter_mut()) {
                    row[c] = v;
                }
            }
        }
        let scale = s.splat(T::from_f64(p.lane_scale()));
        for c in 0..C {
            for (row, out) in acc.iter().zip(res.iter_mut()) {
                s.store(s.mul(row[c], scale), &mut out[c * l..]);
            }
        }
    }
    for (j, o) in ob.chunks_exact_mut(W).enumerate() {
        for (v, r) in o.iter_mut().zip(&res) {
            *v += r[j];
        }
    }
}

/// One source's coordinates `x` and densities `q`, each broadcast to a
/// register.
#[inline(always)]
fn broadcast<T: LaneFloat, S: Simd<T>, const NQ: usize>(
    s: S,
    x: &[T],
    q: &[T],
) -> ([S::V; 3], [S::V; NQ]) {
    let sx = [s.splat(x[0]), s.splat(x[1]), s.splat(x[2])];
    let mut vq = [s.splat(T::ZERO); NQ];
    for (v, &q) in vq.iter_mut().zip(q) {
        *v = s.splat(q);
    }
    (sx, vq)
}

/// `d = x - y` (source minus target) and `r2 = |d|^2` for register `c` of
/// a block whose de-interleaved target coordinates are `ty`.
#[inline(always)]
fn separation<T: LaneFloat, S: Simd<T>, const C: usize>(
    s: S,
    sx: &[S::V; 3],
    ty: &[[S::V; C]; 3],
    c: usize,
) -> ([S::V; 3], S::V) {
    let d = [
        s.sub(sx[0], ty[0][c]),
        s.sub(sx[1], ty[1][c]),
        s.sub(sx[2], ty[2][c]),
    ];
    let r2 = s.mul_add(d[2], d[2], s.mul_add(d[1], d[1], s.mul(d[0], d[0])));
    (d, r2)
}
