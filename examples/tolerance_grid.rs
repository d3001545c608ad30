//! Is the setting chosen for a tolerance the cheapest? A grid sweep of
//! orders x leaf sizes against the choice of `FmmBuilder::tolerance`, and
//! the measurements behind the models of `ferrofmm_fmm::tuning`.
//!
//! ```text
//! cargo run --release --features sweeps --example tolerance_grid -- [N] [GEOMETRY] [MODE] [OPTIONS]
//! ```
//!
//! * `N` (default 100000), `GEOMETRY`: cube, sphere, plummer, two-clusters
//!   (default cube).
//! * `MODE`:
//!   * `grid` (default): every order x leaf size with the library's default
//!     SVD tolerance; the cost model fitted to the grid's runs; and for each
//!     tolerance in 1e-3, 1e-5, 1e-7, 1e-9 the fastest grid setting that
//!     meets it against the chosen setting (both re-measured three times in
//!     alternation, the fastest of each counts).
//!   * `fit`: the grid on every geometry given (default: all four) and
//!     the cost model fitted to all of their runs, to paste into
//!     `CostModel::default` (with `TOLERANCE_GRID_CSV=path` the raw runs
//!     are written to a CSV file too).
//!   * `chosen`: only the chosen settings (time, error, prediction).
//!   * `errors`: the error of every order x leaf size on all four
//!     geometries with the SVD tolerance of the error model
//!     (`ErrorModel::base_svd_tolerance`), N points each: the table behind
//!     `E_p`.
//!   * `memory`: the memory accounting (`Fmm::memory`) of the setting chosen
//!     for 1e-5 (or of `orders=P leaves=L`) and the process's peak resident
//!     memory (run once per geometry, each in its own process).
//! * `OPTIONS`: `orders=2,3,...`, `leaves=16,32,...`, `tolerances=1e-3,...`,
//!   `repeats=3` (evaluations per setting, the fastest counts),
//!   `charges=signed|positive` (default signed: zero-mean, uniform in
//!   [-0.5, 0.5); positive: uniform in [0, 1)).
//!
//! Time of a setting = tree construction (with the V-list layout) + one
//! evaluation (each the best of `repeats`); the time to choose the
//! parameters is reported beside it for the chosen setting,
//! potentials only, with operators loaded from an on-disk cache
//! (`target/tolerance-cache`): precomputation does not depend on the points
//! and is reported separately. Errors are relative L2 potential errors on
//! 997 evenly spaced targets against direct summation.

use std::collections::BTreeMap;
use std::time::Instant;

use ferrofmm::field::{SvdConfig, SvdM2l};
use ferrofmm::fmm::tuning::{self, CostModel, CostSample, WorkCounts};
use ferrofmm::fmm::{Charges, EvalTimings, Fmm, FmmBuilder, Geometry, sample_indices};
use ferrofmm::kernels::{EvalMode, Laplace3d, Precision, direct_sum};

const CACHE: &str = "target/tolerance-cache";

/// The charges of every problem (`charges=` on the command line).
static CHARGES: std::sync::OnceLock<Charges> = std::sync::OnceLock::new();

fn charges(n: usize, seed: u64) -> Vec<f64> {
    CHARGES.get().copied().unwrap_or_default().generate(n, seed)
}
/// Alternating re-measurements of the fastest and the chosen setting.
const ROUNDS: usize = 3;
/// Targets compared with direct summation.
const SAMPLE: usize = 997;

struct Problem {
    points: Vec<f64>,
    q: Vec<f64>,
    sample: Vec<usize>,
    reference: Vec<f64>,
}

impl Problem {
    fn new(g: Geometry, n: usize) -> Self {
        let points: Vec<f64> = g.points(n, 7);
        let q: Vec<f64> = charges(n, 11);
        // 997 (prime) evenly spaced targets: a round count would pick only
        // even indices, and `Geometry::TwoClusters` puts even indices in one
        // cluster and odd ones in the other.
        let sample = sample_indices(n, SAMPLE);
        let at: Vec<f64> = sample
            .iter()
            .flat_map(|&j| [points[3 * j], points[3 * j + 1], points[3 * j + 2]])
            .collect();
        let mut reference = vec![0.0; sample.len()];
        direct_sum(
            &Laplace3d,
            EvalMode::Potential,
            &points,
            &q,
            &at,
            &mut reference,
        );
        Problem {
            points,
            q,
            sample,
            reference,
        }
    }

