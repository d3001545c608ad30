//! A kernel defined outside ferrofmm, through the whole FMM: a softened
//! (Plummer) Laplace kernel
//!
//! ```text
//! K_a(x, y) = 1 / (4 pi sqrt(|x - y|^2 + a^2))
//! ```
//!
//! as used in gravitational N-body codes to remove the close-encounter
//! singularity. What it takes:
//!
//! * [`Kernel`]: the values and gradients the operators are built from; the
//!   kernel is not scale invariant (`a` fixes a length), so `homogeneity`
//!   is `None` and the FMM builds its operators per level;
//! * [`LaneKernel::pair`]: the per-pair micro-kernel on SIMD registers, so
//!   that the near field (P2P) runs in the crate's vectorised loop (AVX-512,
//!   AVX2 or portable, picked at run time) instead of the scalar pairwise
//!   default; `Kernel::evaluate` calls [`lanes::evaluate`].
//!
//! `run` builds the FMM with each M2L scheme (SVD, dense, FFT), checks it
//! against direct summation (potential and gradient, zero-mean charges) and
//! measures the P2P rate of the kernel next to Laplace's and next to the
//! scalar pairwise loop.
//!
//! A caveat that holds for any such kernel: KIFMM represents far fields by
//! equivalent densities, which is exact for fundamental solutions of
//! elliptic PDEs (Laplace, Yukawa, Stokes). The softened kernel is not one:
//! its far field differs from Laplace's by about `(a / r)^2`, which the
//! densities fit only approximately, so the error levels off as the order
//! rises, the more so in deeper trees (boxes of width `h` see `(a / h)^2`).
//! Measured on 4,000 uniform points, leaf 64 (depth 3), dense M2L: at order
//! 7, `a = 1e-4` gives Laplace's error (1.1e-7) and `a = 1e-3` 7e-6; at
//! order 9, 1.0e-8 and 1.6e-5 (Laplace 2.1e-9). The example uses
//! `a = 1e-4` and checks each scheme against Laplace's error with the same
//! scheme and tree.
//!
//! Run with `cargo run --release --example custom_kernel [N]`.

use std::time::Instant;

use ferrofmm::field::{FftConfig, FftM2l};
use ferrofmm::fmm::{FmmBuilder, relative_errors, sample_indices};
use ferrofmm::kernels::lanes::{self, LaneFloat, LaneKernel, Simd};
use ferrofmm::kernels::{EvalMode, INV_4PI, Kernel, Laplace3d, Real, reference};

/// Plummer-softened Laplace kernel with softening length `a`.
#[derive(Clone, Debug)]
pub struct SoftenedLaplace {
    /// Softening length.
    pub a: f64,
}

impl LaneKernel for SoftenedLaplace {
    /// With `rho^2 = r^2 + a^2`: `q / rho` into the potential and
    /// `q / rho^3 (x - y)` into the gradient (`d = x - y`; the factor
    /// `1 / (4 pi)` is `lane_scale`). Coincident points contribute nothing,
    /// by the library's convention.
    #[inline(always)]
    fn pair<T: LaneFloat, S: Simd<T>, const GRAD: bool>(
        &self,
        s: S,
        d: [S::V; 3],
        r2: S::V,
        q: S::V,
        acc: &mut [S::V; 4],
    ) {
        let a2 = s.splat(T::from_f64(self.a * self.a));
        let rho_inv = s.rsqrt_or_zero(s.add(r2, a2));
        let rho_inv = s.zero_unless_ge(rho_inv, r2, s.splat(T::MIN_POSITIVE));
        let qr = s.mul(q, rho_inv);
        acc[0] = s.add(acc[0], qr);
        if GRAD {
            let qr3 = s.mul(qr, s.mul(rho_inv, rho_inv));
            lanes::add_radial_gradient(s, qr3, &d, acc);
        }
    }

    fn lane_scale(&self) -> f64 {
        INV_4PI
    }
}

impl Kernel for SoftenedLaplace {
    fn name(&self) -> String {
        "softened_laplace3d".to_string()
    }

    fn parameters(&self) -> Vec<f64> {
        vec![self.a]
    }

    fn homogeneity(&self) -> Option<f64> {
        None
    }

    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
        let a = T::from_f64(self.a);
        let rho2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + a * a;
        T::from_f64(INV_4PI) / rho2.sqrt()
    }

    /// `grad_y K = -d / (4 pi (|d|^2 + a^2)^(3/2))` with `d = y - x`.
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
        let a = T::from_f64(self.a);
        let rho2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + a * a;
        let rho_inv = T::ONE / rho2.sqrt();
        let f = -(T::from_f64(INV_4PI) * rho_inv * rho_inv * rho_inv);
        [f * d[0], f * d[1], f * d[2]]
    }

    /// The crate's vectorised loop with [`LaneKernel::pair`].
    fn evaluate<T: Real>(
        &self,
        mode: EvalMode,
        sources: &[T],
        charges: &[T],
        targets: &[T],
        out: &mut [T],
    ) {
        lanes::evaluate(self, mode, sources, charges, targets, out);
    }
}

