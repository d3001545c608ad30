//! Error against the expansion order for every source kind (charges,
//! dipoles, both) and every output (potential, gradient, Hessian), for the
//! Laplace and modified Helmholtz kernels.
//!
//! For each kernel, geometry, density sign, order `p` and source kind, one
//! FMM (SVD M2L, f64, leaf size 64) is built with Hessians and evaluated;
//! the relative L2 errors of the potential, the gradient and the Hessian
//! against direct summation on 500 sampled targets are printed as one CSV
//! row, with the evaluation time.
//!
//! ```text
//! cargo run --release -p ferrofmm-fmm --features sweeps --example sources_sweep -- 20000 > sources.csv
//! ```
//!
//! Densities are drawn per component: `signed` uniform in `[-0.5, 0.5)`
//! (zero mean), `positive` in `[0, 1)` (dipoles then all point into the
//! positive octant).
use ferrofmm_fmm::{Charges, FmmBuilder, Geometry, relative_errors_sources, sample_indices};
use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d, ModifiedHelmholtz3d, SourceKind};
use std::time::Instant;

fn main() {
    let n: usize = match std::env::args().nth(1).map(|s| s.parse()) {
        None => 20_000,
        Some(Ok(n)) if n >= 100 => n,
        Some(_) => {
            eprintln!("usage: sources_sweep [N >= 100]");
            std::process::exit(2);
        }
    };
    println!("kernel,geometry,densities,order,kind,potential,gradient,hessian,evaluate_s");
    let yukawa = ModifiedHelmholtz3d::new(5.0).expect("k = 5 is valid");
    for geometry in [Geometry::Cube, Geometry::Plummer] {
        for sign in Charges::ALL {
            sweep(&Laplace3d, geometry, sign, n);
            sweep(&yukawa, geometry, sign, n);
        }
    }
}

fn sweep<K: Kernel>(kernel: &K, geometry: Geometry, sign: Charges, n: usize) {
    let points: Vec<f64> = geometry.points(n, 7);
    let sample = sample_indices(n, 500);
    let mode = EvalMode::PotentialGradientHessian;
    for order in (4..=10).step_by(2) {
        for kind in [
            SourceKind::Charge,
            SourceKind::Dipole,
            SourceKind::ChargeDipole,
        ] {
            let densities: Vec<f64> = sign.generate(n * kind.values_per_source(), 11);
            let fmm = FmmBuilder::new(&points)
                .kernel(kernel.clone())
                .order(order)
                .leaf_size(64)
                .mode(mode)
                .source_kind(kind)
                .build_svd()
                .expect("valid parameters");
            let t = Instant::now();
            let values = fmm.evaluate(&densities).expect("valid densities");
            let seconds = t.elapsed().as_secs_f64();
            let e = relative_errors_sources(
                kernel, kind, mode, &points, &densities, &points, &values, &sample,
            );
            println!(
                "{},{},{},{order},{},{:.3e},{:.3e},{:.3e},{seconds:.3}",
                kernel.name(),
                geometry.name(),
                sign.name(),
                kind.name(),
                e.potential,
                e.gradient.unwrap_or(f64::NAN),
                e.hessian.unwrap_or(f64::NAN),
            );
        }
    }
}
