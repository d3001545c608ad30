//! Integration tests of the `ferrofmm` command, in one binary: each file below
//! is a module, so the generic driver is compiled once for all of them instead
//! of once per file.

mod bad_input;
mod cache;
mod calibrate;
mod common;
mod demo;
mod eval;
mod file_forms;
mod hostile;
mod output_safety;
mod periodic;
mod physics;
mod pipes;
mod precompute;
mod quiet;
mod reporting;
mod stokes_layers;
mod streams;
mod sweep;
