//! A kernel written outside the crate runs in the vectorised loop
//! (`ferrofmm_kernels::lanes`) at every instruction set and agrees with its
//! own pairwise definition.

use crate::common;

use common::{abs_sums, levels, random_points, scaled_error, tolerance};
use ferrofmm_kernels::lanes::{self, LaneFloat, LaneKernel, Simd};
use ferrofmm_kernels::{EvalMode, Kernel, Real, reference};

/// A non-radial kernel: `K(x, y) = (1 + a . (y - x) / r) / r`, with its
/// gradient with respect to `y`, `(a - 2 (a.u) u) / r^2 - u / r^2` where
/// `u = (y - x) / r`; `d = x - y` in the micro-kernel.
#[derive(Clone, Copy)]
struct Tilted {
    a: [f64; 3],
}

impl LaneKernel for Tilted {
    #[inline(always)]
    fn pair<T: LaneFloat, S: Simd<T>, const GRAD: bool>(
        &self,
        s: S,
        d: [S::V; 3],
        r2: S::V,
        q: S::V,
        acc: &mut [S::V; 4],
    ) {
        let a = self.a.map(|v| s.splat(T::from_f64(v)));
        let rinv = s.rsqrt_or_zero(r2);
        // a . (y - x) / r = -(a . d) rinv
        let ad = s.mul_add(a[2], d[2], s.mul_add(a[1], d[1], s.mul(a[0], d[0])));
        let au = s.sub(s.splat(T::ZERO), s.mul(ad, rinv));
        let qr = s.mul(q, rinv);
        acc[0] = s.mul_add(qr, s.add(s.splat(T::ONE), au), acc[0]);
        if GRAD {
            let qr2 = s.mul(qr, rinv);
            for k in 0..3 {
                // u_k = -d_k rinv
                let u = s.sub(s.splat(T::ZERO), s.mul(d[k], rinv));
                let two_au_plus_1 = s.add(s.add(au, au), s.splat(T::ONE));
                let g = s.sub(a[k], s.mul(two_au_plus_1, u));
                acc[k + 1] = s.mul_add(qr2, g, acc[k + 1]);
            }
        }
    }
}

impl Kernel for Tilted {
    fn name(&self) -> String {
        "tilted".into()
    }
    fn parameters(&self) -> Vec<f64> {
        self.a.to_vec()
    }
    fn homogeneity(&self) -> Option<f64> {
        Some(-1.0)
    }
    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let au = (0..3).fold(T::ZERO, |s, k| s + T::from_f64(self.a[k]) * d[k]) / r;
        (T::ONE + au) / r
    }
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let u = [d[0] / r, d[1] / r, d[2] / r];
        let au = (0..3).fold(T::ZERO, |s, k| s + T::from_f64(self.a[k]) * u[k]);
        let two = T::from_f64(2.0);
        std::array::from_fn(|k| (T::from_f64(self.a[k]) - (two * au + T::ONE) * u[k]) / (r * r))
    }
    fn evaluate<T: Real>(&self, mode: EvalMode, s: &[T], q: &[T], t: &[T], out: &mut [T]) {
        lanes::evaluate(self, mode, s, q, t, out);
    }
}

fn check<T: Real>(n: usize, nt: usize) {
    let kernel = Tilted {
        a: [0.3, -0.2, 0.5],
    };
    let (s, q) = random_points::<T>(5, n);
    let (mut t, _) = random_points::<T>(6, nt);
    // Some coincident pairs: they must contribute exactly zero.
    let c = n.min(nt).min(3);
    t[..3 * c].copy_from_slice(&s[..3 * c]);
    let scales = abs_sums(&kernel, &s, &q, &t);
    let tol = 4.0 * tolerance::<T>(n);
    for mode in [EvalMode::Potential, EvalMode::PotentialGradient] {
        let mut expected = vec![T::ZERO; mode.values_per_target() * nt];
        reference::evaluate_pairwise(&kernel, mode, &s, &q, &t, &mut expected);
        for level in levels() {
            // Accumulates: start from ones.
            let mut out = vec![T::ONE; expected.len()];
            lanes::evaluate_with(level, &kernel, mode, &s, &q, &t, &mut out);
            let out: Vec<T> = out.into_iter().map(|v| v - T::ONE).collect();
            let err = scaled_error(mode, &out, &expected, &scales);
            assert!(
                err <= tol,
                "{level} {:?} {mode:?} n={n} nt={nt}: {err:e} > {tol:e}",
                T::PRECISION
            );
        }
    }
}

#[test]
fn user_kernel_matches_its_definition_at_every_level() {
    // Target counts around every block size (1, 4, 8, 16, 32, 64 lanes).
    for nt in [1, 3, 4, 5, 8, 9, 16, 17, 31, 33, 63, 64, 65, 130] {
        check::<f64>(37, nt);
        check::<f32>(37, nt);
    }
    check::<f64>(500, 200);
    check::<f32>(500, 200);
}

#[test]
#[should_panic(expected = "tilted P2P: output has 2 values, expected 1")]
fn lengths_are_checked() {
    let k = Tilted { a: [0.0; 3] };
    let mut out = [0.0f64; 2];
    lanes::evaluate(
        &k,
        EvalMode::Potential,
        &[0.0; 3],
        &[1.0],
        &[1.0; 3],
        &mut out,
    );
}
