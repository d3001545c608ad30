//! P2P throughput of the Laplace kernel (potential + gradient, f64) at the
//! detected SIMD level: leaf-sized blocks of 384 targets against 27 x 384
//! sources, repeated; prints pairs per second on one thread.
//!
//! `cargo run --release -p ferrofmm-kernels --example p2p_rate`

use std::time::Instant;

use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d};

fn main() {
    let (m, n) = (384usize, 27 * 384usize);
    let mut k = 1u64;
    let mut next = move || {
        k = k
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (k >> 11) as f64 / (1u64 << 53) as f64
    };
    let sources: Vec<f64> = (0..3 * n).map(|_| 3.0 * next()).collect();
    let targets: Vec<f64> = (0..3 * m).map(|_| 1.0 + next()).collect();
    let q: Vec<f64> = (0..n).map(|_| next() - 0.5).collect();
    let mut out = vec![0.0; 4 * m];
    let reps = 200;
    let t = Instant::now();
    for _ in 0..reps {
        Laplace3d.evaluate(
            EvalMode::PotentialGradient,
            &sources,
            &q,
            &targets,
            &mut out,
        );
    }
    let s = t.elapsed().as_secs_f64();
    let pairs = (reps * m * n) as f64;
    println!(
        "{:.3e} pairs/s ({:.1} ns a pair), check {:.6e}",
        pairs / s,
        s / pairs * 1e9,
        out[0]
    );
}
