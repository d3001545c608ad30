//! The `eval` subcommand: the distributed FMM on points and densities from
//! files (each rank reads its rows of a `.npy` file) or generated, for any
//! built-in kernel, at a given order or a requested accuracy (chosen from a
//! sample, then verified), the result written in the input order, and
//! per-rank figures.

use std::path::PathBuf;

use clap::Args;
use ferrofmm_field::{
    CacheLocation, CacheOff, CacheSetting, CacheStatus, DenseM2l, FftM2l, M2lScheme, SvdConfig,
    SvdM2l,
};
use ferrofmm_fmm::verify::MAX_VERIFY_RETRIES;
use ferrofmm_fmm::{DEFAULT_LEAF_SIZE, DEFAULT_ORDER, FmmError, SchemeChoice, effective_tolerance};
use ferrofmm_kernels::{
    EvalMode, Kernel, KernelChoice, KernelVisitor, Precision, Real, SourceKind,
};
use ferrofmm_mpi::{
    DistChoice, DistFmmOptions, DistOptions, DistributedFmm, DistributedTree, Geometry,
    agree_options, agree_text, choose_parameters, sampled_errors,
};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::eval_io::{my_rows, read_slice, reader, write_out};
use crate::eval_report::{Attempt, FIGURES, RunInfo, figures, report};
use ferrofmm_io::Contents;

/// Targets a verification samples when `--check` does not say.
const VERIFY_SAMPLE: usize = 200;

/// Arguments of `eval`.
#[derive(Args)]
pub struct EvalArgs {
    /// Source points (also the targets): .npy (N x 3, float64 or float32;
    /// of a C-order file each rank reads only its rows), raw .f64
    /// (little-endian float64, x, y, z per point; each rank reads only
    /// its rows) or .csv (x,y,z per line; every rank reads the file and
    /// keeps its rows).
    #[arg(long, value_name = "FILE", required_unless_present = "generate")]
    pub(crate) sources: Option<PathBuf>,
    /// Charges, one per source: .npy (N, or N x c for a kernel with c
    /// components: re, im for helmholtz:K; fx, fy, fz for stokes), .csv
    /// or raw .f64. For helmholtz:K also a complex .npy array (N,
    /// complex128 or complex64: the .npy output is then complex128) or
    /// real charges alone (zero imaginary parts).
    #[arg(long, value_name = "FILE", required_unless_present_any = ["generate", "dipoles"])]
    pub(crate) charges: Option<PathBuf>,
    /// Dipole vectors, one per source: .npy or .csv (N x 3, or N x 3c:
    /// nx_re, nx_im, ny_re, ... for helmholtz:K, or complex N x 3, or real
    /// vectors alone); with --charges, both.
    #[arg(long, value_name = "FILE")]
    pub(crate) dipoles: Option<PathBuf>,
    /// Output file, .npy or .csv: the potential (c columns), and the
    /// gradient (3c more) with --gradients, float64, in the input order
    /// (complex128, one column per quantity, after a complex .npy input).
    /// Written to a temporary name and renamed once complete.
    #[arg(long, value_name = "FILE")]
    pub(crate) out: Option<PathBuf>,
    /// Instead of files: N points of this geometry (uniform, sphere,
    /// plummer, two-clusters; each rank generates its share) with zero-mean
    /// charges uniform in [-0.5, 0.5).
    #[arg(long, value_name = "GEOMETRY", conflicts_with_all = ["sources", "charges", "dipoles"])]
    pub(crate) generate: Option<String>,
    /// Number of points with --generate (all ranks together).
    #[arg(long, default_value_t = 1_000_000)]
    pub(crate) n: usize,
    /// Kernel (see `KernelChoice::help`).
    #[arg(long, default_value = "laplace", help = format!("Kernel: {}", KernelChoice::help()))]
    pub(crate) kernel: String,
    /// Expansion order p (not with --tolerance). Alone, the leaf size and
    /// the scheme (with --scheme auto) are chosen for it from a sample of
    /// the points; without --order and --tolerance the run is chosen for
    /// the default tolerance (1e-6; 1e-4 in f32) and verified.
    #[arg(long, short = 'p', conflicts_with = "tolerance")]
    pub(crate) order: Option<usize>,
    /// Largest number of points in a leaf box (not with --tolerance;
    /// alone, with order 6).
    #[arg(long, conflicts_with = "tolerance")]
    pub(crate) leaf_size: Option<usize>,
    /// Requested relative L2 error (default 1e-6, 1e-4 in f32, unless
    /// --order or --leaf-size is given): order, leaf size and SVD tolerance
    /// chosen from a sample of the points (at most 200,000, gathered on
    /// rank 0), and the error checked afterwards (see --verify).
    #[arg(long, value_name = "EPS")]
    pub(crate) tolerance: Option<f64>,
    /// With --tolerance: `on` (default) compares the result with direct
    /// summation at sampled points (--check of them, or 200) and raises
    /// the order, at most twice, while the error is above EPS; `off`
    /// trusts the prediction.
    #[arg(long, default_value = "on", value_parser = ["on", "off"])]
    pub(crate) verify: String,
    /// M2L scheme (see `SchemeChoice::help`).
    #[arg(long, default_value = "auto", value_parser = ["auto", "svd", "dense", "fft"], help = SchemeChoice::help())]
    pub(crate) scheme: String,
    /// Float type of the run: f64 or f32 (inputs are read as f64 and
    /// rounded; the output is written as float64 either way).
    #[arg(long, default_value = "f64", value_parser = ["f64", "f32"])]
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
    /// check, unless --tolerance verifies).
    #[arg(long, default_value_t = 0, value_name = "TARGETS")]
    pub(crate) check: usize,
    /// Directory of the operator cache: rank 0 computes (or loads) the
    /// operators, the other ranks load them.
    /// Default: FERROFMM_CACHE (a folder, or `off`), else
    /// $XDG_CACHE_HOME/ferrofmm, else ~/.cache/ferrofmm; at most
    /// FERROFMM_CACHE_SIZE (default 2G) kept, least recently used first out.
    #[arg(long, value_name = "DIR")]
    pub(crate) cache_dir: Option<PathBuf>,
    /// Keep the operators in memory only (every rank computes them).
    #[arg(long, conflicts_with = "cache_dir")]
    pub(crate) no_cache: bool,
    /// Threads per rank (default: RAYON_NUM_THREADS, else the node's cores
    /// divided among the ranks on it).
    #[arg(long, value_name = "T")]
    pub(crate) threads: Option<usize>,
    /// Print one JSON object with per-rank figures (rank 0, last line of
    /// stdout) instead of the table.
    #[arg(long)]
    pub(crate) json: bool,
}

