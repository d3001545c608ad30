//! The built-in M2L schemes pass the public conformance check
//! (`ferrofmm_field::plumbing::conformance`), as a scheme written outside
//! the crate would.

use ferrofmm_field::plumbing::conformance::{check_scheme, full_level_pairs};
use ferrofmm_field::{
    DenseConfig, DenseM2l, N_TRANSFER_VECTORS, OperatorParams, SvdConfig, SvdM2l,
    default_svd_tolerance, transfer_vector_index,
};
use ferrofmm_kernels::{
    EvalMode, Helmholtz3d, Kernel, Laplace3d, ModifiedHelmholtz3d, Precision, Real, Stokes3d,
};

#[test]
fn the_check_covers_every_transfer_vector() {
    let mut seen = vec![false; N_TRANSFER_VECTORS];
    for (t, s, v) in full_level_pairs(3) {
        assert!(t < 512 && s < 512);
        seen[transfer_vector_index(v).unwrap()] = true;
    }
    assert!(seen.iter().all(|&x| x));
    // Level 2 (4^3 boxes): a box's V list has at most 189 entries.
    let pairs = full_level_pairs(2);
    let mut per_target = vec![0; 64];
    for (t, _, _) in &pairs {
        per_target[*t] += 1;
    }
    assert!(per_target.iter().all(|&c| c > 0 && c <= 189));
}

#[test]
fn dense_conforms() {
    let r = check_scheme::<f64, DenseM2l<f64>, _>(
        &Laplace3d,
        &OperatorParams::new(4),
        &DenseConfig,
        1e-13,
    )
    .unwrap();
    assert!(r.pairs > 0 && r.memory_bytes > 0);
    let k = ModifiedHelmholtz3d::new(2.0).unwrap();
    check_scheme::<f64, DenseM2l<f64>, _>(&k, &OperatorParams::new(4), &DenseConfig, 1e-13)
        .unwrap();
    check_scheme::<f32, DenseM2l<f32>, _>(&Laplace3d, &OperatorParams::new(4), &DenseConfig, 1e-6)
        .unwrap();
}

#[test]
fn svd_conforms_to_its_tolerance() {
    for p in [3, 5] {
        let bound = 10.0 * default_svd_tolerance(Precision::F64, p);
        let r = check_scheme::<f64, SvdM2l<f64>, _>(
            &Laplace3d,
            &OperatorParams::new(p),
            &SvdConfig::default(),
            bound,
        )
        .unwrap();
        println!("svd p = {p}: {:.2e} (bound {bound:.1e})", r.relative_error);
    }
    let k = ModifiedHelmholtz3d::new(2.0).unwrap();
    check_scheme::<f64, SvdM2l<f64>, _>(
        &k,
        &OperatorParams::new(4),
        &SvdConfig::default(),
        10.0 * default_svd_tolerance(Precision::F64, 4),
    )
    .unwrap();
}

/// A scheme that drops a group is caught.
#[test]
fn a_broken_scheme_fails() {
    let r = check_scheme::<f64, SvdM2l<f64>, _>(
        &Laplace3d,
        &OperatorParams::new(4),
        &SvdConfig {
            rank: Some(1),
            ..SvdConfig::default()
        },
        1e-6,
    );
    let e = r.unwrap_err();
    assert!(e.contains("relative error"), "{e}");
}

#[test]
fn fft_conforms_exactly() {
    use ferrofmm_field::{FftConfig, FftM2l};
    for p in [2, 3, 4, 6, 7] {
        let r = check_scheme::<f64, FftM2l<f64>, _>(
            &Laplace3d,
            &OperatorParams::new(p),
            &FftConfig,
            1e-12,
        )
        .unwrap();
        println!("fft p = {p}: {:.2e}", r.relative_error);
    }
    let k = ModifiedHelmholtz3d::new(2.0).unwrap();
    check_scheme::<f64, FftM2l<f64>, _>(&k, &OperatorParams::new(5), &FftConfig, 1e-12).unwrap();
    check_scheme::<f32, FftM2l<f32>, _>(&Laplace3d, &OperatorParams::new(5), &FftConfig, 1e-6)
        .unwrap();
}

