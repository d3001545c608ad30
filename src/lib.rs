#![doc = include_str!("../README.md")]

pub use ferrofmm_field as field;
pub use ferrofmm_fmm as fmm;
pub use ferrofmm_kernels as kernels;
pub use ferrofmm_tree as tree;

/// The names most programs need: `use ferrofmm::prelude::*;`.
pub mod prelude {
    pub use ferrofmm_field::{DenseM2l, M2lScheme, SvdM2l};
    pub use ferrofmm_fmm::{Fmm, FmmBuilder, FmmError, Geometry};
    pub use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d, ModifiedHelmholtz3d, Real};
}
