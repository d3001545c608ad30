//! The `eval` subcommand: the distributed FMM on points and charges from
//! files (each rank reads its rows of a `.npy` file) or generated, the
//! result written in the input order, and per-rank figures.

use std::path::{Path, PathBuf};

use clap::Args;
use ferrofmm_field::{DenseM2l, FftM2l, M2lScheme, SvdM2l};
use ferrofmm_fmm::{DEFAULT_LEAF_SIZE, DEFAULT_ORDER};
use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d, Real};
use ferrofmm_mpi::{
    DistFmmOptions, DistOptions, DistributedFmm, DistributedTree, EVAL_PHASES, EvalStats, Geometry,
    PHASES, agree_message, npy,
};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// Arguments of `eval`.
#[derive(Args)]
pub struct EvalArgs {
    /// Source points (also the targets): .npy (N x 3, float64 or float32,
    /// C order; each rank reads only its rows) or .csv (x,y,z per line;
    /// every rank reads the file and keeps its rows).
    #[arg(long, value_name = "FILE", required_unless_present = "generate")]
    sources: Option<PathBuf>,
    /// Charges, one per source: .npy (N) or .csv (one per line).
    #[arg(long, value_name = "FILE", required_unless_present = "generate")]
    charges: Option<PathBuf>,
    /// Output file, .npy or .csv: one potential per point, or potential and
    /// gradient (N x 4) with --gradients, float64, in the input order.
    /// Written to a temporary name and renamed once complete.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Instead of files: N points of this geometry (uniform, sphere,
    /// plummer, two-clusters; each rank generates its share) with zero-mean
    /// charges uniform in [-0.5, 0.5).
    #[arg(long, value_name = "GEOMETRY", conflicts_with_all = ["sources", "charges"])]
    generate: Option<String>,
    /// Number of points with --generate (all ranks together).
    #[arg(long, default_value_t = 1_000_000)]
    n: usize,
    /// Expansion order p.
    #[arg(long, short = 'p', default_value_t = DEFAULT_ORDER)]
    order: usize,
    /// Largest number of points in a leaf box.
    #[arg(long, default_value_t = DEFAULT_LEAF_SIZE)]
    leaf_size: usize,
    /// M2L scheme: svd, dense or fft.
    #[arg(long, default_value = "svd")]
    scheme: String,
    /// Float type of the run: f64 or f32 (inputs are read as f64 and
    /// rounded; the output is written as float64 either way).
    #[arg(long, default_value = "f64")]
    precision: String,
    /// Also evaluate the gradient.
    #[arg(long)]
    gradients: bool,
    /// Evaluations on one build (the same charges): the figures are the
    /// last one's.
    #[arg(long, default_value_t = 1)]
    repeats: usize,
    /// Compare this many sampled points with direct summation over all
    /// points (relative L2 error of the potential and the gradient; 0: no
    /// check).
    #[arg(long, default_value_t = 0, value_name = "TARGETS")]
    check: usize,
    /// Print one JSON object with per-rank figures (rank 0, last line of
    /// stdout) instead of the table.
    #[arg(long)]
    json: bool,
}

/// This rank's rows `[N r / R, N (r + 1) / R)`.
fn my_rows(n: u64, me: usize, size: usize) -> std::ops::Range<u64> {
    let at = |r: usize| (n as u128 * r as u128 / size as u128) as u64;
    at(me)..at(me + 1)
}

/// Values of a .csv file: numbers separated by commas or spaces, `#`
/// comments and blank lines skipped; every row must have `columns`.
fn read_csv(path: &Path, columns: usize) -> Result<Vec<f64>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let row: Vec<f64> = line
            .split([',', ' ', '\t'])
            .filter(|s| !s.is_empty())
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|e| format!("{}: line {}: {e}", path.display(), i + 1))?;
        if row.len() != columns {
            return Err(format!(
                "{}: line {}: {} values, expected {columns}",
                path.display(),
                i + 1,
                row.len()
            ));
        }
        out.extend(row);
    }
    Ok(out)
}

fn is_npy(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
}

