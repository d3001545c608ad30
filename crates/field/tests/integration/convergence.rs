//! Convergence of the KIFMM operators with the order, in f64, against
//! direct summation.

use crate::common;

use common::*;
use ferrofmm_field::{OperatorParams, Operators};
use ferrofmm_kernels::Laplace3d;

/// P2M -> M2L -> DC2E -> L2P (worst relative L2 error over six V-list box
/// pairs, from the closest face neighbour `[2, 0, 0]` to the far corner
/// `[3, 3, 3]`, two random draws of 150 sources and targets each) and the
/// full chain P2M -> M2M -> M2L -> L2L -> L2P must fall steadily with the
/// order.
#[test]
fn error_falls_steadily_with_order() {
    println!("| p | n | P2M->M2L->L2P | P2M->M2M->M2L->L2L->L2P |");
    println!("|---|---|---|---|");
    let mut errors = Vec::new();
    for p in 2..=10 {
        let ops = Operators::<f64>::new(&Laplace3d, &OperatorParams::new(p), 1.0, 3).unwrap();
        let e = (0..2)
            .map(|s| chain_error(&Laplace3d, &ops, 2, 150, 100 + s))
            .fold(0.0, f64::max);
        let f = (0..2)
            .map(|s| full_chain_error(&Laplace3d, &ops, 2, 150, 200 + s))
            .fold(0.0, f64::max);
        println!("| {p} | {} | {e:.2e} | {f:.2e} |", ops.n_surface());
        errors.push((p, e, f));
    }
    for w in errors.windows(2) {
        let ((p0, e0, f0), (p1, e1, f1)) = (w[0], w[1]);
        assert!(
            e1 < 0.7 * e0,
            "P2M->M2L->L2P error does not fall from p={p0} ({e0:.2e}) to p={p1} ({e1:.2e})"
        );
        assert!(
            f1 < 0.7 * f0,
            "full-chain error does not fall from p={p0} ({f0:.2e}) to p={p1} ({f1:.2e})"
        );
    }
    // About an order of magnitude per order overall.
    let (_, e2, _) = errors[0];
    let (_, e10, f10) = errors[8];
    assert!(e2 > 1e-3 && e10 < 3e-9, "p=2: {e2:.2e}, p=10: {e10:.2e}");
    assert!(f10 < 3e-9, "full chain p=10: {f10:.2e}");
}
