//! The Laplace FMM on random points, checked against direct summation.
//!
//! `cargo run --release --example laplace -- [N] [ORDER]`

use ferrofmm::fmm::{FmmBuilder, Geometry, charges, relative_errors, sample_indices};
use ferrofmm::kernels::{EvalMode, Laplace3d};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let n: usize = args
        .next()
        .map(|a| a.parse())
        .transpose()?
        .unwrap_or(200_000);
    let order: usize = args.next().map(|a| a.parse()).transpose()?.unwrap_or(6);

    let points: Vec<f64> = Geometry::Cube.points(n, 1);
    let q: Vec<f64> = charges(n, 2);
    let fmm = FmmBuilder::new(&points)
        .order(order)
        .mode(EvalMode::PotentialGradient)
        .build_svd()?;
    let (values, timings) = fmm.evaluate_timed(&q)?;
    let s = fmm.summary();
    println!(
        "N = {n}, p = {order}: {} leaves, depth {}, setup {:.3} s, evaluation {:.3} s",
        s.n_leaves,
        s.depth,
        fmm.setup_timings().total.as_secs_f64(),
        timings.total.as_secs_f64()
    );
    for (name, t) in timings.operators() {
        println!("  {name:>4}: {:.3} s", t.as_secs_f64());
    }
    let e = relative_errors(
        &Laplace3d,
        EvalMode::PotentialGradient,
        &points,
        &q,
        &points,
        &values,
        &sample_indices(n, 1000),
    );
    println!(
        "relative L2 error on {} targets: potential {:.2e}, gradient {:.2e}",
        e.n_sampled,
        e.potential,
        e.gradient.unwrap_or(f64::NAN)
    );
    Ok(())
}