/// This rank's points and densities (`kind`, `kernel.values_per_source`
/// per point), as read or generated.
struct Inputs {
    points: Vec<f64>,
    densities: Vec<f64>,
    kind: SourceKind,
    /// The densities came as a complex `.npy` array: a `.npy` output is
    /// complex too.
    complex: bool,
}

fn inputs(
    world: &SimpleCommunicator,
    a: &EvalArgs,
    c: usize,
    me: usize,
    size: usize,
) -> Result<Inputs, String> {
    if let Some(g) = &a.generate {
        let geom = Geometry::from_name(g).ok_or_else(|| format!("unknown geometry {g}"))?;
        let r = my_rows(a.n as u64, me, size);
        let n = (r.end - r.start) as usize;
        // Points and charges alone, before any tree: refused beyond this
        // rank's share of the memory limit rather than killed for memory.
        let limit = agree_text(world, reader(world))?.limit();
        let bytes = (n as u128) * (3 + c as u128) * 8;
        if let Some(limit) = limit.filter(|&l| bytes > l as u128) {
            return Err(format!(
                "--n {}: this rank's {n} points and charges alone need {}, more than its share \
                 of the memory limit, {} (the memory available, or FERROFMM_MEMORY_LIMIT, \
                 divided among the ranks of a node): use more ranks or nodes, or a smaller --n",
                a.n,
                ferrofmm_io::human_bytes(u64::try_from(bytes).unwrap_or(u64::MAX)),
                ferrofmm_io::human_bytes(limit)
            ));
        }
        return Ok(Inputs {
            points: geom.points::<f64>(n, 1000 + me as u64),
            densities: ferrofmm_fmm::charges(c * n, 2000 + me as u64),
            kind: SourceKind::Charge,
            complex: false,
        });
    }
    let Some(s) = &a.sources else {
        return Err("give --sources and --charges (or --dipoles), or --generate".into());
    };
    let reader = agree_text(world, reader(world))?;
    // Each file is read, then its outcome agreed (a collective), so that a
    // file one rank cannot read is the same error on every rank.
    let (points, n, _) = agree_text(world, read_slice(&reader, s, Contents::Points, me, size))?;
    // The densities of a complex kernel: complex .npy arrays, re, im
    // pairs or real values alone (zero imaginary parts).
    let complex = KernelChoice::parse(&a.kernel).is_ok_and(|k| k.description().complex);
    let mut complex_file = false;
    let mut read = |path: &Option<PathBuf>, contents: Contents| {
        let Some(p) = path else { return Ok(None) };
        let (v, m, is_complex) = agree_text(world, read_slice(&reader, p, contents, me, size))?;
        complex_file |= is_complex;
        if m != n {
            return Err(format!(
                "{} holds {m} {} for the {n} points of {}: give one per point",
                p.display(),
                contents.noun(),
                s.display()
            ));
        }
        Ok(Some(v))
    };
    let charges = read(&a.charges, Contents::charges(c, complex))?;
    let dipoles = read(&a.dipoles, Contents::dipoles(c, complex))?;
    let (kind, densities) = match (charges, dipoles) {
        (Some(q), None) => (SourceKind::Charge, q),
        (None, Some(d)) => (SourceKind::Dipole, d),
        (Some(q), Some(d)) => (
            SourceKind::ChargeDipole,
            q.chunks_exact(c)
                .zip(d.chunks_exact(3 * c))
                .flat_map(|(q, d)| q.iter().chain(d).copied())
                .collect(),
        ),
        (None, None) => return Err("give --charges or --dipoles".into()),
    };
    Ok(Inputs {
        points,
        densities,
        kind,
        complex: complex_file,
    })
}

