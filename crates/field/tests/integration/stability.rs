//! High-order stability of the check-to-equivalent pseudo-inverse: with the
//! default cutoff the error stays bounded in f32 and f64; without a cutoff
//! f32 blows up, and the library says so in its diagnostics. The table in
//! docs/stability.md comes from `measurements.rs::stability_table`.

use crate::common;

use common::*;
use ferrofmm_field::{AMPLIFICATION_WARNING, OperatorParams, Operators};
use ferrofmm_kernels::{Laplace3d, Real};

fn run<T: Real>(p: usize, rcond: Option<f64>) -> (f64, Vec<String>, f64) {
    let mut params = OperatorParams::new(p);
    params.pinv_rcond = rcond;
    let ops = Operators::<T>::new(&Laplace3d, &params, 1.0, 0).unwrap();
    let e = chain_error(&Laplace3d, &ops, 0, 100, 7);
    let d = ops.diagnostics();
    println!(
        "p={p:2} {} rcond={:>8}: error {e:.2e}, UC2E rank {}/{}, eps*cond {:.1e}, {} warning(s)",
        T::PRECISION.name(),
        rcond.map(|c| format!("{c:e}")).unwrap_or("default".into()),
        d.uc2e[0].rank,
        d.uc2e[0].n,
        d.rounding_amplification,
        d.warnings.len()
    );
    (e, d.warnings, d.rounding_amplification)
}

#[test]
fn default_cutoff_keeps_high_order_bounded() {
    for p in [12, 16] {
        let (e64, w64, _) = run::<f64>(p, None);
        assert!(e64 < 1e-9, "f64 p={p}: {e64:.2e}");
        assert!(w64.is_empty(), "{w64:?}");
        let (e32, w32, _) = run::<f32>(p, None);
        assert!(e32 < 1e-5, "f32 p={p}: {e32:.2e}");
        assert!(w32.is_empty(), "{w32:?}");
    }
}

#[test]
fn no_cutoff_is_flagged_when_it_breaks() {
    for p in [12, 16] {
        // f64 survives without a cutoff (the noise singular values are
        // ~1e-16 sigma_0 and f64 rounding amplified by 1e16 stays O(1)
        // relative to the check potential, far below the far-field signal).
        let (e64, w64, _) = run::<f64>(p, Some(0.0));
        assert!(e64 < 1e-8, "f64 p={p} without cutoff: {e64:.2e}");
        assert!(w64.is_empty());
        // f32 does not: rounding errors of 1e-7 amplified by 1e16.
        let (e32, w32, amp) = run::<f32>(p, Some(0.0));
        assert!(
            e32 > 1e-2,
            "f32 p={p} without cutoff unexpectedly fine: {e32:.2e}"
        );
        assert!(
            amp > AMPLIFICATION_WARNING && !w32.is_empty(),
            "garbage without a warning"
        );
    }
}

#[test]
fn garbage_is_never_silent() {
    // Whatever the cutoff, an error above 1e-3 comes with a warning.
    for rcond in [Some(1e-4), Some(1e-8), Some(1e-10), Some(1e-12), Some(0.0)] {
        let (e, w, _) = run::<f32>(10, rcond);
        assert!(
            e < 1e-3 || !w.is_empty(),
            "rcond {rcond:?}: error {e:.2e} without warning"
        );
    }
}
