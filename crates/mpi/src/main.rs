//! `ferrofmm-mpi`: under `mpirun`, evaluate the distributed FMM (`eval`),
//! build a distributed octree and report per-rank figures (`tree`), or
//! check them against the single machine (`check`, `bad`, `fmm-check`;
//! what the tests run).

mod check;
mod check_fmm;
mod eval;
mod eval_io;
mod eval_layers;
mod eval_report;
mod report;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "ferrofmm-mpi",
    about = "Distributed octree over MPI (run under mpirun)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The distributed FMM: points and charges from files (or generated),
    /// the result in the input order, per-rank times, bytes and imbalance.
    Eval(Box<eval::EvalArgs>),
    /// Build the tree; print per-rank counts, imbalance, ghosts, bytes sent
    /// and phase times.
    Tree(report::TreeArgs),
    /// Build trees of test inputs on all ranks and compare them with the
    /// single-machine tree (exit status 1 on any difference).
    Check(check::CheckArgs),
    /// Give one rank bad input; succeed only if every rank gets the same
    /// error.
    Bad(check::BadArgs),
    /// Evaluate test inputs with the distributed FMM on all ranks and
    /// compare with the single-machine FMM on the same tree (exit status 1
    /// on any difference above the tolerance).
    FmmCheck(check_fmm::FmmCheckArgs),
}

/// The exit status once the command has finished (-1 before): `mpirun`
/// sends SIGTERM to the ranks still finalising when one rank exits, which
/// then must not report an interrupt.
static FINISHED: std::sync::atomic::AtomicI32 = std::sync::atomic::AtomicI32::new(-1);

/// SIGINT / SIGTERM (what `mpirun` forwards on Ctrl-C): remove the
/// temporary output file (rank 0's, while the output is being written)
/// and exit with status 130 instead of leaving it behind (after the
/// command finished: quietly, with its status). `SIGXFSZ` (a
/// write beyond `ulimit -f`) is caught so that the write fails with
/// `EFBIG` and is cleaned up like any other failed write.
fn install_interrupt() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};
    let _ = signal_hook::flag::register(
        signal_hook::consts::SIGXFSZ,
        Arc::new(AtomicBool::new(false)),
    );
    let flag = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        if signal_hook::flag::register(signal, flag.clone()).is_err() {
            return;
        }
    }
    let _ = std::thread::Builder::new()
        .name("ferrofmm-mpi-interrupt".into())
        .spawn(move || {
            while !flag.load(Ordering::Relaxed) {
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
            ferrofmm_io::output::remove_temporaries();
            let done = FINISHED.load(Ordering::SeqCst);
            if done >= 0 {
                std::process::exit(done);
            }
            eprintln!("error: interrupted");
            std::process::exit(130)
        });
}

fn main() {
    let cli = Cli::parse();
    install_interrupt();
    let Some(universe) = mpi::initialize() else {
        eprintln!("MPI could not be initialised");
        std::process::exit(2);
    };
    let world = universe.world();
    let code = match cli.command {
        Command::Eval(a) => eval::run(&world, &a),
        Command::Tree(a) => report::run(&world, &a),
        Command::Check(a) => check::run(&world, &a),
        Command::Bad(a) => check::run_bad(&world, &a),
        Command::FmmCheck(a) => check_fmm::run(&world, &a),
    };
    FINISHED.store(code, std::sync::atomic::Ordering::SeqCst);
    drop(universe);
    std::process::exit(code);
}
