//! `ferrofmm sweep`: speed against accuracy over a grid of configurations.
//!
//! Every configuration (order x scheme x precision x leaf size) runs in a
//! child process of this same binary, `ferrofmm demo --json ...`, so that
//! its peak memory (`VmHWM`, which only grows within a process) is its own
//! and no configuration warms caches or the allocator for the next. The
//! child's JSON report becomes one row of `results.csv`; the charts of
//! [`crate::charts`] are drawn from all rows. Beside the grid, the runs a
//! user gets without choosing (`--with-defaults`: `ferrofmm demo` with no
//! setting) and with `--tolerance EPS` (`--tolerances`), whose order, leaf
//! size and scheme the library chooses and verifies, run once per
//! precision, so that the charts show where they land against every
//! hand-picked setting.
//!
//! `results.csv` columns (times in seconds, memory in MiB):
//!
//! ```text
//! geometry,charges,n,order,scheme,precision,leaf_size,gradients,threads,repeats,
//! depth,n_leaves,n_boxes,setup_s,tree_s,operators_s,m2l_precompute_s,
//! eval_best_s,eval_median_s,p2m_s,m2m_s,m2l_s,p2l_s,l2l_s,l2p_s,m2p_s,p2p_s,far_s,
//! potential_error,gradient_error,peak_rss_mib,m2l_mib,run,tolerance
//! ```
//!
//! `run` is `grid`, `defaults` or `tolerance`; `tolerance` the accuracy
//! asked for (the default one for `defaults`, empty for the grid).
//!
//! `eval_best_s` / `eval_median_s` are the fastest and the median of
//! `--repeats` evaluations; the per-operator times are those of the fastest.
//! `gradient_error` is empty without gradients, `peak_rss_mib` where the
//! platform does not report it.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use clap::Args;

use super::{CHARGES_HELP, ChargesArg, GeometryArg, PrecisionArg, SchemeArg};
use crate::charts;
use crate::error::{CliError, Result};
use crate::report::{RunReport, seconds};

/// The header of `results.csv`.
pub const CSV_HEADER: &str = "geometry,charges,n,order,scheme,precision,leaf_size,gradients,threads,repeats,\
depth,n_leaves,n_boxes,setup_s,tree_s,operators_s,m2l_precompute_s,eval_best_s,eval_median_s,\
p2m_s,m2m_s,m2l_s,p2l_s,l2l_s,l2p_s,m2p_s,p2p_s,far_s,potential_error,gradient_error,peak_rss_mib,m2l_mib,\
run,tolerance";

/// Arguments of `ferrofmm sweep`.
#[derive(Args, Clone, Debug)]
pub struct SweepArgs {
    /// Number of points (sources = targets).
    #[arg(long, short = 'n', default_value_t = 100_000)]
    pub n: usize,
    /// Point distribution (`clustered` is the Plummer sphere).
    #[arg(long, value_enum, default_value_t = GeometryArg::Cube)]
    pub geometry: GeometryArg,
    #[arg(long, default_value = "signed", value_name = "signed|positive", help = CHARGES_HELP)]
    pub charges: String,
    /// Expansion orders: an inclusive range `3..10` or a list `3,5,7`.
    #[arg(long, default_value = "3..10", value_parser = parse_orders)]
    pub orders: Orders,
    /// M2L schemes, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [SchemeArg::Svd, SchemeArg::Dense], value_parser = super::scheme_parser())]
    pub schemes: Vec<SchemeArg>,
    /// Float types, comma-separated.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [PrecisionArg::F64, PrecisionArg::F32])]
    pub precision: Vec<PrecisionArg>,
    /// Leaf sizes, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [ferrofmm_fmm::DEFAULT_LEAF_SIZE])]
    pub leaf_sizes: Vec<usize>,
    /// Evaluations per configuration (the fastest and the median are reported).
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Targets compared with direct summation per configuration.
    #[arg(long, default_value_t = 1000, value_name = "TARGETS")]
    pub check: usize,
    /// Evaluate potentials only (default: potential and gradient).
    #[arg(long = "no-gradients")]
    pub no_gradients: bool,
    /// Evaluate Hessians too (implies gradients).
    #[arg(long)]
    pub hessians: bool,
    #[arg(long, default_value = "laplace", value_name = "NAME[:K]", help = super::kernel_help())]
    pub kernel: String,
    /// Also run with these requested accuracies, comma-separated
    /// (`ferrofmm demo --tolerance EPS`: order, leaf size and scheme chosen
    /// and verified), once per precision; starred on the time charts.
    #[arg(long, value_delimiter = ',', value_name = "EPS,...", value_parser = parse_tolerance)]
    pub tolerances: Vec<f64>,
    /// Also run the defaults (`ferrofmm demo` with no order, leaf size,
    /// scheme or tolerance), once per precision; starred on the time charts.
    #[arg(long)]
    pub with_defaults: bool,
    /// Random seed of the points and charges.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Directory for results.csv and the charts (created when missing).
    #[arg(long, value_name = "DIR")]
    pub out_dir: PathBuf,
}

