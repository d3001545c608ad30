//! Dense Laplace matrix assembly against the pairwise reference.

use crate::common;

use common::{levels, random_points};
use ferrofmm_kernels::{
    Kernel, Laplace3d, ModifiedHelmholtz3d, Real, laplace_assemble_with, reference,
};

fn check<T: Real>(ns: usize, nt: usize) {
    let (s, _) = random_points::<T>(61 + ns as u64, ns);
    let (mut t, _) = random_points::<T>(62 + nt as u64, nt);
    let k = ns.min(nt).min(3);
    t[..3 * k].copy_from_slice(&s[..3 * k]); // coincident pairs -> 0
    let mut expected = vec![T::ZERO; ns * nt];
    reference::assemble_pairwise(&Laplace3d, &s, &t, &mut expected);
    for level in levels() {
        let mut a = vec![T::ONE; ns * nt];
        laplace_assemble_with(level, &s, &t, &mut a);
        // Same operations in the same order: identical values.
        assert_eq!(a, expected, "{level} {:?} {ns}x{nt}", T::PRECISION);
    }
    let mut a = vec![T::ZERO; ns * nt];
    Laplace3d.assemble(&s, &t, &mut a);
    assert_eq!(a, expected);
}

#[test]
fn matches_reference_bitwise() {
    for (ns, nt) in [(0, 5), (5, 0), (1, 1), (7, 9), (17, 33), (64, 64)] {
        check::<f64>(ns, nt);
        check::<f32>(ns, nt);
    }
}

/// Large enough to take the row-parallel path.
#[test]
fn parallel_path_matches_reference() {
    check::<f64>(250, 190);
    check::<f32>(190, 250);
}

#[test]
fn yukawa_default_assembly_and_k0() {
    let (s, _) = random_points::<f64>(71, 20);
    let (t, _) = random_points::<f64>(72, 10);
    let mut a = vec![0.0; 200];
    let mut b = vec![0.0; 200];
    ModifiedHelmholtz3d::new(0.0)
        .unwrap()
        .assemble(&s, &t, &mut a);
    Laplace3d.assemble(&s, &t, &mut b);
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() <= 2.0 * f64::EPSILON * y.abs());
    }
}
