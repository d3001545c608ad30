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
//!
//! With `COST_CHECK_RUNS=FILE` the runs are appended to `FILE` (one line of
//! numbers each) and the fit takes every run in it, so that runs of
//! several invocations (e.g. a few deep trees at a larger N) are fitted
//! together.
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
        .map(|v| {
            v.parse::<f64>()
                .map(|x| x as usize)
                .unwrap_or_else(|_| usage())
        })
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
    if mode != EvalMode::Potential || samples.is_empty() {
        return;
    }
    if let Ok(path) = std::env::var("COST_CHECK_RUNS") {
        // Keep these runs beside earlier invocations' and fit them all.
        let mut text = std::fs::read_to_string(&path).unwrap_or_default();
        for s in &samples {
            text += &to_row(s);
            text.push('\n');
        }
        std::fs::write(&path, &text).expect("write COST_CHECK_RUNS");
        samples = text.lines().filter_map(from_row).collect();
    }
    println!(
        "\nfitted to {} runs: {:#?}",
        samples.len(),
        CostModel::fit(&samples)
    );
}

/// One run as a line of numbers: the work counts, order, rank, scheme
/// (1 = FFT), the timed passes and the tree, in seconds.
fn to_row(s: &CostSample) -> String {
    let w = &s.work;
    let e = &s.eval;
    let t = |d: std::time::Duration| d.as_secs_f64();
    let v: [f64; 20] = [
        w.n_sources as f64,
        w.n_targets as f64,
        w.depth as f64,
        w.n_boxes as f64,
        w.n_leaves as f64,
        w.m2l_boxes as f64,
        w.p2p_pairs,
        w.m2l_pairs,
        w.far_points,
        w.u_entries,
        s.order as f64,
        s.rank as f64,
        if s.shape == M2lCostShape::Fft {
            1.0
        } else {
            0.0
        },
        t(e.p2m),
        t(e.m2m) + t(e.l2l),
        t(e.m2l),
        t(e.p2l) + t(e.m2p),
        t(e.l2p),
        t(e.p2p),
        s.tree_seconds,
    ];
    v.map(|x| format!("{x:e}")).join(" ")
}

/// The inverse of [`to_row`] (the far-field passes it merges come back in
/// one of their fields: the fit sums them).
fn from_row(line: &str) -> Option<CostSample> {
    let v: Vec<f64> = line
        .split(' ')
        .map(|x| x.parse().ok())
        .collect::<Option<_>>()?;
    if v.len() != 20 {
        return None;
    }
    let d = std::time::Duration::from_secs_f64;
    let work = WorkCounts {
        n_sources: v[0] as usize,
        n_targets: v[1] as usize,
        depth: v[2] as u32,
        n_boxes: v[3] as usize,
        n_leaves: v[4] as usize,
        m2l_boxes: v[5] as usize,
        p2p_pairs: v[6],
        m2l_pairs: v[7],
        far_points: v[8],
        u_entries: v[9],
        ..Default::default()
    };
    Some(CostSample {
        work,
        order: v[10] as usize,
        rank: v[11] as usize,
        shape: if v[12] == 1.0 {
            M2lCostShape::Fft
        } else {
            M2lCostShape::Compressed
        },
        eval: EvalTimings {
            p2m: d(v[13]),
            m2m: d(v[14]),
            m2l: d(v[15]),
            p2l: d(v[16]),
            l2p: d(v[17]),
            p2p: d(v[18]),
            ..Default::default()
        },
        tree_seconds: v[19],
    })
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
            work: WorkCounts::of_fmm(f),
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