/// A list of expansion orders.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Orders(pub Vec<usize>);

/// Parse `3..10` (inclusive), `3..=10` or `3,5,7`.
pub fn parse_orders(text: &str) -> std::result::Result<Orders, String> {
    let number = |s: &str| {
        s.trim()
            .parse::<usize>()
            .map_err(|_| format!("'{}' is not an order (a whole number such as 6)", s.trim()))
    };
    let orders: Vec<usize> = if let Some((a, b)) = text.split_once("..") {
        let (a, b) = (number(a)?, number(b.strip_prefix('=').unwrap_or(b))?);
        if a > b {
            return Err(format!("empty range {a}..{b}"));
        }
        (a..=b).collect()
    } else {
        text.split(',')
            .map(number)
            .collect::<std::result::Result<_, _>>()?
    };
    if orders.is_empty() {
        return Err("no orders given".into());
    }
    Ok(Orders(orders))
}

/// A requested accuracy: a number in (0, 1), checked by the library's own
/// rule (`ferrofmm_fmm::tuning::validate_tolerance`, with its message).
fn parse_tolerance(text: &str) -> std::result::Result<f64, String> {
    let eps: f64 = text.trim().parse().map_err(|_| {
        format!(
            "'{}' is not a tolerance (a number such as 1e-6)",
            text.trim()
        )
    })?;
    ferrofmm_fmm::tuning::validate_tolerance(eps, ferrofmm_kernels::Precision::F64)
        .map(|()| eps)
        .map_err(|e| e.to_string())
}

/// One run of the sweep.
#[derive(Clone, Copy, Debug)]
enum Job {
    /// A configuration of the grid, every setting given.
    Grid(Config),
    /// The library's choice for a requested accuracy (`None`: the defaults,
    /// nothing given) in `precision`.
    Chosen {
        tolerance: Option<f64>,
        precision: PrecisionArg,
    },
}

impl Job {
    fn describe(&self) -> String {
        match self {
            Job::Grid(c) => c.describe(),
            Job::Chosen {
                tolerance: Some(eps),
                precision,
            } => format!("eps={eps:.0e} {} (chosen)", precision.name()),
            Job::Chosen {
                tolerance: None,
                precision,
            } => format!("defaults {}", precision.name()),
        }
    }
}

/// One configuration of the grid.
#[derive(Clone, Copy, Debug)]
struct Config {
    order: usize,
    scheme: SchemeArg,
    precision: PrecisionArg,
    leaf_size: usize,
}

impl Config {
    fn describe(&self) -> String {
        format!(
            "p={} {} {} leaf={}",
            self.order,
            self.scheme.name(),
            self.precision.name(),
            self.leaf_size
        )
    }
}

