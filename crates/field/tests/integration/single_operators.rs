//! Each operator on its own against direct summation, for the homogeneous
//! Laplace kernel (one operator set, rescaled) and the non-homogeneous
//! modified Helmholtz kernel (one set per level), in f64 and f32.

use crate::common;

use common::*;
use ferrofmm_field::{
    DenseConfig, DenseM2l, M2lScheme, OperatorParams, Operators, SurfaceKind, SvdConfig, SvdM2l,
    octant_offset,
};
use ferrofmm_kernels::{Kernel, Laplace3d, ModifiedHelmholtz3d, Real};
use ferrofmm_testing::points::in_shell;

const DEPTH: u32 = 4;

fn ops<T: Real, K: Kernel>(kernel: &K, p: usize) -> Operators<T> {
    Operators::new(kernel, &OperatorParams::new(p), 1.0, DEPTH).unwrap()
}

/// P2M at level 2, multipole evaluated in the far field (>= 3 half-widths).
fn p2m_error<T: Real, K: Kernel>(kernel: &K, ops: &Operators<T>) -> f64 {
    let mut rng = SplitMix64(1);
    let level = 2;
    let c = box_center(level, [1, 2, 1]);
    let h = ops.half_width(level);
    let src = in_box(&mut rng, 200, c, h);
    let q = positive_from(&mut rng, 200);
    let tgt = in_shell(&mut rng, 200, c, 3.0 * h, 6.0 * h);
    let phi = p2m(kernel, ops, level, c, &src, &q);
    let approx = eval_density(
        kernel,
        ops,
        SurfaceKind::UpwardEquivalent,
        level,
        c,
        &phi,
        &tgt,
    );
    relative_l2(&approx, &direct(kernel, &src, &q, &tgt))
}

/// P2M in each child at level 3, M2M into the parent; far field of the
/// parent against direct and against the parent's own P2M.
fn m2m_errors<T: Real, K: Kernel>(kernel: &K, ops: &Operators<T>) -> (f64, f64) {
    let mut rng = SplitMix64(2);
    let parent_level = 2;
    let cp = box_center(parent_level, [2, 1, 1]);
    let hp = ops.half_width(parent_level);
    let hc = hp / 2.0;
    let n = ops.n_surface();
    let mut all_src = Vec::new();
    let mut all_q = Vec::new();
    let mut parent = vec![T::ZERO; n];
    for octant in 0..8 {
        let o = octant_offset(octant);
        let cc = [cp[0] + hc * o[0], cp[1] + hc * o[1], cp[2] + hc * o[2]];
        let src = in_box(&mut rng, 40, cc, hc);
        let q = positive_from(&mut rng, 40);
        let phi_c = p2m(kernel, ops, parent_level + 1, cc, &src, &q);
        ops.m2m(parent_level + 1, octant, &phi_c, &mut parent);
        all_src.extend(src);
        all_q.extend(q);
    }
    let tgt = in_shell(&mut rng, 200, cp, 3.0 * hp, 6.0 * hp);
    let via_m2m = eval_density(
        kernel,
        ops,
        SurfaceKind::UpwardEquivalent,
        parent_level,
        cp,
        &parent,
        &tgt,
    );
    let phi_p = p2m(kernel, ops, parent_level, cp, &all_src, &all_q);
    let via_p2m = eval_density(
        kernel,
        ops,
        SurfaceKind::UpwardEquivalent,
        parent_level,
        cp,
        &phi_p,
        &tgt,
    );
    let exact = direct(kernel, &all_src, &all_q, &tgt);
    (
        relative_l2(&via_m2m, &exact),
        relative_l2(&via_m2m, &via_p2m),
    )
}

/// P2M in a source box, M2L through `scheme`, DC2E, L2P in the target box.
fn m2l_error<T: Real, K: Kernel, S: M2lScheme<T>>(
    kernel: &K,
    ops: &Operators<T>,
    scheme: &S,
    level: u32,
) -> f64 {
    let n = ops.n_surface();
    let vectors = [[2, 0, 0], [0, -3, 2], [3, 3, 3], [-2, -1, 1], [-3, 2, -3]];
    chain_error_with(kernel, ops, level, 100, 3, &vectors, |v, _, _, phi| {
        m2l_pair(scheme, level, n, v, phi)
    })
}

