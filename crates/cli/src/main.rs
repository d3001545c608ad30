//! `ferrofmm`: the kernel-independent fast multipole method from the
//! command line.
//!
//! * `ferrofmm demo`: an FMM on built-in random points, checked against
//!   direct summation (timings, per-operator split, errors, peak memory);
//! * `ferrofmm eval`: potentials (and gradients) for your own points and
//!   charges, from and to `.csv` or `.npy` files;
//! * `ferrofmm sweep`: speed against accuracy over a grid of orders,
//!   schemes, precisions and leaf sizes, as `results.csv` and charts.
//!
//! Progress bars (with the time left) are drawn on stderr only when it is a
//! terminal; `--quiet` silences them and the report (never errors or
//! warnings; `--json` still prints its JSON).
//!
//! Exit status: 0 on success (also when stdout is closed before the report
//! is printed, as in `ferrofmm demo | head -1`), 1 when the command fails
//! (the reason is one line on stderr, `error: ...`), 2 for command-line
//! syntax errors, 101 for an internal error (a bug; also reported as one
//! `error: ...` line), 130 when interrupted (Ctrl-C / SIGINT, or SIGTERM:
//! stops within a second, also in the middle of the operator
//! precomputation, and leaves no temporary output file).

mod charts;
mod commands;
mod error;
mod interrupt;
mod memory;
mod progress;
mod report;
mod stdout;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use commands::calibrate::CalibrateArgs;
use commands::demo::DemoArgs;
use commands::eval::EvalArgs;
use commands::sweep::SweepArgs;
use error::{CliError, Result};