/// Run `ferrofmm sweep`; `threads` is passed on to every child.
pub fn sweep(args: &SweepArgs, threads: Option<usize>) -> Result<()> {
    let bad = |m: &str| Err(CliError::InvalidArgument(m.to_string()));
    ChargesArg::parse(&args.charges)?;
    super::parse_kernel(&args.kernel)?;
    if args.n == 0 {
        return bad("--n must be at least 1");
    }
    if args.repeats == 0 {
        return bad("--repeats must be at least 1");
    }
    if args.schemes.is_empty() || args.precision.is_empty() || args.leaf_sizes.is_empty() {
        return bad("--schemes, --precision and --leaf-sizes need at least one value each");
    }
    if args.leaf_sizes.contains(&0) {
        return bad("leaf sizes must be at least 1");
    }
    let range = ferrofmm_fmm::MIN_ORDER..=ferrofmm_fmm::MAX_ORDER;
    if let Some(p) = args.orders.0.iter().find(|p| !range.contains(p)) {
        return Err(CliError::InvalidArgument(format!(
            "order {p} is not supported (use {}..={})",
            range.start(),
            range.end()
        )));
    }
    std::fs::create_dir_all(&args.out_dir).map_err(|e| CliError::io(&args.out_dir, e))?;

    let all = jobs(args);
    let exe =
        std::env::current_exe().map_err(|e| CliError::io(Path::new("current executable"), e))?;
    let csv_path = args.out_dir.join("results.csv");
    let bar = crate::progress::bar(all.len() as u64);
    let mut runs: Vec<RunReport> = Vec::with_capacity(all.len());
    // A chosen run that fails is skipped with its reason, not fatal: the
    // library may decline a tolerance (beyond what f32 can promise on
    // these points), which is an answer, not a broken sweep.
    let mut skipped = Vec::new();
    for job in &all {
        bar.set_message(job.describe());
        let report = match run_child(&exe, args, job, threads) {
            Ok(report) => report,
            Err(e) if matches!(job, Job::Chosen { .. }) => {
                let line = format!("skipped {e}");
                bar.println(&line);
                skipped.push(line);
                bar.inc(1);
                continue;
            }
            Err(e) => return Err(e),
        };
        bar.println(format!(
            "{:<28} eval {:>10}  setup {:>10}  error {}",
            job.describe(),
            seconds(report.evaluation.best_s),
            seconds(report.setup.total_s),
            report
                .errors
                .as_ref()
                .map_or("-".to_string(), |e| format!("{:.2e}", e.potential))
        ));
        runs.push(report);
        // Rewritten after every configuration: an interrupted sweep keeps its rows.
        write_csv(&csv_path, &runs)?;
        bar.inc(1);
    }
    bar.finish_and_clear();

    let charts =
        crate::progress::with_stage("drawing charts", || charts::write_all(&args.out_dir, &runs))?;
    let mut text = summary_table(&runs);
    for line in &skipped {
        text.push_str(line);
        text.push('\n');
    }
    for f in std::iter::once(&csv_path).chain(&charts) {
        text.push_str(&format!("wrote {}\n", f.display()));
    }
    crate::stdout::report(&text)
}

/// All configurations, precision-major, then scheme, leaf size and order;
/// then the chosen runs (defaults first, then the tolerances) per
/// precision, but for tolerances f32 cannot promise on any points.
fn jobs(args: &SweepArgs) -> Vec<Job> {
    let mut jobs = Vec::new();
    for &precision in &args.precision {
        for &scheme in &args.schemes {
            for &leaf_size in &args.leaf_sizes {
                for &order in &args.orders.0 {
                    jobs.push(Job::Grid(Config {
                        order,
                        scheme,
                        precision,
                        leaf_size,
                    }));
                }
            }
        }
    }
    let defaults = args.with_defaults.then_some(None);
    for &precision in &args.precision {
        for tolerance in defaults
            .into_iter()
            .chain(args.tolerances.iter().map(|&e| Some(e)))
        {
            // f32 cannot promise these on any points: not run (the report
            // of such a run would only be the refusal).
            if precision == PrecisionArg::F32
                && tolerance.is_some_and(|eps| !ferrofmm_fmm::tuning::f32_reaches(eps))
            {
                continue;
            }
            jobs.push(Job::Chosen {
                tolerance,
                precision,
            });
        }
    }
    jobs
}