/// P2L at a level-2 parent from far sources, DC2E, L2L to each child, L2P.
fn l2l_error<T: Real, K: Kernel>(kernel: &K, ops: &Operators<T>) -> f64 {
    let mut rng = SplitMix64(4);
    let n = ops.n_surface();
    let parent_level = 2;
    let cp = box_center(parent_level, [1, 1, 2]);
    let hp = ops.half_width(parent_level);
    let hc = hp / 2.0;
    let src = in_shell(&mut rng, 300, cp, 3.0 * hp, 5.0 * hp);
    let q = positive_from(&mut rng, 300);
    let check = check_potential(
        kernel,
        ops,
        SurfaceKind::DownwardCheck,
        parent_level,
        cp,
        &src,
        &q,
    );
    let mut psi_p = vec![T::ZERO; n];
    ops.dc2e(parent_level, &check, &mut psi_p);
    let mut worst: f64 = 0.0;
    for octant in 0..8 {
        let o = octant_offset(octant);
        let cc = [cp[0] + hc * o[0], cp[1] + hc * o[1], cp[2] + hc * o[2]];
        let mut psi_c = vec![T::ZERO; n];
        ops.l2l(parent_level + 1, octant, &psi_p, &mut psi_c);
        let tgt = in_box(&mut rng, 50, cc, hc);
        let approx = eval_density(
            kernel,
            ops,
            SurfaceKind::DownwardEquivalent,
            parent_level + 1,
            cc,
            &psi_c,
            &tgt,
        );
        worst = worst.max(relative_l2(&approx, &direct(kernel, &src, &q, &tgt)));
    }
    worst
}

fn all_operators<T: Real, K: Kernel>(kernel: &K, p: usize, tol: f64) {
    let o = ops::<T, K>(kernel, p);
    assert!(
        o.diagnostics().warnings.is_empty(),
        "{:?}",
        o.diagnostics().warnings
    );
    let e_p2m = p2m_error(kernel, &o);
    let (e_m2m, e_m2m_vs_p2m) = m2m_errors(kernel, &o);
    let e_l2l = l2l_error(kernel, &o);
    let params = OperatorParams::new(p);
    let dense = DenseM2l::<T>::precompute(kernel, &params, &DenseConfig, 1.0, DEPTH).unwrap();
    let svd = SvdM2l::<T>::precompute(kernel, &params, &SvdConfig::default(), 1.0, DEPTH).unwrap();
    let e_dense = (2..=DEPTH)
        .map(|l| m2l_error(kernel, &o, &dense, l))
        .fold(0.0, f64::max);
    let e_svd = (2..=DEPTH)
        .map(|l| m2l_error(kernel, &o, &svd, l))
        .fold(0.0, f64::max);
    println!(
        "{} {} p={p}: P2M {e_p2m:.2e}  M2M {e_m2m:.2e} (vs parent P2M {e_m2m_vs_p2m:.2e})  \
         M2L dense {e_dense:.2e}  M2L svd(k={}) {e_svd:.2e}  L2L {e_l2l:.2e}",
        kernel.name(),
        T::PRECISION.name(),
        svd.rank()
    );
    for (name, e) in [
        ("P2M", e_p2m),
        ("M2M", e_m2m),
        ("M2M vs P2M", e_m2m_vs_p2m),
        ("L2L", e_l2l),
        ("M2L dense", e_dense),
        ("M2L svd", e_svd),
    ] {
        assert!(e < tol, "{name}: error {e:.3e} >= {tol:.1e}");
    }
}

#[test]
fn laplace_f64_p4() {
    all_operators::<f64, _>(&Laplace3d, 4, 1e-3);
}

#[test]
fn laplace_f64_p6() {
    all_operators::<f64, _>(&Laplace3d, 6, 2e-5);
}

#[test]
fn laplace_f32_p5() {
    all_operators::<f32, _>(&Laplace3d, 5, 1e-3);
}

#[test]
fn yukawa_f64_p6_per_level_operators() {
    let k = ModifiedHelmholtz3d::new(5.0).unwrap();
    assert!(k.homogeneity().is_none());
    all_operators::<f64, _>(&k, 6, 5e-5);
}

#[test]
fn yukawa_f32_p4() {
    all_operators::<f32, _>(&ModifiedHelmholtz3d::new(5.0).unwrap(), 4, 5e-3);
}