    fn error(&self, values: &[f64]) -> f64 {
        let (mut d, mut r) = (0.0, 0.0);
        for (k, &j) in self.sample.iter().enumerate() {
            d += (values[j] - self.reference[k]).powi(2);
            r += self.reference[k].powi(2);
        }
        (d / r).sqrt()
    }
}

#[derive(Clone)]
struct Run {
    order: usize,
    leaf: usize,
    svd_tolerance: f64,
    rank: usize,
    tree_s: f64,
    /// Choosing the parameters (0 for grid settings).
    choice_s: f64,
    eval_s: f64,
    precompute_s: f64,
    error: f64,
    depth: u32,
    n_boxes: usize,
    predicted_s: f64,
    sample: CostSample,
}

impl Run {
    /// Tree (with layout) + one evaluation: the cost of the setting.
    fn time(&self) -> f64 {
        self.tree_s + self.eval_s
    }
}

fn measure(p: &Problem, (fmm, tree_s, choice_s): &Built, repeats: usize, model: &CostModel) -> Run {
    let (tree_s, choice_s) = (*tree_s, *choice_s);
    let mut best: Option<EvalTimings> = None;
    let mut values = Vec::new();
    for _ in 0..repeats.max(1) {
        let (v, t) = fmm.evaluate_timed(&p.q).expect("evaluate");
        if best.is_none_or(|b| t.total < b.total) {
            best = Some(t);
        }
        values = v;
    }
    let best = best.unwrap();
    let setup = fmm.setup_timings();
    let work = WorkCounts::of_fmm(fmm);
    let s = fmm.summary();
    let rank = fmm.m2l_scheme().rank();
    Run {
        order: s.order,
        leaf: s.leaf_size,
        svd_tolerance: fmm.m2l_scheme().tolerance(),
        rank,
        tree_s,
        choice_s,
        eval_s: best.total.as_secs_f64(),
        precompute_s: (setup.operators + setup.m2l_precompute).as_secs_f64(),
        error: p.error(&values),
        depth: s.depth,
        n_boxes: s.n_boxes,
        predicted_s: model.predict(&work, s.order, rank).total,
        sample: CostSample {
            work,
            order: s.order,
            rank,
            shape: ferrofmm::fmm::tuning::M2lCostShape::Compressed,
            eval: best,
            tree_seconds: tree_s,
        },
    }
}

/// A built FMM, its fastest tree construction (with layout) and its
/// fastest parameter choice, in seconds.
type Built = (Fmm<f64, Laplace3d, SvdM2l<f64>>, f64, f64);

/// Build `repeats + 1` times (the first warms the operator cache and the
/// allocator) and keep the last, with the fastest tree construction and
/// choice seen.
fn build_best(repeats: usize, build: impl Fn() -> Fmm<f64, Laplace3d, SvdM2l<f64>>) -> Built {
    let _ = build();
    let (mut tree, mut choice) = (f64::INFINITY, f64::INFINITY);
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let f = build();
        let s = f.setup_timings();
        tree = tree.min((s.tree + s.layout).as_secs_f64());
        choice = choice.min(s.tuning.as_secs_f64());
        last = Some(f);
    }
    (last.unwrap(), tree, choice)
}

fn build_grid(p: &Problem, order: usize, leaf: usize, repeats: usize) -> Built {
    build_best(repeats, || {
        FmmBuilder::new(&p.points)
            .order(order)
            .leaf_size(leaf)
            .cache_dir(CACHE)
            .build_with::<SvdM2l<f64>>(SvdConfig::default())
            .expect("build")
    })
}

fn build_chosen(p: &Problem, eps: f64, repeats: usize) -> Built {
    build_best(repeats, || {
        FmmBuilder::new(&p.points)
            .tolerance(eps)
            .cache_dir(CACHE)
            .build_svd()
            .expect("build")
    })
}