/// Deterministic pseudo-random values in `[0, 1)` (no extra dependencies):
/// a 64-bit LCG.
fn uniform(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        })
        .collect()
}

/// Interactions per second of `f` on `n x n` pairs, single thread, best
/// of a few calls.
fn rate(n: usize, mut f: impl FnMut()) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        f();
        best = best.min(t.elapsed().as_secs_f64());
    }
    (n * n) as f64 / best
}

/// Build and check the FMM of the softened kernel with every M2L scheme on
/// `n` uniform points (zero-mean charges, order 7, potential + gradient),
/// then compare P2P rates. Panics when an error exceeds 3 times Laplace's
/// with the same scheme and tree, or `1e-5` (order 7 gives 1e-7 to 1e-6).
pub fn run(n: usize) {
    let points = uniform(3 * n, 1);
    let charges: Vec<f64> = uniform(n, 2).into_iter().map(|q| q - 0.5).collect();
    let mode = EvalMode::PotentialGradient;
    let kernel = SoftenedLaplace { a: 1e-4 };
    let sample = sample_indices(n, 500);

    println!("softened Laplace (a = 1e-4), {n} uniform points, zero-mean charges, order 7");
    println!(
        "{:>7} {:>10} {:>12} {:>12} {:>14} {:>14}",
        "scheme", "seconds", "potential", "gradient", "Laplace pot.", "Laplace grad."
    );
    // Against direct summation on the sampled targets, next to Laplace with
    // the same scheme, order and tree.
    let check = |name: &str, values: &[f64], seconds: f64, laplace: &[f64]| {
        let e = relative_errors(&kernel, mode, &points, &charges, &points, values, &sample);
        let l = relative_errors(
            &Laplace3d, mode, &points, &charges, &points, laplace, &sample,
        );
        let (g, lg) = (
            e.gradient.expect("gradients"),
            l.gradient.expect("gradients"),
        );
        println!(
            "{name:>7} {seconds:>10.3} {:>12.2e} {g:>12.2e} {:>14.2e} {lg:>14.2e}",
            e.potential, l.potential
        );
        assert!(
            e.potential <= 3.0 * l.potential && g <= 3.0 * lg,
            "{name}: {e:?} against Laplace's {l:?}"
        );
        assert!(e.potential <= 1e-5 && g <= 1e-5, "{name}: {e:?}");
    };
    let b = || FmmBuilder::new(&points).order(7).leaf_size(64).mode(mode);
    let t = Instant::now();
    let soft = b().kernel(kernel.clone()).build_svd().expect("svd");
    let values = soft.evaluate(&charges).expect("eval");
    let seconds = t.elapsed().as_secs_f64();
    let laplace = b().build_svd().expect("svd").evaluate(&charges);
    check("svd", &values, seconds, &laplace.expect("eval"));
    let t = Instant::now();
    let soft = b().kernel(kernel.clone()).build_dense().expect("dense");
    let values = soft.evaluate(&charges).expect("eval");
    let seconds = t.elapsed().as_secs_f64();
    let laplace = b().build_dense().expect("dense").evaluate(&charges);
    check("dense", &values, seconds, &laplace.expect("eval"));
    let t = Instant::now();
    let soft = b()
        .kernel(kernel.clone())
        .build_with::<FftM2l<f64>>(FftConfig)
        .expect("fft");
    let values = soft.evaluate(&charges).expect("eval");
    let seconds = t.elapsed().as_secs_f64();
    let laplace = b().build_with::<FftM2l<f64>>(FftConfig).expect("fft");
    check(
        "fft",
        &values,
        seconds,
        &laplace.evaluate(&charges).expect("eval"),
    );

    // P2P rates, one thread, 1024 x 1024 in cache.
    let m = 1024.min(n);
    let (s, q) = (&points[..3 * m], &charges[..m]);
    let mut out = vec![0.0; 4 * m];
    let soft = rate(m, || kernel.evaluate(mode, s, q, s, &mut out));
    let lap = rate(m, || Laplace3d.evaluate(mode, s, q, s, &mut out));
    let pairwise = rate(m, || {
        reference::evaluate_pairwise(&kernel, mode, s, q, s, &mut out)
    });
    println!("P2P, potential + gradient, f64, one thread ({m} x {m} pairs):");
    println!(
        "  softened (vectorised loop)  {:>8.0} M pairs/s",
        soft / 1e6
    );
    println!("  Laplace                     {:>8.0} M pairs/s", lap / 1e6);
    println!(
        "  softened (scalar pairwise)  {:>8.0} M pairs/s",
        pairwise / 1e6
    );
}

pub fn main() {
    let n = std::env::args()
        .nth(1)
        .and_then(|a| a.parse::<f64>().ok())
        .map_or(20_000, |v| v as usize);
    run(n);
}