/// This rank's rows of `path` (`columns` values per row) and the total
/// number of rows.
fn read_slice(
    path: &Path,
    columns: u64,
    me: usize,
    size: usize,
) -> Result<(Vec<f64>, u64), String> {
    if is_npy(path) {
        let h = npy::header(path)?;
        if h.columns != columns {
            return Err(format!(
                "{}: {} values per row, expected {columns}",
                path.display(),
                h.columns
            ));
        }
        let rows = my_rows(h.rows, me, size);
        Ok((npy::read_rows(path, &h, rows)?, h.rows))
    } else {
        let all = read_csv(path, columns as usize)?;
        let n = (all.len() as u64) / columns;
        let r = my_rows(n, me, size);
        let c = columns as usize;
        Ok((all[r.start as usize * c..r.end as usize * c].to_vec(), n))
    }
}

/// This rank's points and charges.
fn inputs(a: &EvalArgs, me: usize, size: usize) -> Result<(Vec<f64>, Vec<f64>), String> {
    if let Some(g) = &a.generate {
        let geom = Geometry::from_name(g).ok_or_else(|| format!("unknown geometry {g}"))?;
        let r = my_rows(a.n as u64, me, size);
        let n = (r.end - r.start) as usize;
        let points = geom.points(n, 1000 + me as u64);
        let mut rng = StdRng::seed_from_u64(2000 + me as u64);
        let q = (0..n).map(|_| rng.random::<f64>() - 0.5).collect();
        return Ok((points, q));
    }
    let (Some(s), Some(c)) = (&a.sources, &a.charges) else {
        return Err("give --sources and --charges, or --generate".into());
    };
    for input in [s, c] {
        if a.out.as_deref() == Some(input.as_path()) {
            return Err(format!("--out {} is an input file", input.display()));
        }
    }
    let (points, n) = read_slice(s, 3, me, size)?;
    let (q, m) = read_slice(c, 1, me, size)?;
    if n != m {
        return Err(format!(
            "{} holds {m} charges for the {n} points of {}",
            c.display(),
            s.display()
        ));
    }
    Ok((points, q))
}

/// Writes the values (`w` per point, this rank's input rows from
/// `first_row`) to `out`, through a temporary file renamed at the end.
fn write_out(
    world: &SimpleCommunicator,
    out: &Path,
    values: &[f64],
    w: usize,
    first_row: u64,
    total: u64,
) -> Result<(), String> {
    let me = world.rank();
    let tmp = out.with_extension(format!(
        "{}.part",
        out.extension().and_then(|e| e.to_str()).unwrap_or("")
    ));
    let result = if is_npy(out) {
        let start = if me == 0 {
            npy::create(&tmp, total, w as u64)
        } else {
            Ok(0)
        };
        let start = agree_message(world, start).map_err(|e| e.to_string())?;
        let mut s = start;
        world.process_at_rank(0).broadcast_into(&mut s);
        npy::write_rows(&tmp, s, w as u64, first_row, values)
    } else {
        // Ranks append their rows in turn.
        let mut r = Ok(());
        for turn in 0..world.size() {
            if turn == me {
                let text: String = values
                    .chunks_exact(w)
                    .map(|row| {
                        row.iter()
                            .map(|x| format!("{x:e}"))
                            .collect::<Vec<_>>()
                            .join(",")
                            + "\n"
                    })
                    .collect();
                r = std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .truncate(false)
                    .open(&tmp)
                    .and_then(|mut f| {
                        if me == 0 {
                            f.set_len(0)?;
                        }
                        std::io::Write::write_all(&mut f, text.as_bytes())
                    })
                    .map_err(|e| format!("{}: {e}", tmp.display()));
            }
            world.barrier();
        }
        r
    };
    agree_message(world, result).map_err(|e| e.to_string())?;
    if me == 0 {
        std::fs::rename(&tmp, out).map_err(|e| format!("{}: {e}", out.display()))?;
    }
    Ok(())
}

/// Figures of one rank, gathered on all: points, ghost points, boxes of the
/// local tree, send and receive partners, tree phase seconds (6) and bytes
/// (6), FMM setup seconds (3) and bytes, evaluation phase seconds (8) and
/// bytes (8), operator seconds (8: P2M .. P2P), and the CPU seconds of
/// the compute phases ([`EvalStats::compute_cpu_seconds`]).
const FIGURES: usize = 5 + 6 + 6 + 3 + 1 + 8 + 8 + 8 + 1;

