//! A kernel defined outside ferrofmm: a softened (Plummer) Laplace kernel
//!
//! ```text
//! K_eps(x, y) = 1 / (4 pi sqrt(|x - y|^2 + eps^2))
//! ```
//!
//! as used in gravitational N-body codes to remove the close-encounter
//! singularity. Implementing [`Kernel`] is all it takes: `direct_sum` (and,
//! later, the FMM driver) use it unchanged. It is not scale invariant (`eps`
//! fixes a length), so `homogeneity` is `None` and the FMM builds its
//! operators per level.
//!
//! Run with `cargo run --release --example custom_kernel`.

use ferrofmm::kernels::{EvalMode, Kernel, Laplace3d, Real, direct_sum};

/// Plummer-softened Laplace kernel with softening length `eps`.
#[derive(Clone, Debug)]
struct SoftenedLaplace {
    eps: f64,
}

impl Kernel for SoftenedLaplace {
    fn name(&self) -> String {
        "softened_laplace3d".to_string()
    }

    fn parameters(&self) -> Vec<f64> {
        vec![self.eps]
    }

    fn homogeneity(&self) -> Option<f64> {
        None
    }

    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
        let eps = T::from_f64(self.eps);
        let s2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + eps * eps;
        T::INV_4PI / s2.sqrt()
    }

    /// `grad_y K = -d / (4 pi (|d|^2 + eps^2)^(3/2))`.
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
        let eps = T::from_f64(self.eps);
        let s2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + eps * eps;
        let sinv = T::ONE / s2.sqrt();
        let f = -(T::INV_4PI * sinv * sinv * sinv);
        [f * d[0], f * d[1], f * d[2]]
    }
    // `evaluate` and `assemble` use the crate's scalar pairwise defaults;
    // coincident pairs are skipped by convention (K(x, x) := 0).
}

/// Deterministic pseudo-random points in the unit cube (no extra
/// dependencies): a 64-bit LCG.
fn cube_points(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed;
    (0..3 * n)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        })
        .collect()
}

fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    let den: f64 = b.iter().map(|y| y * y).sum();
    (num / den).sqrt()
}

fn main() {
    let n = 4000;
    let points = cube_points(n, 1);
    let charges: Vec<f64> = cube_points(n, 2).into_iter().take(n).collect();
    let mode = EvalMode::PotentialGradient;

    let mut laplace = vec![0.0; 4 * n];
    direct_sum(&Laplace3d, mode, &points, &charges, &points, &mut laplace);
    let phi = |v: &[f64]| v.iter().step_by(4).copied().collect::<Vec<_>>();
    let grad = |v: &[f64]| {
        v.chunks_exact(4)
            .flat_map(|c| c[1..].to_vec())
            .collect::<Vec<_>>()
    };

    println!("{n} points in the unit cube, all-pairs potential and gradient");
    println!("softened vs plain Laplace (relative L2 difference):");
    println!("{:>10} {:>14} {:>14}", "eps", "potential", "gradient");
    for eps in [1e-1, 1e-2, 1e-3, 1e-4, 0.0] {
        let kernel = SoftenedLaplace { eps };
        let mut soft = vec![0.0; 4 * n];
        direct_sum(&kernel, mode, &points, &charges, &points, &mut soft);
        println!(
            "{eps:>10.0e} {:>14.3e} {:>14.3e}",
            rel_l2(&phi(&soft), &phi(&laplace)),
            rel_l2(&grad(&soft), &grad(&laplace))
        );
    }
    println!("(eps = 0 is Laplace itself: only rounding differences remain)");
}