/// Run one configuration as `ferrofmm demo --json` and parse its report.
fn run_child(exe: &Path, args: &SweepArgs, job: &Job, threads: Option<usize>) -> Result<RunReport> {
    let mut cmd = Command::new(exe);
    cmd.arg("demo")
        .arg("--json")
        .args(["--n", &args.n.to_string()])
        .args(["--geometry", args.geometry.name()])
        .args(["--charges", ChargesArg::parse(&args.charges)?.name()])
        .args(["--repeats", &args.repeats.to_string()])
        .args(["--check", &args.check.to_string()])
        .args(["--seed", &args.seed.to_string()]);
    match job {
        Job::Grid(config) => {
            cmd.args(["--order", &config.order.to_string()])
                .args(["--scheme", config.scheme.name()])
                .args(["--precision", config.precision.name()])
                .args(["--leaf-size", &config.leaf_size.to_string()]);
        }
        Job::Chosen {
            tolerance,
            precision,
        } => {
            cmd.args(["--precision", precision.name()]);
            if let Some(eps) = tolerance {
                cmd.args(["--tolerance", &eps.to_string()]);
            }
        }
    }
    cmd.args(["--kernel", &args.kernel]);
    if args.hessians {
        cmd.arg("--hessians");
    } else if args.no_gradients {
        cmd.arg("--no-gradients");
    }
    if let Some(t) = threads {
        cmd.args(["--threads", &t.to_string()]);
    }
    let fail = |message: String| CliError::SweepRun {
        config: job.describe(),
        message,
    };
    let out = cmd
        .output()
        .map_err(|e| fail(format!("cannot start {}: {e}", exe.display())))?;
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        let last = stderr
            .lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .unwrap_or("no message");
        let last = last.trim();
        let last = last.strip_prefix("error: ").unwrap_or(last);
        return Err(fail(format!("{last} ({})", out.status)));
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .ok_or_else(|| fail("the run printed nothing".into()))?;
    serde_json::from_str(line).map_err(|e| fail(format!("unreadable report ({e})")))
}

/// One `results.csv` row.
pub fn csv_row(r: &RunReport) -> String {
    let mib = |b: f64| b / (1024.0 * 1024.0);
    let e = &r.evaluation;
    let mut row = format!(
        "{},{},{},{},{},{},{},{},{},{},{},{},{}",
        r.geometry.as_deref().unwrap_or(""),
        r.charges.as_deref().unwrap_or(""),
        r.n_sources,
        r.order,
        r.scheme,
        r.precision,
        r.leaf_size,
        r.gradients,
        r.threads,
        e.repeats,
        r.tree.depth,
        r.tree.n_leaves,
        r.tree.n_boxes
    );
    let s = &r.setup;
    for v in [
        s.total_s,
        s.tree_s,
        s.operators_s,
        s.m2l_precompute_s,
        e.best_s,
        e.median_s,
    ] {
        let _ = write!(row, ",{v:.6e}");
    }
    for v in e.operators_s.values() {
        let _ = write!(row, ",{v:.6e}");
    }
    let (pot, grad) = match &r.errors {
        Some(err) => (
            format!("{:.6e}", err.potential),
            err.gradient.map(|g| format!("{g:.6e}")).unwrap_or_default(),
        ),
        None => (String::new(), String::new()),
    };
    let peak = r
        .peak_rss_bytes
        .map(|b| format!("{:.1}", mib(b as f64)))
        .unwrap_or_default();
    let _ = write!(
        row,
        ",{pot},{grad},{peak},{:.3},{},{}",
        mib(r.tree.m2l_bytes as f64),
        run_kind(r),
        r.tolerance.map(|e| format!("{e:e}")).unwrap_or_default()
    );
    row
}

/// `grid`, `defaults` or `tolerance`: how the run's parameters were set.
fn run_kind(r: &RunReport) -> &'static str {
    if r.default_tolerance {
        "defaults"
    } else if r.tolerance.is_some() {
        "tolerance"
    } else {
        "grid"
    }
}

fn write_csv(path: &Path, runs: &[RunReport]) -> Result<()> {
    let mut text = String::with_capacity(256 * (runs.len() + 1));
    text.push_str(CSV_HEADER);
    text.push('\n');
    for r in runs {
        text.push_str(&csv_row(r));
        text.push('\n');
    }
    let mut file = std::fs::File::create(path).map_err(|e| CliError::io(path, e))?;
    file.write_all(text.as_bytes())
        .map_err(|e| CliError::io(path, e))
}

