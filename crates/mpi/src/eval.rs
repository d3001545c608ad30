//! The `eval` subcommand: the distributed FMM on points and densities from
//! files (each rank reads its rows of a `.npy` file) or generated, for any
//! built-in kernel, at a given order or a requested accuracy (chosen from a
//! sample, then verified), the result written in the input order, and
//! per-rank figures.

use std::path::PathBuf;

use clap::Args;
use ferrofmm_field::{CacheLocation, CacheOff, CacheSetting};
use ferrofmm_fmm::SchemeChoice;
use ferrofmm_fmm::StokesRequest;
use ferrofmm_kernels::{EvalMode, KernelChoice, Precision, SourceKind};
use ferrofmm_mpi::{DistRequest, DistSolver, Geometry, agree_options, agree_text};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::eval_io::{my_rows, read_slice, reader, write_out};
use crate::eval_report::{Attempt, FIGURES, RunInfo, figures, report};
use ferrofmm_io::Contents;

/// Arguments of `eval`.
#[derive(Args)]
pub struct EvalArgs {
    /// Source points (also the targets, unless --targets): .npy (N x 3, float64 or float32;
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
    /// For --kernel stokes these are the forces (N x 3).
    #[arg(long, value_name = "FILE", required_unless_present_any = ["generate", "dipoles", "strslet"])]
    pub(crate) charges: Option<PathBuf>,
    /// Dipole vectors, one per source: .npy or .csv (N x 3, or N x 3c:
    /// nx_re, nx_im, ny_re, ... for helmholtz:K, or complex N x 3, or real
    /// vectors alone); with --charges, both.
    #[arg(long, value_name = "FILE")]
    pub(crate) dipoles: Option<PathBuf>,
    /// `--kernel stokes` only: stresslet strengths `m` (FMM3D's
    /// `strslet`), one 3-vector per source (.npy N x 3, .csv or raw .f64;
    /// each rank reads its rows), with `--strsvec`. Each adds
    /// `3 d (d . m)(d . n) / (4 pi r^5)` to the velocity (`d`: target minus
    /// source); with `--charges` (forces) too, both. As `ferrofmm eval`.
    #[arg(
        long,
        value_name = "FILE",
        requires = "strsvec",
        conflicts_with = "generate"
    )]
    pub(crate) strslet: Option<PathBuf>,
    /// `--kernel stokes` only: stresslet orientations `n` (FMM3D's
    /// `strsvec`, e.g. surface normals), same format, with `--strslet`.
    #[arg(
        long,
        value_name = "FILE",
        requires = "strslet",
        conflicts_with = "generate"
    )]
    pub(crate) strsvec: Option<PathBuf>,
    /// `--kernel stokes` only: also the pressure (FMM3D's `pre`), and with
    /// --gradients its gradient: columns `pressure` (and `pressure_grad_x,
    /// pressure_grad_y, pressure_grad_z`) after the velocity's. As
    /// `ferrofmm eval`.
    #[arg(long)]
    pub(crate) pressure: bool,
    /// Separate targets (the same formats as --sources; each rank reads
    /// its rows): the values are computed there, for the charges at the
    /// sources, and --out holds one row per target in this file's order.
    /// Targets may lie anywhere (the tree's cube covers both sets).
    #[arg(long, value_name = "FILE", conflicts_with = "generate")]
    pub(crate) targets: Option<PathBuf>,
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
    /// No report: a successful run prints nothing (its output file is its
    /// result). Errors and warnings (such as the note that --threads was
    /// lowered) still print on stderr, and the exit status is unchanged;
    /// the JSON of --json, asked for explicitly, is still printed. As
    /// `ferrofmm --quiet`.
    #[arg(short = 'q', long)]
    pub(crate) quiet: bool,
    /// A periodic cell, as `ferrofmm eval --box L`: not in the distributed
    /// FMM yet, refused with where periodic systems run (`ferrofmm eval
    /// --box`, Python's `box=`, on one machine).
    #[arg(long = "box", value_name = "L")]
    pub(crate) periodic_box: Option<String>,
    /// Periodic axes, as `ferrofmm eval --periodic`: refused as `--box`.
    #[arg(long, value_name = "AXES")]
    pub(crate) periodic: Option<String>,
}

