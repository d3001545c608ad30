//! Integration tests of ferrofmm-fmm, in one binary: each file below is a
//! module, so the generic driver is compiled once for all of them instead of
//! once per file.

mod accuracy;
mod calibration;
mod components;
mod concurrency;
mod defaults;
mod determinism;
mod errors;
mod fft_scheme;
mod hostile;
mod memory;
mod outliers;
mod periodic;
mod periodic_images;
mod periodic_slab_rod;
mod periodic_stokes;
mod periodic_yukawa;
mod proptest_fmm;
mod registry;
mod right_sized;
mod sources;
mod stability_cache;
mod stability_common;
mod stability_geometry;
mod stability_input;
mod stability_numerics;
mod stokes_layers;
mod svd_truncation;
mod tolerance;
mod tree_fmm;
mod wider_root;

/// The operator cache that this binary's tests share: tests that build the
/// same kernel at the same orders again (the Stokeslet at orders 3-10 on two
/// point sets, its layers, its periodic cells) read the operators back
/// instead of recomputing them (`ferrofmm_testing::operator_cache`).
fn ops_cache() -> std::path::PathBuf {
    ferrofmm_testing::shared_operator_cache(std::path::Path::new(env!("CARGO_TARGET_TMPDIR")))
}

/// The M2L scheme of a test run: SVD, dense (the reference), or FFT (exact
/// operators, precomputed in milliseconds where the SVD's factorisations
/// take seconds).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Scheme {
    Svd,
    Dense,
    Fft,
}

impl Scheme {
    /// Build `builder` with this scheme and evaluate `densities`.
    fn evaluate<T: ferrofmm_kernels::Real, K: ferrofmm_kernels::Kernel>(
        self,
        builder: ferrofmm_fmm::FmmBuilder<'_, T, K>,
        densities: &[T],
    ) -> Vec<T> {
        match self {
            Scheme::Svd => builder.build_svd().unwrap().evaluate(densities),
            Scheme::Dense => builder.build_dense().unwrap().evaluate(densities),
            Scheme::Fft => builder
                .build_with::<ferrofmm_field::FftM2l<T>>(Default::default())
                .unwrap()
                .evaluate(densities),
        }
        .unwrap()
    }
}