/// Helmholtz's blocks as a `2 x 2` real kernel that does not say it is
/// complex: the FFT scheme's general path of `c^2` real convolutions.
#[derive(Clone)]
struct RealForm(Helmholtz3d);

impl Kernel for RealForm {
    fn name(&self) -> String {
        "helmholtz3d-real-form".to_string()
    }
    fn parameters(&self) -> Vec<f64> {
        self.0.parameters()
    }
    fn homogeneity(&self) -> Option<f64> {
        self.0.homogeneity()
    }
    fn components(&self) -> usize {
        2
    }
    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
        self.0.kernel_value(d)
    }
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
        self.0.kernel_gradient(d)
    }
    fn evaluate<T: Real>(&self, mode: EvalMode, s: &[T], q: &[T], t: &[T], out: &mut [T]) {
        self.0.evaluate(mode, s, q, t, out)
    }
    fn assemble<T: Real>(&self, sources: &[T], targets: &[T], matrix: &mut [T]) {
        self.0.assemble(sources, targets, matrix)
    }
}

/// Kernels with several components: the `3 x 3` Stokeslet (odd and even
/// orders) and the Helmholtz kernel (per-level operators; `k W = 8` on the
/// check's domain of width 2), in `f64` and `f32`: the same operator as
/// the dense products, both on the complex path (one complex convolution
/// per pair, real and damped wavenumbers) and in the
/// general real form (`c^2` real convolutions).
#[test]
fn fft_conforms_exactly_for_kernels_with_components() {
    use ferrofmm_field::{FftConfig, FftM2l};
    let stokes = Stokes3d::new(0.7).unwrap();
    for p in [3, 4] {
        let r = check_scheme::<f64, FftM2l<f64>, _>(
            &stokes,
            &OperatorParams::new(p),
            &FftConfig,
            1e-12,
        )
        .unwrap();
        println!("fft stokes p = {p}: {:.2e}", r.relative_error);
    }
    let helmholtz = Helmholtz3d::new(4.0).unwrap();
    let damped = Helmholtz3d::new_complex(3.0, 1.5).unwrap();
    for (k, p) in [(&helmholtz, 4), (&damped, 3)] {
        let r = check_scheme::<f64, FftM2l<f64>, _>(k, &OperatorParams::new(p), &FftConfig, 1e-12)
            .unwrap();
        println!("fft {} p = {p}: {:.2e}", k.name(), r.relative_error);
    }
    check_scheme::<f32, FftM2l<f32>, _>(&helmholtz, &OperatorParams::new(3), &FftConfig, 1e-5)
        .unwrap();
    let r = check_scheme::<f64, FftM2l<f64>, _>(
        &RealForm(helmholtz),
        &OperatorParams::new(3),
        &FftConfig,
        1e-12,
    )
    .unwrap();
    println!("fft helmholtz in real form p = 3: {:.2e}", r.relative_error);
}

/// Order 10 (grid 20: the smooth size at or above `2p - 1`, even past the
/// prime 19), every transfer vector, every column layout. (Orders 8, 11
/// and 12, grids 15, 21 and 24, passed too; the lower orders of
/// `fft_conforms_exactly` cover odd and even grids already, 5 and 7 odd.)
#[test]
fn fft_conforms_exactly_at_high_orders() {
    use ferrofmm_field::{FftConfig, FftM2l};
    let r = check_scheme::<f64, FftM2l<f64>, _>(
        &Laplace3d,
        &OperatorParams::new(10),
        &FftConfig,
        1e-12,
    )
    .unwrap();
    println!("fft p = 10: {:.2e}", r.relative_error);
}

#[test]
fn fft_needs_one_lattice() {
    use ferrofmm_field::{FftConfig, FftM2l, FieldError, M2lScheme};
    let mut params = OperatorParams::new(4);
    params.radii.downward_check = 1.2;
    let e = FftM2l::<f64>::precompute(&Laplace3d, &params, &FftConfig, 1.0, 3)
        .err()
        .unwrap();
    assert!(
        matches!(e, FieldError::InvalidParams(ref m) if m.contains("equal")),
        "{e}"
    );
}
