//! The `eval` subcommand: the distributed FMM on points and charges from
//! files (each rank reads its rows of a `.npy` file) or generated, the
//! result written in the input order, and per-rank figures.

use std::path::PathBuf;

use clap::Args;
use ferrofmm_field::{DenseM2l, FftM2l, M2lScheme, SvdM2l};
use ferrofmm_fmm::{DEFAULT_LEAF_SIZE, DEFAULT_ORDER};
use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d, Real};
use ferrofmm_mpi::{
    DistFmmOptions, DistOptions, DistributedFmm, DistributedTree, Geometry, agree_message,
};
use mpi::collective::SystemOperation;

use crate::eval_io::{my_rows, read_slice, write_out};
use crate::eval_report::{FIGURES, figures, report};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// Arguments of `eval`.
#[derive(Args)]
pub struct EvalArgs {
    /// Source points (also the targets): .npy (N x 3, float64 or float32,
    /// C order; each rank reads only its rows) or .csv (x,y,z per line;
    /// every rank reads the file and keeps its rows).
    #[arg(long, value_name = "FILE", required_unless_present = "generate")]
    pub(crate) sources: Option<PathBuf>,
    /// Charges, one per source: .npy (N) or .csv (one per line).
    #[arg(long, value_name = "FILE", required_unless_present = "generate")]
    pub(crate) charges: Option<PathBuf>,
    /// Output file, .npy or .csv: one potential per point, or potential and
    /// gradient (N x 4) with --gradients, float64, in the input order.
    /// Written to a temporary name and renamed once complete.
    #[arg(long, value_name = "FILE")]
    pub(crate) out: Option<PathBuf>,
    /// Instead of files: N points of this geometry (uniform, sphere,
    /// plummer, two-clusters; each rank generates its share) with zero-mean
    /// charges uniform in [-0.5, 0.5).
    #[arg(long, value_name = "GEOMETRY", conflicts_with_all = ["sources", "charges"])]
    pub(crate) generate: Option<String>,
    /// Number of points with --generate (all ranks together).
    #[arg(long, default_value_t = 1_000_000)]
    pub(crate) n: usize,
    /// Expansion order p.
    #[arg(long, short = 'p', default_value_t = DEFAULT_ORDER)]
    pub(crate) order: usize,
    /// Largest number of points in a leaf box.
    #[arg(long, default_value_t = DEFAULT_LEAF_SIZE)]
    pub(crate) leaf_size: usize,
    /// M2L scheme: svd, dense or fft.
    #[arg(long, default_value = "svd")]
    pub(crate) scheme: String,
    /// Float type of the run: f64 or f32 (inputs are read as f64 and
    /// rounded; the output is written as float64 either way).
    #[arg(long, default_value = "f64")]
    pub(crate) precision: String,
    /// Also evaluate the gradient.
    #[arg(long)]
    pub(crate) gradients: bool,
    /// Evaluations on one build (the same charges): the figures are the
    /// last one's.
    #[arg(long, default_value_t = 1)]
    pub(crate) repeats: usize,
    /// Compare this many sampled points with direct summation over all
    /// points (relative L2 error of the potential and the gradient; 0: no
    /// check).
    #[arg(long, default_value_t = 0, value_name = "TARGETS")]
    pub(crate) check: usize,
    /// Print one JSON object with per-rank figures (rank 0, last line of
    /// stdout) instead of the table.
    #[arg(long)]
    pub(crate) json: bool,
}

/// This rank's points and charges.
fn inputs(a: &EvalArgs, me: usize, size: usize) -> Result<(Vec<f64>, Vec<f64>), String> {
    if let Some(g) = &a.generate {
        let geom = Geometry::from_name(g).ok_or_else(|| format!("unknown geometry {g}"))?;
        let r = my_rows(a.n as u64, me, size);
        let n = (r.end - r.start) as usize;
        let points = geom.points::<f64>(n, 1000 + me as u64);
        let q = ferrofmm_fmm::charges(n, 2000 + me as u64);
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
