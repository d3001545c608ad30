//! Runs the `ferrofmm-mpi` binary under `mpirun` with 1 to 4 ranks
//! (`--oversubscribe`: CI machines have 2 cores): the distributed tree must
//! equal the single-machine tree for every input and layout, and bad input
//! on one rank must be the same error on every rank, without a hang (each
//! run is killed after a time limit).

mod cache;
mod calibration;
mod common;
mod eval;
mod eval_input;
mod fmm;
mod layers;
mod tree;
