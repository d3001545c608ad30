//! Per-rank figures of the `eval` command, gathered on every rank, and
//! their report (a table, or one JSON object) on rank 0.

use ferrofmm_mpi::{DistChoice, DistributedTree, EVAL_PHASES, EvalStats, PHASES, SetupStats};

/// One evaluation of a run: its order and, when checked, the relative L2
/// errors `[potential, gradient]` against direct summation.
pub(crate) struct Attempt {
    pub(crate) order: usize,
    pub(crate) errors: Option<[f64; 2]>,
}

/// What rank 0 reports besides the per-rank figures: the run's settings
/// and parameters (given or chosen for a tolerance) and its outcome. The
/// `eval` command fills it in; the report reads nothing else.
pub(crate) struct RunInfo<'a> {
    /// One JSON object instead of the table.
    pub(crate) json: bool,
    pub(crate) kernel: String,
    /// Float type (`f32` or `f64`).
    pub(crate) precision: &'a str,
    pub(crate) gradients: bool,
    /// The generated geometry, or `None` for points from files.
    pub(crate) input: Option<&'a str>,
    /// The tolerance asked for, if any.
    pub(crate) tolerance: Option<f64>,
    pub(crate) order: usize,
    pub(crate) leaf_size: usize,
    pub(crate) scheme: &'static str,
    pub(crate) svd_tolerance: Option<f64>,
    /// The parameters chosen for the tolerance.
    pub(crate) choice: Option<&'a DistChoice>,
    pub(crate) attempts: &'a [Attempt],
    pub(crate) samples: usize,
    pub(crate) read_s: f64,
    pub(crate) threads: usize,
    /// What the operator cache did on rank 0, in words (`hit`, `miss
    /// (computed, saved)`, `off (--no-cache)`, `memory only: ...`).
    pub(crate) cache: String,
    /// The cache folder (`None`: none).
    pub(crate) cache_dir: Option<String>,
    /// A run with stresslets or the pressure: lines for the table and an
    /// object for the JSON (`layers`) on the Laplace FMM and the check
    /// of velocity and pressure.
    pub(crate) layers: Option<(Vec<String>, serde_json::Value)>,
}

/// Figures of one rank, gathered on all: points, ghost points, boxes of the
/// local tree, send and receive partners, tree phase seconds (6) and bytes
/// (6), FMM setup seconds (3) and bytes, evaluation phase seconds (8) and
/// bytes (8), operator seconds (8: P2M .. P2P), and the CPU seconds of
/// the compute phases ([`EvalStats::compute_cpu_seconds`]), and the boxes
/// whose expansions the rank computes.
pub(crate) const FIGURES: usize = 5 + 6 + 6 + 3 + 1 + 8 + 8 + 8 + 1 + 1;

pub(crate) fn figures(dtree: &DistributedTree, s: &SetupStats, stats: &EvalStats) -> Vec<f64> {
    let mut v = vec![
        dtree.points.len() as f64,
        s.ghost_points as f64,
        s.boxes as f64,
        s.send_partners as f64,
        s.recv_partners as f64,
    ];
    v.extend(dtree.stats.seconds);
    v.extend(dtree.stats.bytes_sent.map(|b| b as f64));
    v.extend(s.seconds);
    v.push(s.bytes_sent as f64);
    v.extend(stats.seconds);
    v.extend(stats.bytes_sent.map(|b| b as f64));
    v.extend(
        stats.passes.operators()[..8]
            .iter()
            .map(|o| o.1.as_secs_f64()),
    );
    v
}

/// Max over mean of column `i` of the per-rank figures.
fn imbalance(rows: &[&[f64]], f: impl Fn(&[f64]) -> f64) -> f64 {
    let v: Vec<f64> = rows.iter().map(|r| f(r)).collect();
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let max = v.iter().copied().fold(0.0, f64::max);
    if mean > 0.0 { max / mean } else { 1.0 }
}

