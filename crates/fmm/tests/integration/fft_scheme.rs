//! The FFT M2L scheme through the whole FMM: the same operator as dense
//! M2L, so the same values up to rounding and the same error against
//! direct summation, for a homogeneous and a non-homogeneous kernel, f64
//! and f32, zero-mean and positive charges, a thin set.

use ferrofmm_field::FftConfig;
use ferrofmm_fmm::{Charges, FmmBuilder, Geometry, relative_errors, sample_indices};
use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d, ModifiedHelmholtz3d, Real};

fn compare<T: Real, K: Kernel + Clone>(
    kernel: K,
    geometry: Geometry,
    order: usize,
    charges: Charges,
) {
    let n = 3000;
    let points: Vec<T> = geometry.points(n, 5);
    let q: Vec<T> = charges.generate(n, 6);
    let mode = EvalMode::PotentialGradient;
    let builder = || {
        FmmBuilder::new(&points)
            .kernel(kernel.clone())
            .order(order)
            .leaf_size(30)
            .mode(mode)
    };
    let fft = builder()
        .build_with::<ferrofmm_field::FftM2l<T>>(FftConfig)
        .unwrap();
    let dense = builder().build_dense().unwrap();
    let (vf, vd) = (fft.evaluate(&q).unwrap(), dense.evaluate(&q).unwrap());
    let sample = sample_indices(n, 500);
    let err = |v: &[T]| relative_errors(&kernel, mode, &points, &q, &points, v, &sample);
    let (ef, ed) = (err(&vf), err(&vd));
    let diff = vf
        .iter()
        .zip(&vd)
        .map(|(a, b)| (a.to_f64() - b.to_f64()).powi(2))
        .sum::<f64>()
        .sqrt()
        / vd.iter().map(|b| b.to_f64().powi(2)).sum::<f64>().sqrt();
    let rounding = if T::PRECISION == ferrofmm_kernels::Precision::F64 {
        1e-11
    } else {
        2e-5
    };
    let label = format!(
        "{} {geometry:?} p = {order} {charges:?} {:?}",
        kernel.name(),
        T::PRECISION
    );
    assert!(
        diff < rounding,
        "{label}: fft and dense differ by {diff:.2e}"
    );
    assert!(
        ef.potential <= 1.05 * ed.potential + rounding,
        "{label}: potential {:.2e} against dense {:.2e}",
        ef.potential,
        ed.potential
    );
    let (gf, gd) = (ef.gradient.unwrap(), ed.gradient.unwrap());
    assert!(
        gf <= 1.05 * gd + rounding,
        "{label}: gradient {gf:.2e} against dense {gd:.2e}"
    );
}

#[test]
fn fft_equals_dense_through_the_fmm() {
    for charges in [Charges::Signed, Charges::Positive] {
        compare::<f64, _>(Laplace3d, Geometry::Cube, 6, charges);
        compare::<f64, _>(Laplace3d, Geometry::Plane, 4, charges);
    }
    compare::<f64, _>(
        ModifiedHelmholtz3d::new(2.0).unwrap(),
        Geometry::Plummer,
        5,
        Charges::Signed,
    );
    compare::<f32, _>(Laplace3d, Geometry::Cube, 5, Charges::Signed);
}