fn list<T: std::str::FromStr>(v: &str) -> Vec<T> {
    v.split(',').filter_map(|x| x.trim().parse().ok()).collect()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut n = 100_000usize;
    let mut geometry = Geometry::Cube;
    let mut mode = "grid".to_string();
    let mut orders: Vec<usize> = (2..=11).collect();
    let mut leaves: Vec<usize> = vec![16, 32, 64, 128, 256, 512, 1024];
    let mut tolerances: Vec<f64> = vec![1e-3, 1e-5, 1e-7, 1e-9];
    let mut repeats = 3usize;
    let mut given: Vec<Geometry> = Vec::new();
    let (mut given_orders, mut given_leaves) = (false, false);
    for a in &args {
        if let Some(v) = a.strip_prefix("orders=") {
            orders = list(v);
            given_orders = true;
        } else if let Some(v) = a.strip_prefix("leaves=") {
            leaves = list(v);
            given_leaves = true;
        } else if let Some(v) = a.strip_prefix("tolerances=") {
            tolerances = list(v);
        } else if let Some(v) = a.strip_prefix("charges=") {
            let kind = Charges::from_name(v).expect("charges=signed or charges=positive");
            CHARGES.set(kind).expect("charges given once");
        } else if let Some(v) = a.strip_prefix("repeats=") {
            repeats = v.parse().expect("repeats");
        } else if let Ok(v) = a.parse::<f64>() {
            n = v as usize;
        } else if let Some(g) = Geometry::from_name(a) {
            geometry = g;
            given.push(g);
        } else {
            mode = a.clone();
        }
    }
    let given_setting = (given_orders && given_leaves).then(|| (orders[0], leaves[0]));
    let geometries = if given.is_empty() {
        Geometry::ALL.to_vec()
    } else {
        given
    };
    println!(
        "# N = {n}, geometry {}, charges {}, mode {mode}, {} threads",
        geometry.name(),
        CHARGES.get().copied().unwrap_or_default().name(),
        rayon::current_num_threads()
    );
    match mode.as_str() {
        "fit" => fit(n, &geometries, &orders, &leaves, repeats),
        "grid" => grid(n, geometry, &orders, &leaves, &tolerances, repeats),
        "chosen" => chosen(n, geometry, &tolerances, repeats),
        "errors" => errors(n, &orders, &leaves),
        "memory" => memory(
            n,
            geometry,
            tolerances[tolerances.len().min(2) - 1],
            given_setting,
        ),
        other => panic!("unknown mode {other}"),
    }
}

/// Every order x leaf size on `p`, printed as a table row each.
fn run_grid(
    p: &Problem,
    orders: &[usize],
    leaves: &[usize],
    repeats: usize,
    label: &str,
) -> Vec<Run> {
    let model = CostModel::default();
    let mut runs = Vec::new();
    for &order in orders {
        for &leaf in leaves {
            let fmm = build_grid(p, order, leaf, repeats);
            let r = measure(p, &fmm, repeats, &model);
            drop(fmm);
            println!(
                "| {label}{} | {} | {} | {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {:.1e} |",
                r.order,
                r.leaf,
                r.depth,
                r.n_boxes,
                r.rank,
                r.tree_s,
                r.eval_s,
                r.time(),
                r.predicted_s,
                r.precompute_s,
                r.error
            );
            runs.push(r);
        }
    }
    runs
}

const GRID_HEADER: &str = "| p | leaf | depth | boxes | rank | tree s | eval s | time s | predicted s | precompute s | error |\n|---|---|---|---|---|---|---|---|---|---|---|";

/// Mean relative error of `m`'s predictions (geometric mean of the ratios).
fn prediction_error(m: &CostModel, runs: &[Run]) -> f64 {
    let e: Vec<f64> = runs
        .iter()
        .map(|r| {
            (m.predict(&r.sample.work, r.order, r.rank).total / r.time())
                .ln()
                .abs()
        })
        .collect();
    (e.iter().sum::<f64>() / e.len().max(1) as f64).exp() - 1.0
}

