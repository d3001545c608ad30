//! The cost model against this machine, pass by pass: for each setting,
//! the measured P2P, far field (P2M, M2M, L2L, L2P, M2P, P2L), M2L and
//! tree times next to what `tuning::CostModel` predicts for the same tree,
//! and their ratio. A ratio far from 1 in one column only (the others
//! near each other) is what moves the chooser's decisions on a new machine:
//! only the ratios between the columns matter to it.
//!
//! ```text
//! cargo run --release -p ferrofmm-fmm --features sweeps --example cost_check -- \
//!     N[,N...] KERNEL GEOMETRY[,GEOMETRY...] MODE SCHEME ORDER,LEAF [ORDER,LEAF ...]
//! cargo run --release -p ferrofmm-fmm --features sweeps --example cost_check -- \
//!     100000 laplace cube gradient fft 6,512 8,384 6,128
//! ```
//!
//! Every setting runs on every size and geometry given. `KERNEL`:
//! `laplace` or `helmholtz:K`; `GEOMETRY`: cube, sphere, plummer,
//! two-clusters; `MODE`: `potential` or `gradient`; `SCHEME`: `fft`, `svd`
//! or `both` (each setting with each scheme). Zero-mean charges; evaluation
//! the best of two; operators from the on-disk cache
//! `target/cost-check-cache` (filled on the first run).
//!
//! For Laplace potentials (what `CostModel::default` describes; the other
//! kernels and modes are factors on it) the runs are also fitted
//! (`CostModel::fit`, group by group; a group without runs, e.g. the SVD
//! M2L with `fft`, keeps its default) and the fitted model printed, to
//! paste into `CostModel::default` after checking it on other settings.
//!
//! ```text
//! cargo run --release -p ferrofmm-fmm --features sweeps --example cost_check -- \
//!     100000 laplace cube potential both 4,64 6,128 6,512 8,256 8,512 10,512
//! ```
use ferrofmm_field::{FftM2l, M2lCostShape, M2lScheme, SvdM2l};
use ferrofmm_fmm::tuning::{CostModel, CostSample, WorkCounts, default_model};
use ferrofmm_fmm::{Charges, EvalTimings, Fmm, FmmBuilder, Geometry};
use ferrofmm_kernels::{EvalMode, Helmholtz3d, Kernel, Laplace3d, SourceKind};

const CACHE: &str = "target/cost-check-cache";

