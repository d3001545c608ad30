//! `ferrofmm-mpi`: build a distributed octree under `mpirun` and report
//! per-rank figures (`tree`), or check it against the single-machine tree
//! (`check`, `bad`; what the tests run).

mod check;
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
    /// Build the tree; print per-rank counts, imbalance, ghosts, bytes sent
    /// and phase times.
    Tree(report::TreeArgs),
    /// Build trees of test inputs on all ranks and compare them with the
    /// single-machine tree (exit status 1 on any difference).
    Check(check::CheckArgs),
    /// Give one rank bad input; succeed only if every rank gets the same
    /// error.
    Bad(check::BadArgs),
}

fn main() {
    let cli = Cli::parse();
    let Some(universe) = mpi::initialize() else {
        eprintln!("MPI could not be initialised");
        std::process::exit(2);
    };
    let world = universe.world();
    let code = match cli.command {
        Command::Tree(a) => report::run(&world, &a),
        Command::Check(a) => check::run(&world, &a),
        Command::Bad(a) => check::run_bad(&world, &a),
    };
    drop(universe);
    std::process::exit(code);
}