/// Prints the report of a run on rank 0: the table, or one JSON object.
pub(crate) fn report(info: &RunInfo<'_>, all: &[f64], size: usize) {
    let errors = info.attempts.last().and_then(|t| t.errors);
    let tolerance_met = info
        .tolerance
        .zip(errors)
        .map(|(eps, e)| e[0].max(e[1]) <= eps);
    let rows: Vec<&[f64]> = all.chunks_exact(FIGURES).collect();
    let eval_s = |r: &[f64]| r[21..29].iter().sum::<f64>();
    let points_imb = imbalance(&rows, |r| r[0]);
    let time_imb = imbalance(&rows, eval_s);
    let op_names = ["P2M", "M2M", "M2L", "P2L", "L2L", "L2P", "M2P", "P2P"];
    let per_rank: Vec<serde_json::Value> = rows
        .iter()
        .enumerate()
        .map(|(r, x)| {
            let named =
                |names: &[&str], vals: &[f64]| -> serde_json::Map<String, serde_json::Value> {
                    names
                        .iter()
                        .zip(vals)
                        .map(|(n, v)| (n.to_string(), serde_json::json!(v)))
                        .collect()
                };
            serde_json::json!({
                "rank": r,
                "points": x[0],
                "ghost_points": x[1],
                "local_tree_boxes": x[2],
                "send_partners": x[3],
                "recv_partners": x[4],
                "tree_seconds": named(&PHASES, &x[5..11]),
                "tree_bytes_sent": named(&PHASES, &x[11..17]),
                "fmm_setup_seconds": named(&["plans", "local tree", "operators"], &x[17..20]),
                "fmm_setup_bytes_sent": x[20],
                "eval_seconds": named(&EVAL_PHASES, &x[21..29]),
                "eval_bytes_sent": named(&EVAL_PHASES, &x[29..37]),
                "eval_total_seconds": eval_s(x),
                "eval_total_bytes_sent": x[29..37].iter().sum::<f64>(),
                "operator_seconds": named(&op_names, &x[37..45]),
                "compute_cpu_seconds": x[45],
                "active_boxes": x[46],
            })
        })
        .collect();
    if info.json {
        let j = serde_json::json!({
            "command": "eval",
            "ranks": size,
            "n": rows.iter().map(|r| r[0]).sum::<f64>(),
            "kernel": info.kernel,
            "order": info.order,
            "leaf_size": info.leaf_size,
            "scheme": info.scheme,
            "svd_tolerance": info.svd_tolerance,
            "precision": info.precision,
            "gradients": info.gradients,
            "input": info.input.unwrap_or("files"),
            "threads_per_rank": info.threads,
            "cache": info.cache,
            "cache_dir": info.cache_dir,
            "tolerance": info.tolerance,
            "chosen": info.choice.map(|c| serde_json::json!({
                "order": c.order,
                "leaf_size": c.leaf_size,
                "svd_tolerance": c.svd_tolerance,
                "predicted_error": c.predicted_error,
                "sample_points": c.sample,
                "model": c.chosen.as_ref().map(|p| p.model.clone()),
                "calibrated": c.calibrated,
            })),
            "attempts": info.attempts.iter().map(|t| serde_json::json!({
                "order": t.order,
                "potential_error": t.errors.map(|e| e[0]),
                "gradient_error": t.errors.filter(|_| info.gradients).map(|e| e[1]),
            })).collect::<Vec<_>>(),
            "tolerance_met": tolerance_met,
            "read_seconds": info.read_s,
            "imbalance_points": points_imb,
            "imbalance_eval_seconds": time_imb,
            "eval_seconds_max": rows.iter().map(|r| eval_s(r)).fold(0.0, f64::max),
            "compute_cpu_seconds_max": rows.iter().map(|r| r[45]).fold(0.0, f64::max),
            "compute_cpu_seconds_total": rows.iter().map(|r| r[45]).sum::<f64>(),
            "check": errors.map(|e| serde_json::json!({
                "samples": info.samples,
                "potential_error": e[0],
                "gradient_error": if info.gradients { serde_json::json!(e[1]) } else { serde_json::Value::Null },
            })),
            "per_rank": per_rank,
            "layers": info.layers.as_ref().map(|l| l.1.clone()),
        });
        println!("{j}");
        return;
    }
    println!(
        "{size} ranks x {} threads, {}, order {}, leaf {}, {} M2L; imbalance: points {points_imb:.4}, evaluation time {time_imb:.4}",
        info.threads, info.kernel, info.order, info.leaf_size, info.scheme
    );
    match &info.cache_dir {
        Some(dir) => println!("operator cache (rank 0): {} in {dir}", info.cache),
        None => println!("operator cache: {}", info.cache),
    }

    if let (Some(eps), Some(c)) = (info.tolerance, info.choice) {
        println!(
            "tolerance {eps:e}: {}chosen order {}, leaf {}, predicted error {:.2e} (from {} sampled points{}){}",
            if info.layers.is_some() {
                "Stokeslet FMM "
            } else {
                ""
            },
            c.order,
            c.leaf_size,
            c.predicted_error,
            c.sample,
            if c.calibrated {
                "; costs calibrated on this machine"
            } else {
                ""
            },
            match tolerance_met {
                Some(true) => format!(", met after {} evaluation(s)", info.attempts.len()),
                Some(false) => ", NOT met at the highest order tried".to_string(),
                None => ", not verified".to_string(),
            }
        );
    }
    if let Some((lines, _)) = &info.layers {
        // The layers' own check replaces the Stokeslet FMM's alone.
        for line in lines {
            println!("{line}");
        }
    } else if let Some(e) = errors {
        println!(
            "check against direct summation at {} points: potential error {:.3e}{}",
            info.samples,
            e[0],
            if info.gradients {
                format!(", gradient error {:.3e}", e[1])
            } else {
                String::new()
            }
        );
    }
    println!("rank   points   ghosts  eval s   MB sent  (ghosts, coarse, routing)  setup s");
    for (r, x) in rows.iter().enumerate() {
        println!(
            "{r:>4} {:>8} {:>8} {:>7.3} {:>9.3}  ({:.3}, {:.3}, {:.3})  {:.3}",
            x[0],
            x[1],
            eval_s(x),
            x[29..37].iter().sum::<f64>() / 1e6,
            x[31] / 1e6,
            (x[32] + x[34]) / 1e6,
            (x[29] + x[36]) / 1e6,
            x[17..20].iter().sum::<f64>()
        );
    }
}