/// Every option of `eval` that shapes the result or where it goes, as
/// (name, value) pairs: they must be the same on every rank
/// ([`agree_options`]). Only `--threads` may differ between ranks.
fn shared_options(a: &EvalArgs) -> Vec<(&'static str, String)> {
    fn given<T: std::fmt::Display>(v: Option<T>) -> String {
        v.map_or_else(|| "(not given)".into(), |v| v.to_string())
    }
    let path = |p: &Option<PathBuf>| given(p.as_ref().map(|p| p.display()));
    vec![
        ("--sources", path(&a.sources)),
        ("--charges", path(&a.charges)),
        ("--dipoles", path(&a.dipoles)),
        ("--out", path(&a.out)),
        ("--generate", given(a.generate.as_ref())),
        ("--n", a.n.to_string()),
        ("--kernel", a.kernel.clone()),
        ("--order", given(a.order)),
        ("--leaf-size", given(a.leaf_size)),
        ("--tolerance", given(a.tolerance)),
        ("--verify", a.verify.clone()),
        ("--scheme", a.scheme.clone()),
        ("--precision", a.precision.clone()),
        ("--gradients", a.gradients.to_string()),
        ("--repeats", a.repeats.to_string()),
        ("--check", a.check.to_string()),
        ("--cache-dir", path(&a.cache_dir)),
        ("--no-cache", a.no_cache.to_string()),
        ("--json", a.json.to_string()),
    ]
}

/// The output: checked before any work, on every rank (a `.csv` or `.npy`
/// name, not a directory, not an input, in a directory that takes a new
/// file), agreed.
fn check_output(a: &EvalArgs) -> Result<(), String> {
    let Some(out) = &a.out else { return Ok(()) };
    let inputs: Vec<(&'static str, &std::path::Path)> = [
        ("--sources", &a.sources),
        ("--charges", &a.charges),
        ("--dipoles", &a.dipoles),
    ]
    .into_iter()
    .filter_map(|(flag, p)| p.as_deref().map(|p| (flag, p)))
    .collect();
    ferrofmm_io::output::check(out, &inputs).map_err(|e| e.to_string())
}

/// Threads of this rank: `--threads`, else `RAYON_NUM_THREADS`, else the
/// cores of the node shared evenly among its ranks; a request above that
/// share is lowered to it, with a note (`ferrofmm_io::threads`, as in
/// `ferrofmm`). Rank 0 prints the note.
fn set_threads(world: &SimpleCommunicator, a: &EvalArgs) -> Result<usize, String> {
    let on_node = world.split_shared(world.rank()).size().max(1) as usize;
    let threads = ferrofmm_io::threads::choose(a.threads, on_node).map_err(|e| e.to_string())?;
    if let Some(note) = threads.note.as_ref().filter(|_| world.rank() == 0) {
        eprintln!("{note}");
    }
    // Fails only when the pool was already built (not in this program).
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.count)
        .build_global();
    Ok(rayon::current_num_threads())
}

