//! Error and time as one point moves away from a unit cloud.
//!
//! Puts `n - 1` points uniformly in the unit cube and the last point at
//! `(D, D, D)` for `D = 1, 10, ..., 1e15`, evaluates the Laplace potential
//! and gradient with zero-mean charges (order 6, SVD M2L, f64) and prints
//! one CSV row per distance: the relative errors against direct summation
//! on 500 sampled targets, the build and evaluation seconds, the P2P
//! seconds and the tree depth. The first row (`D = 0`) is the clean cloud
//! (no outlier), the reference the other rows should match.
//!
//! ```text
//! cargo run --release -p ferrofmm-fmm --features sweeps --example outlier_sweep -- 20000 > after.csv
//! ```
//!
//! It uses only the API that predates the forest of trees, so the same
//! file, compiled against an older checkout, gives the "before" curve of
//! `docs/charts/outliers.svg`.
use ferrofmm_fmm::{FmmBuilder, Geometry, charges, relative_errors, sample_indices};
use ferrofmm_kernels::{EvalMode, Laplace3d};
use std::time::Instant;

fn main() {
    let n: usize = match std::env::args().nth(1).map(|s| s.parse()) {
        None => 20_000,
        Some(Ok(n)) if n >= 2 => n,
        Some(_) => {
            eprintln!("usage: outlier_sweep [N >= 2]");
            std::process::exit(2);
        }
    };
    let mode = EvalMode::PotentialGradient;
    let base: Vec<f64> = Geometry::Cube.points(n, 3);
    let q: Vec<f64> = charges(n, 4);
    let sample = sample_indices(n, 500);
    println!("distance,potential_error,gradient_error,build_s,evaluate_s,p2p_s,depth");
    let distances = std::iter::once(0.0).chain((0..=15).map(|e| 10f64.powi(e)));
    for d in distances {
        let mut points = base.clone();
        if d > 0.0 {
            points[3 * n - 3..].copy_from_slice(&[d; 3]);
        }
        let start = Instant::now();
        let fmm = match FmmBuilder::new(&points).order(6).mode(mode).build_svd() {
            Ok(f) => f,
            Err(e) => {
                eprintln!("D = {d:e}: {e}");
                continue;
            }
        };
        let build = start.elapsed().as_secs_f64();
        let (v, timings) = match fmm.evaluate_timed(&q) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("D = {d:e}: {e}");
                continue;
            }
        };
        let evaluate = start.elapsed().as_secs_f64() - build;
        let e = relative_errors(&Laplace3d, mode, &points, &q, &points, &v, &sample);
        println!(
            "{d:e},{:.3e},{:.3e},{build:.3},{evaluate:.3},{:.3},{}",
            e.potential,
            e.gradient.unwrap_or(f64::NAN),
            timings.p2p.as_secs_f64(),
            fmm.summary().depth
        );
    }
}