/// A plain-text table of the sweep, one line per configuration.
fn summary_table(runs: &[RunReport]) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "{:<9} {:>5} {:>6} {:>5} {:>6} {:>10} {:>10} {:>10} {:>10} {:>9}",
        "run",
        "order",
        "scheme",
        "prec",
        "leaf",
        "setup",
        "eval",
        "pot err",
        "grad err",
        "peak MiB"
    );
    for r in runs {
        let (pot, grad) = match &r.errors {
            Some(e) => (
                format!("{:.2e}", e.potential),
                e.gradient.map_or("-".to_string(), |g| format!("{g:.2e}")),
            ),
            None => ("-".to_string(), "-".to_string()),
        };
        let peak = r.peak_rss_bytes.map_or("-".to_string(), |b| {
            format!("{:.0}", b as f64 / (1024.0 * 1024.0))
        });
        let run = match (run_kind(r), r.tolerance) {
            ("tolerance", Some(eps)) => format!("eps {eps:.0e}"),
            (kind, _) => kind.to_string(),
        };
        let _ = writeln!(
            o,
            "{:<9} {:>5} {:>6} {:>5} {:>6} {:>10} {:>10} {:>10} {:>10} {:>9}",
            run,
            r.order,
            r.scheme,
            r.precision,
            r.leaf_size,
            seconds(r.setup.total_s),
            seconds(r.evaluation.best_s),
            pot,
            grad,
            peak
        );
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orders_parse() {
        assert_eq!(parse_orders("3..6").unwrap(), Orders(vec![3, 4, 5, 6]));
        assert_eq!(parse_orders("3..=4").unwrap(), Orders(vec![3, 4]));
        assert_eq!(parse_orders("3, 5,7").unwrap(), Orders(vec![3, 5, 7]));
        assert_eq!(parse_orders("8").unwrap(), Orders(vec![8]));
        assert!(parse_orders("6..3").is_err());
        assert!(parse_orders("a,b").is_err());
        assert!(parse_orders("").is_err());
    }

    #[test]
    fn tolerances_parse() {
        assert_eq!(parse_tolerance(" 1e-6").unwrap(), 1e-6);
        for bad in ["0", "1", "-1e-3", "abc", "NaN", "inf"] {
            assert!(parse_tolerance(bad).is_err(), "{bad}");
        }
    }

    /// The chosen runs come after the grid, defaults first, once per
    /// precision, with nothing but the precision (and the tolerance) set;
    /// f32 skips a tolerance it cannot promise (1e-7).
    #[test]
    fn chosen_runs_follow_the_grid_once_per_precision() {
        use clap::Parser;
        #[derive(Parser)]
        struct Wrap {
            #[command(flatten)]
            sweep: SweepArgs,
        }
        let args = Wrap::try_parse_from([
            "sweep",
            "--out-dir",
            "x",
            "--orders",
            "4,6",
            "--schemes",
            "fft",
            "--precision",
            "f64,f32",
            "--tolerances",
            "1e-3,1e-7",
            "--with-defaults",
        ])
        .unwrap()
        .sweep;
        let all = jobs(&args);
        let names: Vec<String> = all.iter().map(Job::describe).collect();
        assert_eq!(all.len(), 4 + 5, "{names:?}");
        assert!(all[..4].iter().all(|j| matches!(j, Job::Grid(_))));
        assert_eq!(
            names[4..],
            [
                "defaults f64",
                "eps=1e-3 f64 (chosen)",
                "eps=1e-7 f64 (chosen)",
                "defaults f32",
                "eps=1e-3 f32 (chosen)",
            ]
        );
        let none = Wrap::try_parse_from(["sweep", "--out-dir", "x", "--orders", "5"])
            .unwrap()
            .sweep;
        assert!(jobs(&none).iter().all(|j| matches!(j, Job::Grid(_))));
        assert!(Wrap::try_parse_from(["sweep", "--out-dir", "x", "--tolerances", "2"]).is_err());
    }

    #[test]
    fn csv_rows_match_the_header() {
        let header_fields = CSV_HEADER.split(',').count();
        let run = crate::charts::tests::fake_run(SchemeArg::Svd, PrecisionArg::F64, 5, 64);
        assert_eq!(csv_row(&run).split(',').count(), header_fields);
        let mut no_check = run.clone();
        no_check.errors = None;
        no_check.peak_rss_bytes = None;
        assert_eq!(csv_row(&no_check).split(',').count(), header_fields);
        assert!(csv_row(&run).ends_with(",grid,"));
        let mut chosen = run.clone();
        chosen.tolerance = Some(1e-5);
        assert!(csv_row(&chosen).ends_with(",tolerance,1e-5"));
        assert_eq!(csv_row(&chosen).split(',').count(), header_fields);
        chosen.default_tolerance = true;
        assert!(csv_row(&chosen).ends_with(",defaults,1e-5"));
    }
}