/// Runs `eval` (a collective); returns the exit status.
pub fn run(world: &SimpleCommunicator, a: &EvalArgs) -> i32 {
    let fail = |e: String| {
        if world.rank() == 0 {
            eprintln!("error: {e}");
        }
        1
    };
    // Every rank was given the same arguments (checked first), so parsing
    // them has the same outcome everywhere.
    if let Err(e) = agree_options(world, &shared_options(a)) {
        return fail(e);
    }
    let kernel = match KernelChoice::parse(&a.kernel) {
        Ok(k) => k,
        Err(e) => return fail(format!("--kernel {e}")),
    };
    if a.dipoles.is_some()
        && let Err(e) = kernel.check_dipoles()
    {
        return fail(e);
    }
    // The environment may differ between ranks: agreed.
    let threads = match agree_text(world, set_threads(world, a)) {
        Ok(t) => t,
        Err(e) => return fail(e),
    };
    if let Err(e) = agree_text(world, check_output(a)) {
        return fail(e);
    }
    match kernel.visit(WithKernel { world, a, threads }) {
        Ok(()) => 0,
        Err(e) => fail(e),
    }
}

/// The rest of `eval` for the kernel `--kernel` names.
struct WithKernel<'a> {
    world: &'a SimpleCommunicator,
    a: &'a EvalArgs,
    threads: usize,
}

/// What the parameters were: given, or chosen for a tolerance.
#[derive(Clone)]
struct Plan {
    pub(crate) order: usize,
    pub(crate) leaf_size: usize,
    pub(crate) scheme: &'static str,
    pub(crate) svd_tolerance: Option<f64>,
    pub(crate) choice: Option<DistChoice>,
    /// The tolerance asked for or the default one (`None`: an order, or an
    /// order and a leaf size, given without one).
    pub(crate) tolerance: Option<f64>,
}

impl KernelVisitor for WithKernel<'_> {
    type Output = Result<(), String>;

    fn visit<K: Kernel>(self, kernel: K) -> Result<(), String> {
        let (world, a) = (self.world, self.a);
        let me = world.rank() as usize;
        let size = world.size() as usize;
        let t0 = std::time::Instant::now();
        let c = kernel.components();
        let input = agree_text(world, inputs(world, a, c, me, size))?;
        let read_s = t0.elapsed().as_secs_f64();
        let mode = if a.gradients {
            EvalMode::PotentialGradient
        } else {
            EvalMode::Potential
        };
        if !kernel.supports(input.kind, mode) {
            return Err(format!(
                "kernel {} does not take {} sources",
                kernel.name(),
                input.kind.name()
            ));
        }
        let precision = if a.precision == "f32" {
            Precision::F32
        } else {
            Precision::F64
        };
        // clap checked the name.
        let scheme = SchemeChoice::parse(&a.scheme)?;
        // The one default rule: no order and no tolerance means the
        // default tolerance; an order alone gets its leaf size and scheme
        // from the cost model; an order and a leaf size are used as given.
        let eps = effective_tolerance(
            a.tolerance,
            a.order.or(a.leaf_size.map(|_| DEFAULT_ORDER)),
            precision,
        );
        let plan = match (eps, a.order, a.leaf_size) {
            (None, Some(_), Some(_)) | (None, None, _) => Plan {
                order: a.order.unwrap_or(DEFAULT_ORDER),
                leaf_size: a.leaf_size.unwrap_or(DEFAULT_LEAF_SIZE),
                scheme: match scheme {
                    SchemeChoice::Auto if SchemeChoice::auto_is_fft(&kernel) => "fft",
                    SchemeChoice::Auto => "svd",
                    s => s.name(),
                },
                svd_tolerance: None,
                choice: None,
                tolerance: None,
            },
            (eps, order, _) => {
                let shape = scheme.shape();
                let choice = choose_parameters(
                    world,
                    &input.points,
                    &kernel,
                    eps,
                    order,
                    precision,
                    mode,
                    shape,
                    a.cache_dir.is_some(),
                )
                .map_err(|e| e.to_string())?;
                Plan {
                    order: choice.order,
                    leaf_size: choice.leaf_size,
                    scheme: SchemeChoice::of_shape(choice.shape).name(),
                    svd_tolerance: Some(choice.svd_tolerance),
                    choice: Some(choice),
                    tolerance: eps,
                }
            }
        };
        let run = Run {
            world,
            a,
            kernel,
            input,
            mode,
            plan,
            read_s,
            threads: self.threads,
        };
        match (precision, run.plan.scheme) {
            (Precision::F64, "svd") => run.go::<f64, SvdM2l<f64>>(),
            (Precision::F64, "dense") => run.go::<f64, DenseM2l<f64>>(),
            (Precision::F64, _) => run.go::<f64, FftM2l<f64>>(),
            (_, "svd") => run.go::<f32, SvdM2l<f32>>(),
            (_, "dense") => run.go::<f32, DenseM2l<f32>>(),
            (_, _) => run.go::<f32, FftM2l<f32>>(),
        }
    }
}

