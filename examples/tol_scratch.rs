//! scratch measurements (to be removed)
use ferrofmm::field::SvdConfig;
use ferrofmm::fmm::{FmmBuilder, Geometry, charges, relative_errors, sample_indices};
use ferrofmm::kernels::{EvalMode, Laplace3d, Real};
use std::time::Instant;

fn run<T: Real>(
    g: Geometry,
    n: usize,
    p: usize,
    leaf: usize,
    svd_tol: f64,
) -> (f64, f64, f64, usize, u32, usize) {
    let points: Vec<T> = g.points(n, 7);
    let q: Vec<T> = charges(n, 11);
    let t0 = Instant::now();
    let fmm = FmmBuilder::new(&points)
        .order(p)
        .leaf_size(leaf)
        .cache_dir(std::env::var("TOLCACHE").unwrap_or("target/tol-cache".into()))
        .build_with::<ferrofmm::field::SvdM2l<T>>(SvdConfig {
            rank: None,
            tolerance: svd_tol,
        })
        .unwrap();
    let setup = t0.elapsed().as_secs_f64();
    let mut best = f64::INFINITY;
    let mut values = Vec::new();
    for _ in 0..2 {
        let (v, t) = fmm.evaluate_timed(&q).unwrap();
        best = best.min(t.total.as_secs_f64());
        values = v;
    }
    let e = relative_errors(
        &Laplace3d,
        EvalMode::Potential,
        &points,
        &q,
        &points,
        &values,
        &sample_indices(n, 997),
    );
    let s = fmm.summary();
    (
        e.potential,
        setup,
        best,
        fmm.m2l_scheme().rank(),
        s.depth,
        s.n_leaves,
    )
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mode = args.first().map(String::as_str).unwrap_or("errors");
    let n: usize = args.get(1).map(|a| a.parse().unwrap()).unwrap_or(20000);
    match mode {
        "errors" => {
            let leaves: Vec<usize> = args
                .get(2)
                .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
                .unwrap_or(vec![32, 64, 150, 400]);
            let orders: Vec<usize> = args
                .get(3)
                .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
                .unwrap_or((2..=12).collect());
            for &p in &orders {
                for g in Geometry::ALL {
                    let mut line = format!("p={p:2} {:13}", g.name());
                    for &leaf in &leaves {
                        let (e, _, _, k, d, _) = run::<f64>(g, n, p, leaf, 0.0);
                        line += &format!(" leaf {leaf:4}: {e:.2e} (d{d},k{k})");
                    }
                    println!("{line}");
                }
            }
        }
        "svd" => {
            let orders: Vec<usize> = args
                .get(2)
                .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
                .unwrap_or((3..=11).collect());
            for &p in &orders {
                for g in [Geometry::Cube, Geometry::Plummer] {
                    let mut line = format!("p={p:2} {:8}", g.name());
                    for tol in [
                        0.0, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11,
                    ] {
                        let (e, _, t, k, _, _) = run::<f64>(g, n, p, 64, tol);
                        line += &format!(" {tol:.0e}:{e:.1e}/k{k}/{t:.3}");
                    }
                    println!("{line}");
                }
            }
        }
        "f32" => {
            for p in 2..=10 {
                for g in Geometry::ALL {
                    let mut line = format!("p={p:2} {:13}", g.name());
                    for tol in [0.0, 1e-5, 1e-6, 1e-7] {
                        let (e, _, _, k, _, _) = run::<f32>(g, n, p, 64, tol);
                        line += &format!(" {tol:.0e}:{e:.2e}/k{k}");
                    }
                    println!("{line}");
                }
            }
        }
        "one32" => {
            let p: usize = args[2].parse().unwrap();
            let leaf: usize = args[3].parse().unwrap();
            let tol: f64 = args[4].parse().unwrap();
            let g = Geometry::from_name(&args[5]).unwrap();
            let (e, _, _, k, d, nl) = run::<f32>(g, n, p, leaf, tol);
            println!(
                "f32 {} p {p} leaf {leaf} tol {tol}: {e:.3e} k{k} d{d} leaves {nl}",
                g.name()
            );
        }
        "f32leaf" => {
            for p in [3, 6, 8] {
                for g in [Geometry::TwoClusters] {
                    let mut line = format!("p={p:2} {:13}", g.name());
                    for leaf in [32, 64, 128, 256, 384, 512, 1024, 2048] {
                        let (e, _, _, _, d, nl) = run::<f32>(g, n, p, leaf, 0.0);
                        let (e64, _, _, _, _, _) = run::<f64>(g, n, p, leaf, 0.0);
                        line += &format!(" {leaf}:{e:.2e}/{e64:.1e}/d{d}/{nl}");
                    }
                    println!("{line}");
                }
            }
        }
        _ => panic!("mode"),
    }
}
