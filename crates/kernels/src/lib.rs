//! # ferrofmm-kernels
//!
//! The [`Kernel`] trait through which the whole FMM sees a Green's function,
//! the kernels we ship ([`Laplace3d`], [`ModifiedHelmholtz3d`], the
//! oscillatory [`Helmholtz3d`] in complex form and the [`Stokes3d`]
//! Stokeslet, the last two with several [components](Kernel::components)), fast
//! particle-to-particle (P2P) evaluation with runtime CPU dispatch
//! ([`laplace_p2p_with`], [`modified_helmholtz_p2p_with`], [`SimdLevel`]),
//! dense kernel matrices ([`laplace_assemble_with`]), and parallel direct
//! summation ([`direct_sum`], [`direct_sum_checked`], [`check_inputs`]).
//!
//! ```
//! use ferrofmm_kernels::{direct_sum, EvalMode, Laplace3d};
//! // Two unit charges; potential and gradient at a third point.
//! let sources = [0.0f64, 0.0, 0.0, 0.0, 0.0, 1.0];
//! let charges = [1.0f64, 1.0];
//! let targets = [0.0f64, 0.0, 0.5];
//! let mut out = [0.0f64; 4]; // [phi, dphi/dx, dphi/dy, dphi/dz]
//! direct_sum(&Laplace3d, EvalMode::PotentialGradient, &sources, &charges, &targets, &mut out);
//! let k = 1.0 / (4.0 * std::f64::consts::PI);
//! assert!((out[0] - 4.0 * k).abs() < 1e-15);
//! assert!(out[3].abs() < 1e-15); // symmetric: no force along z
//! ```
//!
//! ## Data layout
//!
//! * **Points are interleaved** `[x0, y0, z0, x1, y1, z1, ...]`; charges hold
//!   one value per source; outputs hold 1 (`[phi]`) or 4 (`[phi, gx, gy, gz]`)
//!   values per target, interleaved ([`EvalMode::values_per_target`]).
//!   Every crate of the workspace uses this layout. A kernel with `c`
//!   components stores `c` values per quantity, quantity-major (complex
//!   numbers as `[re, im]` pairs; Stokes forces and velocities as
//!   3-vectors): see [`Kernel`].
//! * Why not structure-of-arrays? It is what users hold (`&[[f64; 3]]` casts
//!   to it for free), the tree sorts and gathers points as one contiguous
//!   record each, and the P2P does not need SoA: it vectorises over
//!   **targets** ("target lanes"). A block of 8 (`f64`) or 16 (`f32`) targets
//!   per register is de-interleaved once into registers and stays there,
//!   together with its accumulators, while the loop streams over the sources,
//!   each of which is just three scalar broadcasts (plus the charge) from one
//!   cache line, whatever the layout. The de-interleave costs `O(block)` and
//!   is amortised over all sources (a few hundred in an FMM leaf pair); no
//!   horizontal reductions are needed, and each target's sum runs in source
//!   order like the scalar reference. Dense assembly, which is unit-stride in
//!   sources, de-interleaves the sources once per matrix instead.
//!
//! ## Vectorisation and dispatch
//!
//! The crate builds for the portable baseline (no `-C target-cpu`). One P2P
//! loop, the lane engine of [`lanes`], serves every kernel: a kernel plugs
//! in a per-pair micro-kernel on SIMD registers ([`lanes::PairKernel`];
//! for a scalar kernel with charges the shorter [`lanes::LaneKernel`], for
//! a radial one [`lanes::RadialLaneKernel`], from which dipoles and
//! Hessians are composed), and the loop is compiled as AVX-512F, AVX2+FMA
//! and portable lane-chunked versions (`#[target_feature]`, chosen at run
//! time by [`SimdLevel::detected`], cached). Laplace, modified Helmholtz,
//! Helmholtz, Stokes and kernels written outside the crate all run in it,
//! with charges, dipoles or both, complex values and several components.
//! Every kernel's P2P has the same entry points: [`Kernel::evaluate`] and
//! [`Kernel::evaluate_sources`] at [`SimdLevel::active`], and
//! [`lanes::evaluate_sources_with`] at a given level ([`laplace_p2p_with`]
//! and [`modified_helmholtz_p2p_with`] are the same for those two kernels).
//! [`SimdLevel`] lets tests and benchmarks force a level, per call or
//! globally ([`set_simd_level`], env `FERROFMM_SIMD=scalar|avx2|avx512`).
//! The AVX-512 path uses `vrsqrt14` with a polynomial refinement to full
//! precision; see [`lanes`] for the error analysis.
//!
//! ## Layout of the crate
//!
//! One folder per kernel, each with its maths (module docs), its
//! [`Kernel`] impl (`mod.rs`) and its micro-kernel (`pair.rs`):
//! `laplace/` (and its dense assembly and the periodic Ewald sums of
//! [`ewald`]: [`EwaldSum`], [`PeriodicGreen`]), `modified_helmholtz/` (Yukawa),
//! `helmholtz/` (the oscillatory kernel) and `stokes/`. Shared machinery
//! stays outside them: the lane engine and its instruction sets
//! (`lanes/`), direct summation (`direct.rs`), the pairwise references
//! (`reference.rs`), [`Real`] and [`SimdLevel`].
//!
//! ## Conventions
//!
//! `K(x, x) := 0`: coincident pairs contribute exactly zero in every path
//! (masked in SIMD code, never NaN or Inf). `evaluate` accumulates into its
//! output. Everything is generic over [`Real`] (`f32`, `f64`).

#![warn(missing_docs)]

mod direct;
mod error;
pub mod helmholtz;
mod kernel;
pub mod lanes;
pub mod laplace;
mod lattice;
pub mod modified_helmholtz;
mod real;
pub mod reference;
pub mod registry;
mod simd;
pub mod stokes;

pub use direct::{
    DIRECT_SUM_BLOCK, check_inputs, check_kernel_inputs, check_source_inputs, direct_sum,
    direct_sum_checked, direct_sum_sources, direct_sum_sources_checked,
};
pub use error::KernelError;
pub use helmholtz::Helmholtz3d;
pub use kernel::{EvalMode, Kernel, SourceKind};
pub use laplace::ewald;
pub use laplace::ewald::{
    EwaldOptions, EwaldParameters, EwaldSum, PeriodicCell, PeriodicGreen, RodGreen, SlabGreen,
};
pub use laplace::{INV_4PI, Laplace3d, laplace_assemble_with, laplace_p2p, laplace_p2p_with};
pub use modified_helmholtz::{ModifiedHelmholtz3d, modified_helmholtz_p2p_with};
pub use real::{Precision, Real};
pub use registry::{
    AutoScheme, BuiltinKernel, KernelChoice, KernelDescription, KernelVisitor,
    ParameterDescription, ParseKernelError, TuningFamily,
};
pub use simd::{ParseSimdLevelError, SimdLevel, set_simd_level};
pub use stokes::Stokes3d;
pub use stokes::ewald::{PeriodicStokeslet, StokesEwaldSum};