fn figures<T: Real, S: M2lScheme<T>>(
    dtree: &DistributedTree,
    dfmm: &DistributedFmm<T, Laplace3d, S>,
    stats: &EvalStats,
) -> Vec<f64> {
    let s = dfmm.setup_stats();
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

/// Runs `eval` (a collective); returns the exit status.
pub fn run(world: &SimpleCommunicator, a: &EvalArgs) -> i32 {
    match (a.precision.as_str(), a.scheme.as_str()) {
        ("f64", "svd") => run_with::<f64, SvdM2l<f64>>(world, a),
        ("f64", "dense") => run_with::<f64, DenseM2l<f64>>(world, a),
        ("f64", "fft") => run_with::<f64, FftM2l<f64>>(world, a),
        ("f32", "svd") => run_with::<f32, SvdM2l<f32>>(world, a),
        ("f32", "dense") => run_with::<f32, DenseM2l<f32>>(world, a),
        ("f32", "fft") => run_with::<f32, FftM2l<f32>>(world, a),
        (p, s) => {
            if world.rank() == 0 {
                eprintln!("unknown --precision {p} or --scheme {s}: f64 or f32; svd, dense or fft");
            }
            2
        }
    }
}

fn run_with<T: Real, S: M2lScheme<T>>(world: &SimpleCommunicator, a: &EvalArgs) -> i32 {
    match eval::<T, S>(world, a) {
        Ok(()) => 0,
        Err(e) => {
            if world.rank() == 0 {
                eprintln!("error: {e}");
            }
            1
        }
    }
}

fn eval<T: Real, S: M2lScheme<T>>(world: &SimpleCommunicator, a: &EvalArgs) -> Result<(), String> {
    let me = world.rank() as usize;
    let size = world.size() as usize;
    let t0 = std::time::Instant::now();
    let (points, q) = agree_message(world, inputs(a, me, size)).map_err(|e| e.to_string())?;
    let read_s = t0.elapsed().as_secs_f64();
    let dtree = DistributedTree::build(world, &points, &DistOptions::adaptive(a.leaf_size))
        .map_err(|e| e.to_string())?;
    let mode = if a.gradients {
        EvalMode::PotentialGradient
    } else {
        EvalMode::Potential
    };
    let options = DistFmmOptions {
        order: a.order,
        mode,
    };
    let dfmm =
        DistributedFmm::<T, _, S>::build(world, &dtree, Laplace3d, &Default::default(), &options)
            .map_err(|e| e.to_string())?;
    let q_t: Vec<T> = q.iter().map(|&x| T::from_f64(x)).collect();
    let mut last = None;
    for _ in 0..a.repeats.max(1) {
        last = Some(dfmm.evaluate(world, &q_t).map_err(|e| e.to_string())?);
    }
    let Some((values, stats)) = last else {
        return Err("no evaluation".into());
    };
    let values: Vec<f64> = values.iter().map(|v| v.to_f64()).collect();
    if let Some(out) = &a.out {
        let first: u64 = dtree.input_counts[..me].iter().sum();
        let total: u64 = dtree.input_counts.iter().sum();
        write_out(world, out, &values, mode.values_per_target(), first, total)?;
    }
    let errors = (a.check > 0).then(|| {
        let first: u64 = dtree.input_counts[..me].iter().sum();
        let total: u64 = dtree.input_counts.iter().sum();
        check_direct(world, &points, &q, &values, mode, first, total, a.check)
    });
    drop(points);
    let mut mine = figures(&dtree, &dfmm, &stats);
    mine.push(stats.compute_cpu_seconds);
    let mut all = vec![0.0f64; FIGURES * size];
    world.all_gather_into(&mine[..], &mut all[..]);
    if me == 0 {
        report(a, &all, size, read_s, errors);
    }
    Ok(())
}

/// Relative L2 errors `[potential, gradient]` of `values` (this rank's
/// input points, `w` values each) at `k` points sampled evenly over the
/// global input order, against direct summation over all points (a
/// collective: each rank sums its own points' field at the sample, then
/// one `all_reduce`). The gradient error is 0 without gradients.
#[allow(clippy::too_many_arguments)]
fn check_direct(
    world: &SimpleCommunicator,
    points: &[f64],
    q: &[f64],
    values: &[f64],
    mode: EvalMode,
    first: u64,
    total: u64,
    k: usize,
) -> [f64; 2] {
    let w = mode.values_per_target();
    let k = k.min(total as usize);
    let ids: Vec<u64> = (0..k as u64).map(|j| j * total / k as u64).collect();
    // Sample coordinates and FMM values, from their owners to all.
    let mut mine = vec![0.0; (3 + w) * k];
    for (j, &id) in ids.iter().enumerate() {
        if id >= first && id < first + (q.len() as u64) {
            let i = (id - first) as usize;
            mine[3 * j..3 * j + 3].copy_from_slice(&points[3 * i..3 * i + 3]);
            mine[3 * k + w * j..3 * k + w * (j + 1)].copy_from_slice(&values[w * i..w * (i + 1)]);
        }
    }
    let mut shared = vec![0.0; mine.len()];
    world.all_reduce_into(&mine[..], &mut shared[..], SystemOperation::sum());
    let (sample, fmm) = shared.split_at(3 * k);
    let mut direct = vec![0.0; w * k];
    Laplace3d.evaluate(mode, points, q, sample, &mut direct);
    let mut sum = vec![0.0; w * k];
    world.all_reduce_into(&direct[..], &mut sum[..], SystemOperation::sum());
    let mut s = [0.0f64; 4];
    for (f, d) in fmm.chunks_exact(w).zip(sum.chunks_exact(w)) {
        for c in 0..w {
            let g = usize::from(c > 0);
            s[2 * g] += (f[c] - d[c]) * (f[c] - d[c]);
            s[2 * g + 1] += d[c] * d[c];
        }
    }
    let rel = |num: f64, den: f64| if den > 0.0 { (num / den).sqrt() } else { 0.0 };
    [rel(s[0], s[1]), rel(s[2], s[3])]
}

/// Max over mean of column `i` of the per-rank figures.
fn imbalance(rows: &[&[f64]], f: impl Fn(&[f64]) -> f64) -> f64 {
    let v: Vec<f64> = rows.iter().map(|r| f(r)).collect();
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let max = v.iter().copied().fold(0.0, f64::max);
    if mean > 0.0 { max / mean } else { 1.0 }
}

fn report(a: &EvalArgs, all: &[f64], size: usize, read_s: f64, errors: Option<[f64; 2]>) {
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
            })
        })
        .collect();
    if a.json {
        let j = serde_json::json!({
            "command": "eval",
            "ranks": size,
            "n": rows.iter().map(|r| r[0]).sum::<f64>(),
            "order": a.order,
            "leaf_size": a.leaf_size,
            "scheme": a.scheme,
            "precision": a.precision,
            "gradients": a.gradients,
            "input": a.generate.clone().unwrap_or_else(|| "files".into()),
            "threads_per_rank": rayon_threads(),
            "read_seconds": read_s,
            "imbalance_points": points_imb,
            "imbalance_eval_seconds": time_imb,
            "eval_seconds_max": rows.iter().map(|r| eval_s(r)).fold(0.0, f64::max),
            "compute_cpu_seconds_max": rows.iter().map(|r| r[45]).fold(0.0, f64::max),
            "compute_cpu_seconds_total": rows.iter().map(|r| r[45]).sum::<f64>(),
            "check": errors.map(|e| serde_json::json!({
                "samples": a.check,
                "potential_error": e[0],
                "gradient_error": if a.gradients { serde_json::json!(e[1]) } else { serde_json::Value::Null },
            })),
            "per_rank": per_rank,
        });
        println!("{j}");
        return;
    }
    println!(
        "{size} ranks, order {}, leaf {}, {} M2L; imbalance: points {points_imb:.4}, evaluation time {time_imb:.4}",
        a.order, a.leaf_size, a.scheme
    );
    if let Some(e) = errors {
        println!(
            "check against direct summation at {} points: potential error {:.3e}{}",
            a.check,
            e[0],
            if a.gradients {
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

fn rayon_threads() -> usize {
    std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}