/// The configuration of a scheme for an SVD tolerance (`None`: the
/// scheme's default; only the SVD scheme has one).
trait SchemeConfig<T: Real>: M2lScheme<T> {
    fn config(svd_tolerance: Option<f64>) -> Self::Config;
}

impl<T: Real> SchemeConfig<T> for SvdM2l<T> {
    fn config(svd_tolerance: Option<f64>) -> SvdConfig {
        SvdConfig {
            rank: None,
            tolerance: svd_tolerance.unwrap_or(0.0),
        }
    }
}

impl<T: Real> SchemeConfig<T> for DenseM2l<T> {
    fn config(_: Option<f64>) -> Self::Config {
        Default::default()
    }
}

impl<T: Real> SchemeConfig<T> for FftM2l<T> {
    fn config(_: Option<f64>) -> Self::Config {
        Default::default()
    }
}

/// [`ferrofmm_fmm::check_finite_output`] on this rank's values (the
/// target index made global: input rows before this rank added; the
/// largest density over all ranks), agreed by every rank (a collective).
fn finite_output<T: Real>(
    world: &SimpleCommunicator,
    dtree: &DistributedTree,
    values: &[T],
    per_target: usize,
    densities: &[T],
) -> Result<(), String> {
    let local_max = densities
        .iter()
        .map(|q| q.to_f64().abs())
        .fold(0.0, f64::max);
    let mut largest = 0.0f64;
    world.all_reduce_into(
        &local_max,
        &mut largest,
        mpi::collective::SystemOperation::max(),
    );
    let me = world.rank() as usize;
    let first: u64 = dtree.input_counts[..me].iter().sum();
    let local = ferrofmm_fmm::check_finite_output(values, per_target, densities).map_err(|e| {
        match e {
            FmmError::NonFiniteResult {
                target,
                component,
                value,
                precision,
                ..
            } => FmmError::NonFiniteResult {
                target: target + first as usize,
                component,
                value,
                largest_density: largest,
                precision,
            },
            other => other,
        }
        .to_string()
    });
    agree_text(world, local)
}

/// One `eval` with its inputs and parameters settled.
struct Run<'a, K> {
    world: &'a SimpleCommunicator,
    a: &'a EvalArgs,
    kernel: K,
    input: Inputs,
    mode: EvalMode,
    plan: Plan,
    read_s: f64,
    threads: usize,
}

