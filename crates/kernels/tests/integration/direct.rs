//! Parallel direct summation and its checked variant.

use crate::common;

use common::random_points;
use ferrofmm_kernels::{
    DIRECT_SUM_BLOCK, EvalMode, Kernel, KernelError, Laplace3d, ModifiedHelmholtz3d, check_inputs,
    direct_sum, direct_sum_checked,
};

fn equals_serial<K: Kernel>(kernel: &K) {
    // More targets than one block, not a multiple of it.
    let nt = 2 * DIRECT_SUM_BLOCK + 37;
    let (s, q) = random_points::<f64>(51, 300);
    let (t, _) = random_points::<f64>(52, nt);
    for mode in [EvalMode::Potential, EvalMode::PotentialGradient] {
        let w = mode.values_per_target();
        let init: Vec<f64> = (0..w * nt).map(|i| (i % 5) as f64).collect();
        let mut par = init.clone();
        let mut ser = init.clone();
        direct_sum(kernel, mode, &s, &q, &t, &mut par);
        // Serial, block by block, through the kernel's own `evaluate`:
        // the same computation, so the same bits.
        for (tb, ob) in t
            .chunks(3 * DIRECT_SUM_BLOCK)
            .zip(ser.chunks_mut(w * DIRECT_SUM_BLOCK))
        {
            kernel.evaluate(mode, &s, &q, tb, ob);
        }
        assert_eq!(par, ser, "{} {mode:?}", kernel.name());
        // And one serial call over all targets (target sums do not depend on
        // the blocking).
        let mut one = init.clone();
        kernel.evaluate(mode, &s, &q, &t, &mut one);
        assert_eq!(par, one, "{} {mode:?} single call", kernel.name());
    }
}

#[test]
fn direct_sum_equals_serial() {
    equals_serial(&Laplace3d);
    equals_serial(&ModifiedHelmholtz3d::new(1.5).unwrap());
}

#[test]
fn direct_sum_f32_and_empty() {
    let (s, q) = random_points::<f32>(53, 100);
    let (t, _) = random_points::<f32>(54, 300);
    let mut a = vec![0.0f32; 300];
    let mut b = vec![0.0f32; 300];
    direct_sum(&Laplace3d, EvalMode::Potential, &s, &q, &t, &mut a);
    Laplace3d.evaluate(EvalMode::Potential, &s, &q, &t, &mut b);
    assert_eq!(a, b);
    let mut empty: Vec<f32> = vec![];
    direct_sum(
        &Laplace3d,
        EvalMode::PotentialGradient,
        &s,
        &q,
        &[],
        &mut empty,
    );
    let mut c = vec![2.0f32; 4 * 300];
    direct_sum_checked(
        &Laplace3d,
        EvalMode::PotentialGradient,
        &[],
        &[],
        &t,
        &mut c,
    )
    .unwrap();
    assert!(c.iter().all(|&v| v == 2.0));
}

#[test]
fn checked_variant_reports_errors() {
    let s = [0.0f64, 0.0, 0.0, 1.0, 1.0, 1.0];
    let q = [1.0f64, 2.0];
    let t = [0.5f64, 0.5, 0.5];
    let pot = EvalMode::Potential;
    let grad = EvalMode::PotentialGradient;
    let mut out1 = [0.0f64; 1];
    let mut out4 = [0.0f64; 4];

    assert_eq!(
        direct_sum_checked(&Laplace3d, pot, &s, &q, &t, &mut out1),
        Ok(())
    );
    assert!(out1[0] > 0.0);
    assert_eq!(
        direct_sum_checked(&Laplace3d, pot, &s[..5], &q, &t, &mut out1),
        Err(KernelError::NotMultipleOf3 {
            what: "sources",
            len: 5
        })
    );
    assert_eq!(
        direct_sum_checked(&Laplace3d, pot, &s, &q, &t[..2], &mut out1),
        Err(KernelError::NotMultipleOf3 {
            what: "targets",
            len: 2
        })
    );
    assert_eq!(
        direct_sum_checked(&Laplace3d, pot, &s, &q[..1], &t, &mut out1),
        Err(KernelError::ChargesLength {
            n_sources: 2,
            n_charges: 1
        })
    );
    assert_eq!(
        direct_sum_checked(&Laplace3d, grad, &s, &q, &t, &mut out1),
        Err(KernelError::OutputLength {
            expected: 4,
            found: 1,
            values_per_target: 4
        })
    );
    let mut bad = s;
    bad[4] = f64::NAN;
    let before = out4;
    assert!(matches!(
        direct_sum_checked(&Laplace3d, grad, &bad, &q, &t, &mut out4),
        Err(KernelError::NonFinite {
            what: "sources",
            index: 4,
            ..
        })
    ));
    assert_eq!(out4, before, "output untouched on error");
    assert!(matches!(
        check_inputs(pot, &s, &[1.0, f64::INFINITY], &t, &out1),
        Err(KernelError::NonFinite {
            what: "charges",
            index: 1,
            ..
        })
    ));
    assert!(matches!(
        check_inputs(pot, &s, &q, &[0.0, f64::NEG_INFINITY, 0.0], &out1),
        Err(KernelError::NonFinite {
            what: "targets",
            index: 1,
            ..
        })
    ));
    // Messages are informative.
    let e = direct_sum_checked(&Laplace3d, pot, &s, &q[..1], &t, &mut out1).unwrap_err();
    assert_eq!(e.to_string(), "2 sources but 1 charges");
}

#[test]
#[should_panic(expected = "direct_sum")]
fn unchecked_panics_on_bad_lengths() {
    let mut out = [0.0f64; 2];
    direct_sum(
        &Laplace3d,
        EvalMode::Potential,
        &[0.0; 3],
        &[1.0],
        &[1.0; 3],
        &mut out,
    );
}