/// This rank's points and densities (`kind`, `kernel.values_per_source`
/// per point), as read or generated.
struct Inputs {
    points: Vec<f64>,
    /// Separate targets (`None`: the points).
    targets: Option<Vec<f64>>,
    densities: Vec<f64>,
    kind: SourceKind,
    /// Charges (forces, for Stokes) were given or generated: with
    /// stresslets, `densities` may be empty otherwise.
    has_charges: bool,
    /// Stresslet strengths and orientations (three values each per point).
    stresslets: Option<(Vec<f64>, Vec<f64>)>,
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
            targets: None,
            densities: ferrofmm_fmm::charges(c * n, 2000 + me as u64),
            kind: SourceKind::Charge,
            has_charges: true,
            stresslets: None,
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
    let targets = match &a.targets {
        Some(t) => Some(agree_text(world, read_slice(&reader, t, Contents::Points, me, size))?.0),
        None => None,
    };
    let charges = read(&a.charges, Contents::charges(c, complex))?;
    let dipoles = read(&a.dipoles, Contents::dipoles(c, complex))?;
    let stresslets = match (
        read(&a.strslet, Contents::Points)?,
        read(&a.strsvec, Contents::Points)?,
    ) {
        (Some(m), Some(v)) => Some((m, v)),
        _ => None,
    };
    let has_charges = charges.is_some();
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
        (None, None) if stresslets.is_some() => (SourceKind::Charge, Vec::new()),
        (None, None) => return Err("give --charges or --dipoles".into()),
    };
    Ok(Inputs {
        points,
        targets,
        densities,
        kind,
        has_charges,
        stresslets,
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
        ("--strslet", path(&a.strslet)),
        ("--strsvec", path(&a.strsvec)),
        ("--pressure", a.pressure.to_string()),
        ("--targets", path(&a.targets)),
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
        ("--quiet", a.quiet.to_string()),
        ("--box", given(a.periodic_box.as_ref())),
        ("--periodic", given(a.periodic.as_ref())),
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
        ("--strslet", &a.strslet),
        ("--strsvec", &a.strsvec),
        ("--targets", &a.targets),
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
    if let Some(flag) = [("--box", &a.periodic_box), ("--periodic", &a.periodic)]
        .iter()
        .find_map(|(flag, v)| v.is_some().then_some(flag))
    {
        return fail(format!(
            "{flag}: periodic boundaries are not in the distributed FMM yet; run them on one \
             machine with `ferrofmm eval --box L` or Python's `ferrofmm.laplace(..., box=L)`"
        ));
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
    if let Err(e) = StokesRequest::check_flags(&kernel, layered(a), a.dipoles.is_some()) {
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
    match go(world, a, kernel, threads) {
        Ok(()) => 0,
        Err(e) => fail(e),
    }
}

/// Whether `eval` runs stresslets or the pressure (`--strslet`,
/// `--pressure`): two distributed FMMs ([`crate::eval_layers`]).
fn layered(a: &EvalArgs) -> bool {
    a.strslet.is_some() || a.pressure
}

impl Inputs {
    /// What a run of stresslets and the pressure reads.
    fn into_layers(self) -> crate::eval_layers::LayerInputs {
        crate::eval_layers::LayerInputs {
            points: self.points,
            targets: self.targets,
            forces: self.has_charges.then_some(self.densities),
            stresslets: self.stresslets,
        }
    }
}

/// The request of `eval`'s arguments (clap checked the names).
pub(crate) fn request(
    a: &EvalArgs,
    kernel: KernelChoice,
    kind: SourceKind,
) -> Result<DistRequest, String> {
    Ok(DistRequest {
        mode: if a.gradients {
            EvalMode::PotentialGradient
        } else {
            EvalMode::Potential
        },
        sources: kind,
        precision: if a.precision == "f32" {
            Precision::F32
        } else {
            Precision::F64
        },
        tolerance: a.tolerance,
        order: a.order,
        leaf_size: a.leaf_size,
        scheme: SchemeChoice::parse(&a.scheme)?,
        verify: a.verify == "on",
        samples: a.check,
        // The one resolution of the cache folder (every rank reads the
        // same environment, so a bad FERROFMM_CACHE_SIZE fails on all).
        cache: match (&a.cache_dir, a.no_cache) {
            (Some(dir), _) => CacheSetting::Dir(dir.clone()),
            (None, true) => CacheSetting::Off,
            (None, false) => CacheSetting::Default,
        },
        ..DistRequest::new(kernel)
    })
}

/// The run: inputs, the solver ([`DistSolver`]: plan, build, evaluate,
/// verify), the output and the report.
fn go(
    world: &SimpleCommunicator,
    a: &EvalArgs,
    kernel: KernelChoice,
    threads: usize,
) -> Result<(), String> {
    let me = world.rank() as usize;
    let size = world.size() as usize;
    let t0 = std::time::Instant::now();
    let c = kernel.component_names().len().max(1);
    let input = agree_text(world, inputs(world, a, c, me, size))?;
    let read_s = t0.elapsed().as_secs_f64();
    if layered(a) {
        return crate::eval_layers::go(world, a, kernel, threads, input.into_layers(), read_s);
    }
    let request = request(a, kernel, input.kind)?;
    let Inputs {
        points,
        targets,
        densities,
        complex,
        ..
    } = input;
    let solver = match targets {
        None => DistSolver::build(world, points, request),
        Some(t) => DistSolver::build_with_targets(world, points, t, request),
    };
    let mut solver = solver.map_err(|e| e.to_string())?;
    let mut last = None;
    let mut verified = None;
    for _ in 0..a.repeats.max(1) {
        let solution = solver
            .evaluate(world, &densities)
            .map_err(|e| e.to_string())?;
        // A missed tolerance is a failure (exit status 1), with no output
        // written: the values are not what was asked for.
        if let (Some(false), Some(e), Some(eps)) =
            (solution.verified, solution.errors, solver.plan().tolerance)
        {
            return Err(format!(
                "tolerance {eps:e} not met: the error measured on {} sampled points is {:.2e} \
                 after {} attempt(s) (last order {}); no output written (ask for a larger \
                 tolerance{}, or --verify off to take the unchecked result)",
                solver.samples(),
                e[0].max(e[1]),
                solver.attempts().len(),
                solver.plan().order,
                if solver.request().precision == Precision::F32 {
                    ", use --precision f64"
                } else {
                    ""
                }
            ));
        }
        verified = verified.or(solution.errors);
        last = Some(solution);
    }
    let Some(solution) = last else {
        return Err("no evaluation".into());
    };
    // --check without a verification: measured on the last evaluation.
    let samples = if a.check > 0 || verified.is_some() {
        solver.samples()
    } else {
        0
    };
    let errors = verified.or_else(|| {
        (samples > 0).then(|| solver.sampled_errors(world, &densities, &solution.values, samples))
    });
    // Every order verified, or the one evaluated (with its check, if any).
    let mut attempts: Vec<Attempt> = solver
        .attempts()
        .iter()
        .map(|t| Attempt {
            order: t.order,
            errors: Some(t.errors),
        })
        .collect();
    if verified.is_none() {
        attempts.push(Attempt {
            order: solver.plan().order,
            errors,
        });
    }
    let tree = solver.tree();
    if let Some(out) = &a.out {
        // One row per target (the points, or the --targets rows).
        let counts = solver.target_counts();
        let first: u64 = counts[..me].iter().sum();
        let total: u64 = counts.iter().sum();
        let names = ferrofmm_io::column_names(
            solver.request().mode.values_per_target(),
            kernel.component_names(),
        );
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        if names.len() != solver.values_per_target() {
            return Err(format!(
                "internal error: {} output columns named for {} values per target",
                names.len(),
                solver.values_per_target()
            ));
        }
        write_out(
            world,
            out,
            &solution.values,
            &names,
            (first, total),
            complex,
        )?;
    }
    let mut mine = figures(tree, solver.setup_stats(), &solution.stats);
    mine.push(solution.stats.compute_cpu_seconds);
    mine.push(solver.setup_stats().active_boxes as f64);
    let mut all = vec![0.0f64; FIGURES * size];
    world.all_gather_into(&mine[..], &mut all[..]);
    // `--quiet` silences the table, not a JSON asked for.
    if me == 0 && (a.json || !a.quiet) {
        let info = run_info(a, &solver, &attempts, samples, read_s, threads, None);
        report(&info, &all, size);
    }
    Ok(())
}

/// What rank 0 reports of a run of `solver` (the Stokeslet FMM's, for a
/// run with layers, whose lines and JSON come as `layers`).
pub(crate) fn run_info<'a>(
    a: &'a EvalArgs,
    solver: &'a DistSolver<SimpleCommunicator>,
    attempts: &'a [Attempt],
    samples: usize,
    read_s: f64,
    threads: usize,
    layers: Option<(Vec<String>, serde_json::Value)>,
) -> RunInfo<'a> {
    let plan = solver.plan();
    RunInfo {
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
        attempts,
        samples,
        read_s,
        threads,
        cache: match solver.cache() {
            CacheLocation::Off(CacheOff::Requested) => "off (--no-cache)".into(),
            CacheLocation::Off(why) => why.to_string(),
            CacheLocation::Folder { .. } => solver
                .cache_summary()
                .unwrap_or_else(|| "not needed".into()),
        },
        cache_dir: solver.cache().dir().map(|d| d.display().to_string()),
        layers,
    }
}