/// Fit the cost model to grids on several geometries.
fn fit(n: usize, geometries: &[Geometry], orders: &[usize], leaves: &[usize], repeats: usize) {
    let mut all: Vec<(Geometry, Vec<Run>)> = Vec::new();
    println!("{GRID_HEADER}");
    for &g in geometries {
        let p = Problem::new(g, n);
        let label = format!("{} p=", g.name());
        all.push((g, run_grid(&p, orders, leaves, repeats, &label)));
    }
    let runs: Vec<Run> = all.iter().flat_map(|(_, r)| r.iter().cloned()).collect();
    if let Ok(path) = std::env::var("TOLERANCE_GRID_CSV") {
        // Raw samples, to try other forms of the model offline.
        let mut csv = String::from(
            "geometry,order,leaf,n,rank,boxes,m2l_boxes,leaves,depth,p2p_pairs,m2l_pairs,far_points,points,tree_s,p2m_s,m2m_s,m2l_s,p2l_s,l2l_s,l2p_s,m2p_s,p2p_s,eval_s\n",
        );
        for (g, rs) in &all {
            for r in rs {
                let w = &r.sample.work;
                let e = &r.sample.eval;
                csv += &format!(
                    "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
                    g.name(),
                    r.order,
                    r.leaf,
                    ferrofmm::field::n_surface_points(r.order),
                    r.rank,
                    w.n_boxes,
                    w.m2l_boxes,
                    w.n_leaves,
                    w.depth,
                    w.p2p_pairs,
                    w.m2l_pairs,
                    w.far_points,
                    w.n_sources + w.n_targets,
                    r.tree_s,
                    e.p2m.as_secs_f64(),
                    e.m2m.as_secs_f64(),
                    e.m2l.as_secs_f64(),
                    e.p2l.as_secs_f64(),
                    e.l2l.as_secs_f64(),
                    e.l2p.as_secs_f64(),
                    e.m2p.as_secs_f64(),
                    e.p2p.as_secs_f64(),
                    e.total.as_secs_f64()
                );
            }
        }
        std::fs::write(&path, csv).expect("write the CSV");
    }
    let samples: Vec<CostSample> = runs.iter().map(|r| r.sample).collect();
    let fitted = CostModel::fit(&samples);
    println!("\nfitted cost model ({} runs): {fitted:#?}", samples.len());
    println!("\n| geometry | default model error | fitted model error |\n|---|---|---|");
    for (g, r) in &all {
        println!(
            "| {} | {:.0}% | {:.0}% |",
            g.name(),
            100.0 * prediction_error(&CostModel::default(), r),
            100.0 * prediction_error(&fitted, r)
        );
    }
}

fn grid(
    n: usize,
    g: Geometry,
    orders: &[usize],
    leaves: &[usize],
    tolerances: &[f64],
    repeats: usize,
) {
    let p = Problem::new(g, n);
    let model = CostModel::default();
    println!("{GRID_HEADER}");
    let runs = run_grid(&p, orders, leaves, repeats, "");
    let samples: Vec<CostSample> = runs.iter().map(|r| r.sample).collect();
    let fitted = CostModel::fit(&samples);
    println!(
        "\ncost model error on these runs: default {:.0}%, refitted {:.0}%",
        100.0 * prediction_error(&model, &runs),
        100.0 * prediction_error(&fitted, &runs)
    );
    println!(
        "\n| tolerance | fastest in grid (p, leaf) | time s | error | chosen (p, leaf, svd tol, rank) | time s | error | chosen / fastest | choice ms | with choice / fastest |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for &eps in tolerances {
        let fastest = runs
            .iter()
            .filter(|r| r.error <= eps)
            .min_by(|a, b| a.time().total_cmp(&b.time()));
        // Re-measure the fastest grid setting and the chosen one in
        // alternation, so that both see the same machine.
        let mut c: Option<Run> = None;
        let mut f: Option<Run> = None;
        for _ in 0..ROUNDS {
            let r = measure(&p, &build_chosen(&p, eps, repeats), repeats, &model);
            if c.as_ref().is_none_or(|c| r.time() < c.time()) {
                c = Some(r);
            }
            if let Some(g) = fastest {
                let r = measure(
                    &p,
                    &build_grid(&p, g.order, g.leaf, repeats),
                    repeats,
                    &model,
                );
                if f.as_ref().is_none_or(|f| r.time() < f.time()) {
                    f = Some(r);
                }
            }
        }
        let c = c.expect("measured");
        let (f_desc, f_time, f_err, ratio, ratio_with_choice) = match f {
            Some(f) => (
                format!("p={}, leaf {}", f.order, f.leaf),
                format!("{:.3}", f.time()),
                format!("{:.1e}", f.error),
                format!("{:.2}", c.time() / f.time()),
                format!("{:.2}", (c.time() + c.choice_s) / f.time()),
            ),
            None => (
                "none meets it".into(),
                "-".into(),
                "-".into(),
                "-".into(),
                "-".into(),
            ),
        };
        println!(
            "| {eps:.0e} | {f_desc} | {f_time} | {f_err} | p={}, leaf {}, {:.1e}, {} | {:.3} | {:.1e} | {ratio} | {:.1} | {ratio_with_choice} |",
            c.order,
            c.leaf,
            c.svd_tolerance,
            c.rank,
            c.time(),
            c.error,
            1e3 * c.choice_s
        );
    }
}

