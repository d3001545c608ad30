//! Integration tests of ferrofmm-field, in one binary: each file below is a
//! module, so the generic driver is compiled once for all of them instead of
//! once per file.

mod cache;
mod cache_policy;
mod common;
mod conformance;
mod convergence;
mod m2l_schemes;
mod measurements;
mod precompute;
mod single_operators;
mod stability;
