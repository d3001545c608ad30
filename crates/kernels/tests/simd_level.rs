//! The process-global SIMD override (own test binary: it changes global
//! state that other tests' `Laplace3d::evaluate` calls would observe).

use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d, SimdLevel, laplace_p2p_with, set_simd_level};

#[test]
fn global_override_drives_the_trait_dispatch() {
    let s = [0.1f64, 0.2, 0.3, -0.4, 0.5, 0.6, 0.9, -0.8, 0.7];
    let q = [1.0f64, -2.0, 0.5];
    let t: Vec<f64> = (0..30).map(|i| (i as f64 * 0.37).sin()).collect();
    for level in SimdLevel::supported() {
        assert_eq!(set_simd_level(Some(level)), level);
        assert_eq!(SimdLevel::active(), level);
        let mut a = vec![0.0; 40];
        let mut b = vec![0.0; 40];
        Laplace3d.evaluate(EvalMode::PotentialGradient, &s, &q, &t, &mut a);
        laplace_p2p_with(level, EvalMode::PotentialGradient, &s, &q, &t, &mut b);
        assert_eq!(a, b, "{level}");
    }
    // Unsupported requests are clamped.
    assert_eq!(
        set_simd_level(Some(SimdLevel::Avx512)),
        SimdLevel::detected()
    );
    set_simd_level(None);
    assert_eq!(SimdLevel::active(), SimdLevel::detected());
}
