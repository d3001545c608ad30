//! Error against the expansion order for the kernels with several
//! components: the complex Helmholtz kernel over wavenumbers (charges plus
//! dipoles) and the Stokeslet (forces).
//!
//! For each kernel, wavenumber, geometry, density sign and order `p`, one
//! FMM (f64, leaf size 64, potentials and gradients; SVD M2L and p = 4, 6,
//! 8 unless asked otherwise) is built and evaluated; the relative L2
//! errors of the potential and the gradient against direct summation on
//! 400 sampled targets are printed as one CSV row with the build and
//! evaluation times.
//!
//! ```text
//! cargo run --release -p ferrofmm-fmm --features sweeps --example components_sweep -- 20000 > components.csv
//! cargo run --release -p ferrofmm-fmm --features sweeps --example components_sweep -- 20000 '' stokes
//! # N, wavenumbers, kernels (helmholtz | stokes | both), scheme (svd | fft), orders
//! cargo run --release -p ferrofmm-fmm --features sweeps --example components_sweep -- 20000 '' stokes fft 3,4,5,6,7,8,9,10
//! ```
//!
//! `k W` is the wavenumber times the width of the points' bounding cube
//! (1 for the cube, about 1 for Plummer, whose outliers are far but few).
use ferrofmm_field::{FftM2l, M2lScheme, SvdM2l};
use ferrofmm_fmm::{Charges, FmmBuilder, Geometry, relative_errors_sources, sample_indices};
use ferrofmm_kernels::{EvalMode, Helmholtz3d, Kernel, SourceKind, Stokes3d};
use std::time::Instant;

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = match args.next().map(|s| s.parse()) {
        None => 20_000,
        Some(Ok(n)) if n >= 100 => n,
        Some(_) => {
            eprintln!(
                "usage: components_sweep [N >= 100] [k,k,...] [helmholtz|stokes|both] [svd|fft] [p,p,...]"
            );
            std::process::exit(2);
        }
    };
    let ks: Vec<f64> = args
        .next()
        .map(|s| s.split(',').filter_map(|k| k.parse().ok()).collect())
        .unwrap_or_else(|| vec![1.0, 5.0, 10.0, 20.0, 30.0, 40.0]);
    // A third argument picks the second part's kernels: `helmholtz`,
    // `stokes` or (the default) both.
    let which = args.next().unwrap_or_else(|| "both".to_string());
    let scheme = args.next().unwrap_or_else(|| "svd".to_string());
    let orders: Vec<usize> = args
        .next()
        .map(|s| s.split(',').filter_map(|p| p.parse().ok()).collect())
        .unwrap_or_else(|| vec![4, 6, 8]);
    let sweep = |kernel: &dyn Fn(&Sweep)| match scheme.as_str() {
        "svd" => kernel(&Sweep::Svd),
        "fft" => kernel(&Sweep::Fft),
        other => {
            eprintln!("unknown scheme {other:?}: svd or fft");
            std::process::exit(2);
        }
    };
    println!("kernel,k,scheme,geometry,densities,order,potential,gradient,build_s,evaluate_s");
    for &k in &ks {
        let h = Helmholtz3d::new(k).expect("valid k");
        let kind = SourceKind::ChargeDipole;
        sweep(&|s| s.run(&h, k, Geometry::Cube, Charges::Signed, kind, n, &orders));
    }
    for (geometry, sign) in [
        (Geometry::Cube, Charges::Signed),
        (Geometry::Plummer, Charges::Positive),
    ] {
        let kind = SourceKind::Charge;
        if which != "stokes" {
            let h = Helmholtz3d::new(10.0).expect("valid k");
            sweep(&|s| s.run(&h, 10.0, geometry, sign, kind, n, &orders));
        }
        if which != "helmholtz" {
            let stokes = Stokes3d::default();
            sweep(&|s| s.run(&stokes, 0.0, geometry, sign, kind, n, &orders));
        }
    }
}

/// The M2L scheme of a sweep.
enum Sweep {
    Svd,
    Fft,
}

impl Sweep {
    #[allow(clippy::too_many_arguments)]
    fn run<K: Kernel>(
        &self,
        kernel: &K,
        k: f64,
        geometry: Geometry,
        sign: Charges,
        kind: SourceKind,
        n: usize,
        orders: &[usize],
    ) {
        match self {
            Sweep::Svd => sweep::<K, SvdM2l<f64>>(kernel, k, geometry, sign, kind, n, orders),
            Sweep::Fft => sweep::<K, FftM2l<f64>>(kernel, k, geometry, sign, kind, n, orders),
        }
    }
}

fn sweep<K: Kernel, S: M2lScheme<f64>>(
    kernel: &K,
    k: f64,
    geometry: Geometry,
    sign: Charges,
    kind: SourceKind,
    n: usize,
    orders: &[usize],
) where
    S::Config: Default,
{
    let points: Vec<f64> = geometry.points(n, 7);
    let sample = sample_indices(n, 400);
    let mode = EvalMode::PotentialGradient;
    let densities: Vec<f64> = sign.generate(n * kernel.values_per_source(kind), 11);
    for &order in orders {
        let t = Instant::now();
        let fmm = match FmmBuilder::new(&points)
            .kernel(kernel.clone())
            .order(order)
            .leaf_size(64)
            .mode(mode)
            .source_kind(kind)
            .build_with::<S>(S::Config::default())
        {
            Ok(f) => f,
            Err(e) => {
                eprintln!("{} k={k} p={order}: {e}", kernel.name());
                return;
            }
        };
        let build = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let (values, timings) = fmm.evaluate_timed(&densities).expect("valid densities");
        let evaluate = t.elapsed().as_secs_f64();
        let phases: Vec<String> = timings
            .operators()
            .iter()
            .map(|(name, d)| format!("{name} {:.3}", d.as_secs_f64()))
            .collect();
        eprintln!("{} k={k} p={order}: {}", kernel.name(), phases.join(", "));
        let e = relative_errors_sources(
            kernel, kind, mode, &points, &densities, &points, &values, &sample,
        );
        println!(
            "{},{k},{},{},{},{order},{:.3e},{:.3e},{build:.3},{evaluate:.3}",
            kernel.name(),
            fmm.summary().m2l_scheme,
            geometry.name(),
            sign.name(),
            e.potential,
            e.gradient.unwrap_or(f64::NAN),
        );
    }
}
