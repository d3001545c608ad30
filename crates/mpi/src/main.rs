//! `ferrofmm-mpi`: under `mpirun`, evaluate the distributed FMM (`eval`),
//! build a distributed octree and report per-rank figures (`tree`), or
//! check them against the single machine (`check`, `bad`, `fmm-check`;
//! what the tests run).

mod check;
mod check_fmm;
mod eval;
mod eval_io;
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

fn main() {
    let cli = Cli::parse();
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
    drop(universe);
    std::process::exit(code);
}
