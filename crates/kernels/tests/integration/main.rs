//! Integration tests of ferrofmm-kernels (the process-global SIMD override has
//! its own binary, `simd_level`), in one binary: each file below is a module,
//! so the generic driver is compiled once for all of them instead of once per
//! file.

mod assemble;
mod common;
mod components;
mod direct;
mod ewald;
mod ewald_screened;
mod ewald_slab_rod;
mod ewald_stokes;
mod gradients;
mod helmholtz;
mod lane_kernel;
mod laplace_p2p;
mod sources;
