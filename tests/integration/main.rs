//! The facade crate used as a user would: a kernel and an M2L scheme written
//! outside the library, in one binary: each file below is a module, so the
//! generic driver is compiled once for all of them instead of once per file.

mod custom_kernel;
mod custom_m2l;