fn chosen(n: usize, g: Geometry, tolerances: &[f64], repeats: usize) {
    let p = Problem::new(g, n);
    let model = CostModel::default();
    println!(
        "| tolerance | p | leaf | svd tol | rank | depth | tree s | eval s | time s | predicted s | choice s | error | predicted error |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for &eps in tolerances {
        let t = Instant::now();
        let chosen = tuning::choose_parameters(eps, &p.points, None).expect("choose");
        let choice_s = t.elapsed().as_secs_f64();
        let fmm = build_chosen(&p, eps, repeats);
        let r = measure(&p, &fmm, repeats, &model);
        println!(
            "| {eps:.0e} | {} | {} | {:.1e} | {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.1e} | {:.1e} |",
            r.order,
            r.leaf,
            r.svd_tolerance,
            r.rank,
            r.depth,
            r.tree_s,
            r.eval_s,
            r.time(),
            chosen.predicted_seconds,
            choice_s,
            r.error,
            chosen.predicted_error
        );
    }
}

fn errors(n: usize, orders: &[usize], leaves: &[usize]) {
    let model = tuning::ErrorModel::laplace(Precision::F64);
    let mut worst: BTreeMap<usize, (f64, String)> = BTreeMap::new();
    let mut best: BTreeMap<usize, f64> = BTreeMap::new();
    print!("| p | geometry |");
    for l in leaves {
        print!(" leaf {l} |");
    }
    println!();
    println!("|---|---|{}", "---|".repeat(leaves.len()));
    let problems: Vec<(Geometry, Problem)> = Geometry::ALL
        .iter()
        .map(|&g| (g, Problem::new(g, n)))
        .collect();
    for &order in orders {
        for (g, p) in &problems {
            print!("| {order} | {} |", g.name());
            for &leaf in leaves {
                // The SVD tolerance the error model's E_p is defined with.
                let fmm = FmmBuilder::new(&p.points)
                    .order(order)
                    .leaf_size(leaf)
                    .cache_dir(CACHE)
                    .build_with::<SvdM2l<f64>>(SvdConfig {
                        rank: None,
                        tolerance: model.base_svd_tolerance(order),
                    })
                    .expect("build");
                let e = p.error(&fmm.evaluate(&p.q).expect("evaluate"));
                print!(" {e:.2e} |");
                let w = worst.entry(order).or_insert((0.0, String::new()));
                if e > w.0 {
                    *w = (e, format!("{} leaf {leaf}", g.name()));
                }
                let b = best.entry(order).or_insert(f64::INFINITY);
                *b = b.min(e);
            }
            println!();
        }
    }
    println!("\n| p | worst measured | where | best measured | model E_p |");
    println!("|---|---|---|---|---|");
    for (p, (e, at)) in &worst {
        println!(
            "| {p} | {e:.2e} | {at} | {:.2e} | {:.2e} |",
            best[p],
            model.order_error(*p).unwrap_or(f64::NAN)
        );
    }
}

/// With `orders=P leaves=L`: that setting; otherwise the one chosen for
/// `eps`.
fn memory(n: usize, g: Geometry, eps: f64, setting: Option<(usize, usize)>) {
    let points: Vec<f64> = g.points(n, 7);
    let q: Vec<f64> = charges(n, 11);
    let builder = FmmBuilder::new(&points);
    let builder = match setting {
        Some((p, l)) => builder.order(p).leaf_size(l),
        None => builder.tolerance(eps),
    };
    let fmm = builder.build_svd().expect("build");
    let _ = fmm.evaluate(&q).expect("evaluate");
    let s = fmm.summary();
    let m = fmm.memory();
    let mb = |b: usize| b as f64 / 1e6;
    println!(
        "{}: N {n}, p {} leaf {} depth {} boxes {} (8^depth = {:.1e})",
        g.name(),
        s.order,
        s.leaf_size,
        s.depth,
        s.n_boxes,
        8f64.powi(s.depth as i32)
    );
    println!(
        "  MB: expansions {:.1}, evaluation scratch {:.1}, points {:.1}, tree {:.1}, M2L interactions {:.1}, operators {:.1}, M2L operators {:.1}, total {:.1}",
        mb(m.expansions),
        mb(m.evaluation_scratch),
        mb(m.points),
        mb(m.tree),
        mb(m.m2l_interactions),
        mb(m.operators),
        mb(m.m2l),
        mb(m.total)
    );
    if let Some(kb) = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1).map(str::to_string))
        })
    {
        println!(
            "  peak resident memory of the process: {:.1} MB",
            kb.parse::<f64>().unwrap_or(0.0) / 1e3
        );
    }
}