impl<K: Kernel> Run<'_, K> {
    fn go<T: Real, S: SchemeConfig<T>>(self) -> Result<(), String> {
        let Run {
            world,
            a,
            kernel,
            input,
            mode,
            mut plan,
            read_s,
            threads,
        } = self;
        let me = world.rank() as usize;
        let size = world.size() as usize;
        let dtree =
            DistributedTree::build(world, &input.points, &DistOptions::adaptive(plan.leaf_size))
                .map_err(|e| e.to_string())?;
        let q_t: Vec<T> = input.densities.iter().map(|&x| T::from_f64(x)).collect();
        let verify = plan.tolerance.filter(|_| a.verify == "on");
        // At most every point (the report names the number compared).
        let total_points: u64 = dtree.input_counts.iter().sum();
        let samples = if a.check > 0 {
            a.check
        } else if verify.is_some() {
            VERIFY_SAMPLE
        } else {
            0
        }
        .min(usize::try_from(total_points).unwrap_or(usize::MAX));
        let mut attempts = Vec::new();
        // The one resolution of the cache folder (every rank reads the
        // same environment, so a bad FERROFMM_CACHE_SIZE fails on all).
        let cache_setting = match (&a.cache_dir, a.no_cache) {
            (Some(dir), _) => CacheSetting::Dir(dir.clone()),
            (None, true) => CacheSetting::Off,
            (None, false) => CacheSetting::Default,
        };
        let cache = cache_setting.resolve().map_err(|e| e.to_string())?;
        loop {
            let options = DistFmmOptions {
                sources: input.kind,
                cache_dir: cache.dir().map(PathBuf::from),
                cache_size_limit: cache.size_limit(),
                ..DistFmmOptions::new(plan.order, mode)
            };
            let config = S::config(plan.svd_tolerance);
            let dfmm =
                DistributedFmm::<T, K, S>::build(world, &dtree, kernel.clone(), &config, &options)
                    .map_err(|e| e.to_string())?;
            let mut last = None;
            for _ in 0..a.repeats.max(1) {
                last = Some(dfmm.evaluate(world, &q_t).map_err(|e| e.to_string())?);
            }
            let Some((values, stats)) = last else {
                return Err("no evaluation".into());
            };
            // Finite inputs can still overflow (charges near the float
            // type's largest value): an error on every rank, naming the
            // first bad value in the input order, and nothing written.
            finite_output(world, &dtree, &values, dfmm.values_per_target(), &q_t)?;
            let values: Vec<f64> = values.iter().map(|v| v.to_f64()).collect();
            let errors = (samples > 0).then(|| {
                sampled_errors(
                    world,
                    &kernel,
                    input.kind,
                    mode,
                    &input.points,
                    &input.densities,
                    &values,
                    samples,
                )
            });
            let worst = errors.map_or(0.0, |e| e[0].max(e[1]));
            attempts.push(Attempt {
                order: plan.order,
                errors,
            });
            let retry = verify.is_some_and(|eps| worst > eps)
                && attempts.len() <= MAX_VERIFY_RETRIES
                && plan.order < ferrofmm_field::MAX_ORDER;
            if retry {
                // The tree stays; the operators are rebuilt one order up
                // (the SVD tolerance then the order's default).
                plan.order += 1;
                plan.svd_tolerance = None;
                continue;
            }
            // A missed tolerance is a failure (exit status 1), with no
            // output written: the values are not what was asked for.
            if let Some(eps) = verify.filter(|&eps| worst > eps) {
                return Err(format!(
                    "tolerance {eps:e} not met: the error measured on {samples} sampled points \
                     is {worst:.2e} after {} attempt(s) (last order {}); no output written \
                     (ask for a larger tolerance{}, or --verify off to take the unchecked result)",
                    attempts.len(),
                    plan.order,
                    if T::PRECISION == Precision::F32 {
                        ", use --precision f64"
                    } else {
                        ""
                    }
                ));
            }
            if let Some(out) = &a.out {
                let first: u64 = dtree.input_counts[..me].iter().sum();
                let total: u64 = dtree.input_counts.iter().sum();
                let components = KernelChoice::parse(&a.kernel)
                    .map(|k| k.component_names())
                    .map_err(|e| format!("--kernel {e}"))?;
                let names = ferrofmm_io::column_names(mode.values_per_target(), components);
                let names: Vec<&str> = names.iter().map(String::as_str).collect();
                if names.len() != dfmm.values_per_target() {
                    return Err(format!(
                        "internal error: {} output columns named for {} values per target",
                        names.len(),
                        dfmm.values_per_target()
                    ));
                }
                write_out(world, out, &values, &names, (first, total), input.complex)?;
            }
            let mut mine = figures(&dtree, &dfmm, &stats);
            mine.push(stats.compute_cpu_seconds);
            mine.push(dfmm.setup_stats().active_boxes as f64);
            let mut all = vec![0.0f64; FIGURES * size];
            world.all_gather_into(&mine[..], &mut all[..]);
            if me == 0 {
                let info = RunInfo {
                    json: a.json,
                    kernel: a.kernel.clone(),
                    precision: &a.precision,
                    gradients: a.gradients,
                    input: a.generate.as_deref(),
                    tolerance: plan.tolerance,
                    order: plan.order,
                    leaf_size: plan.leaf_size,
                    scheme: plan.scheme,
                    svd_tolerance: plan.svd_tolerance,
                    choice: plan.choice.as_ref(),
                    attempts: &attempts,
                    samples,
                    read_s,
                    threads,
                    cache: match &cache {
                        CacheLocation::Off(CacheOff::Requested) => "off (--no-cache)".into(),
                        CacheLocation::Off(why) => why.to_string(),
                        CacheLocation::Folder { .. } => CacheStatus::summary(
                            dfmm.local().operators().cache_status(),
                            &dfmm.local().m2l_scheme().cache_status(),
                        )
                        .unwrap_or_else(|| "not needed".into()),
                    },
                    cache_dir: cache.dir().map(|d| d.display().to_string()),
                };
                report(&info, &all, size);
            }
            return Ok(());
        }
    }
}