/// Kernel-independent fast multipole method in 3D (Laplace, modified
/// Helmholtz, Helmholtz and Stokes kernels).
#[derive(Parser, Debug)]
#[command(
    name = "ferrofmm",
    version,
    about,
    long_about = "Kernel-independent fast multipole method for the 3D Laplace kernel 1/(4 pi r):\n\
                  potentials (and gradients) of N charges at M targets in O(N + M).\n\n\
                  Exit status: 0 on success (also when stdout is closed early, e.g. `| head`),\n\
                  1 when the command fails (one line `error: ...` on stderr), 2 for command-line\n\
                  syntax errors, 101 for an internal error (a bug in ferrofmm), 130 when\n\
                  interrupted (Ctrl-C: stops within a second, also during the operator\n\
                  precomputation, and leaves no temporary output file).\n\n\
                  Environment: FERROFMM_MEMORY_LIMIT (e.g. 8G, or unlimited) caps the memory of\n\
                  the operator precomputation (default: the memory available; --force lifts it);\n\
                  RAYON_NUM_THREADS sets the default thread count (at most one per core)."
)]
struct Cli {
    /// Worker threads for every parallel step (tree, operator precomputation,
    /// evaluation, direct check), in one pool shared by all of them (the
    /// linear algebra inside a parallel step runs sequentially, so threads
    /// are never nested). At most one per available core (default: one per
    /// core, or RAYON_NUM_THREADS). A larger T (also from RAYON_NUM_THREADS)
    /// is lowered to the number of cores, with a note on stderr: more
    /// threads than cores only make them wait for each other. The table and
    /// the JSON report the count used.
    #[arg(long, short = 't', global = true, value_name = "T")]
    threads: Option<usize>,
    /// No progress bars and no report: a successful run prints nothing
    /// (its output file is its result). Errors and warnings (such as the
    /// note that --threads was lowered) still print on stderr, and the
    /// exit status is unchanged. The JSON of --json, asked for explicitly,
    /// is still printed (alone on stdout).
    #[arg(long, short = 'q', global = true)]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run the FMM on built-in random points and check it against direct summation.
    ///
    /// Prints the problem, the tree, setup and evaluation time (per operator),
    /// the relative L2 errors of potential and gradient on sampled targets,
    /// and the peak memory.
    Demo(DemoArgs),
    /// Evaluate potentials (and gradients) for points and charges from files.
    ///
    /// Inputs: .csv (one point `x,y,z` per line, or one charge per line;
    /// commas or whitespace separate fields; blank lines and lines starting
    /// with `#` are ignored; a first line without any number is a header) or
    /// .npy (float64/float32; points N x 3, charges N; C or Fortran order).
    /// Output by extension: .npy (N, or N x 4 with --gradients, in the run's
    /// precision) or .csv (a header line, then one target per line).
    /// Potentials use 1/(4 pi r). Coincident points: a source and a target
    /// closer than about 1.5e-154 in f64 (1.1e-19 in f32), that is whose
    /// squared distance is below the smallest normal float, count as the
    /// same point and contribute nothing (no infinity, no NaN).
    ///
    /// The output is checked before any work (not an input file, not a
    /// directory, its directory writable), written to a temporary file
    /// beside it and renamed into place: a failed run leaves no partial file.
    Eval(EvalArgs),
    /// Measure speed against accuracy over a grid of configurations.
    ///
    /// Each configuration runs as a child `ferrofmm demo --json` (so its peak
    /// memory is its own). Writes DIR/results.csv (one row per configuration;
    /// columns geometry, n, order, scheme, precision, leaf_size, gradients,
    /// threads, repeats, depth, n_leaves, n_boxes, setup_s, tree_s,
    /// operators_s, m2l_precompute_s, eval_best_s, eval_median_s, one `<op>_s`
    /// per operator (p2m ... p2p, from the fastest evaluation),
    /// potential_error, gradient_error, peak_rss_mib, m2l_mib) and the charts
    /// time_vs_error, operators and error_vs_order as PNG and SVG.
    Sweep(SweepArgs),
    /// Measure this machine's cost model and save it where the chooser finds it.
    ///
    /// Times a few Laplace FMMs (uniform cube, both M2L schemes, small and
    /// large leaves) and saves, for each kind of work (P2P, far field, SVD
    /// and FFT M2L, tree), the measured over the predicted seconds in the
    /// operator cache folder (machine-calibration.txt). Runs with that
    /// cache folder, on this processor, with the same number of threads,
    /// then choose their leaf size and scheme with this machine's costs.
    /// Takes seconds to a minute; run it again after changing the machine
    /// or --threads.
    Calibrate(CalibrateArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    install_panic_hook();
    interrupt::install();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        // Nobody reads the report (`ferrofmm ... | head`): the work is done,
        // end quietly.
        Err(CliError::StdoutClosed) => ExitCode::SUCCESS,
        // Ctrl-C during the precomputation: it stopped itself.
        Err(CliError::Fmm(e)) if e.is_cancelled() => interrupt::exit_interrupted(),
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Bad input never panics; should a bug panic all the same, say so in one
/// line (exit status 101) instead of a raw panic message, unless
/// `RUST_BACKTRACE` asks for the details.
fn install_panic_hook() {
    if std::env::var_os("RUST_BACKTRACE").is_some() {
        return;
    }
    std::panic::set_hook(Box::new(|info| {
        let payload = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown cause".to_string());
        let payload = payload.lines().next().unwrap_or_default();
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!(
            "error: internal error{at}: {payload} (a bug in ferrofmm: please report it; \
             RUST_BACKTRACE=1 shows details)"
        );
    }));
}

fn run(cli: Cli) -> Result<()> {
    progress::set_quiet(cli.quiet);
    // `--threads`, else RAYON_NUM_THREADS (a number, or an error), at most
    // the cores available, with a note when lowered (ferrofmm_io::threads,
    // shared with ferrofmm-mpi).
    let threads = ferrofmm_io::threads::choose(cli.threads, 1)?;
    if let Some(note) = &threads.note {
        eprintln!("{note}");
    }
    let t = threads.count;
    rayon::ThreadPoolBuilder::new()
        .num_threads(t)
        .build_global()
        .map_err(|e| CliError::InvalidArgument(format!("cannot start {t} threads: {e}")))?;
    match &cli.command {
        Command::Demo(args) => commands::demo::demo(args),
        Command::Eval(args) => commands::eval::eval(args),
        Command::Sweep(args) => commands::sweep::sweep(args, cli.threads),
        Command::Calibrate(args) => commands::calibrate::calibrate(args),
    }
}