fn usage() -> ! {
    eprintln!(
        "usage: cost_check N[,N..] laplace|helmholtz:K GEOMETRY[,GEOMETRY..] potential|gradient fft|svd|both ORDER,LEAF ..."
    );
    std::process::exit(2);
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 6 {
        usage();
    }
    let sizes: Vec<usize> = args[0]
        .split(',')
        .map(|v| v.parse::<f64>().map(|x| x as usize).unwrap_or_else(|_| usage()))
        .collect();
    let geometries: Vec<Geometry> = args[2]
        .split(',')
        .map(|g| Geometry::from_name(g).unwrap_or_else(|| usage()))
        .collect();
    let mode = match args[3].as_str() {
        "potential" => EvalMode::Potential,
        "gradient" => EvalMode::PotentialGradient,
        _ => usage(),
    };
    let schemes: &[bool] = match args[4].as_str() {
        "fft" => &[true],
        "svd" => &[false],
        "both" => &[true, false],
        _ => usage(),
    };
    let settings: Vec<(usize, usize)> = args[5..]
        .iter()
        .map(|s| {
            let (p, l) = s.split_once(',').unwrap_or_else(|| usage());
            (
                p.parse().unwrap_or_else(|_| usage()),
                l.parse().unwrap_or_else(|_| usage()),
            )
        })
        .collect();
    println!(
        "| N, geometry | kernel | order, leaf | depth | P2P s (model) | far s (model) | M2L s (model) | tree s (model) | total s (model) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    let mut samples = Vec::new();
    for &n in &sizes {
        for &geometry in &geometries {
            let points: Vec<f64> = geometry.points(n, 7);
            let label = format!("{n:.0e}, {}", geometry.name());
            match args[1].split_once(':') {
                None if args[1] == "laplace" => {
                    for &s in &settings {
                        for &fft in schemes {
                            samples.push(row(&label, &points, Laplace3d, mode, fft, s));
                        }
                    }
                }
                Some(("helmholtz", k)) => {
                    let k: f64 = k.parse().unwrap_or_else(|_| usage());
                    for &s in &settings {
                        for &fft in schemes {
                            row(&label, &points, Helmholtz3d::new(k).unwrap(), mode, fft, s);
                        }
                    }
                }
                _ => usage(),
            }
        }
    }
    if !samples.is_empty() && mode == EvalMode::Potential {
        println!(
            "\nfitted to these {} runs: {:#?}",
            samples.len(),
            CostModel::fit(&samples)
        );
    }
}

/// One built and evaluated setting.
struct Measured {
    /// Tree construction with the V-list layout, seconds.
    tree_s: f64,
    eval: EvalTimings,
    work: WorkCounts,
    depth: u32,
    /// Width of the root box.
    width: f64,
    /// M2L rank (0 for FFT).
    rank: usize,
}

impl Measured {
    fn of<K: Kernel, S: M2lScheme<f64>>(f: &Fmm<f64, K, S>, q: &[f64], rank: usize) -> Self {
        let (_, eval) = f.evaluate_timed(q).unwrap();
        let s = f.setup_timings();
        Measured {
            tree_s: (s.tree + s.layout).as_secs_f64(),
            eval,
            work: WorkCounts::of_tree(f.tree()),
            depth: f.summary().depth,
            width: f.tree().domain().width,
            rank,
        }
    }
}

/// Measure one setting, print its row and return it as a fit sample.
fn row<K: Kernel>(
    label: &str,
    points: &[f64],
    kernel: K,
    mode: EvalMode,
    fft: bool,
    (order, leaf): (usize, usize),
) -> CostSample {
    let n = points.len() / 3;
    let q: Vec<f64> = Charges::Signed.generate(n * kernel.values_per_source(SourceKind::Charge), 3);
    let builder = || {
        FmmBuilder::new(points)
            .kernel(kernel.clone())
            .order(order)
            .leaf_size(leaf)
            .mode(mode)
            .cache_dir(CACHE)
    };
    // Build three times (the first fills the cache), keep the faster of
    // the last two.
    let best = |run: &dyn Fn() -> Measured| {
        let _ = run();
        let (a, b) = (run(), run());
        if a.eval.total <= b.eval.total { a } else { b }
    };
    let Measured {
        tree_s,
        eval: t,
        work,
        depth,
        width,
        rank,
    } = if fft {
        best(&|| {
            let f = builder()
                .build_with::<FftM2l<f64>>(Default::default())
                .unwrap();
            Measured::of(&f, &q, 0)
        })
    } else {
        best(&|| {
            let f = builder()
                .build_with::<SvdM2l<f64>>(Default::default())
                .unwrap();
            Measured::of(&f, &q, f.m2l_scheme().rank())
        })
    };
    let shape = if fft {
        M2lCostShape::Fft
    } else {
        M2lCostShape::Compressed
    };
    let model = default_model(&kernel, width).cost_model(mode, shape);
    let p = model.predict_for(shape, &work, order, rank);
    let far = t.p2m + t.m2m + t.l2l + t.l2p + t.m2p + t.p2l;
    let cell = |m: f64, pr: f64| format!("{m:.3} ({pr:.3}, {:.2}x)", m / pr);
    println!(
        "| {label} | {} {} | {order}, {leaf} | {depth} | {} | {} | {} | {} | {} |",
        kernel.name(),
        if fft { "fft" } else { "svd" },
        cell(t.p2p.as_secs_f64(), p.p2p),
        cell(far.as_secs_f64(), p.far),
        cell(t.m2l.as_secs_f64(), p.m2l),
        cell(tree_s, p.tree),
        cell(t.total.as_secs_f64() + tree_s, p.total),
    );
    CostSample {
        work,
        order,
        rank,
        shape,
        eval: t,
        tree_seconds: tree_s,
    }
}
