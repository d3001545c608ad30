//! Measurements behind the defaults (radii, cutoffs, SVD tolerance). Run
//! with `cargo test -p ferrofmm-field --release --test integration measurements:: --
//! --ignored --nocapture --test-threads 1`; the tables are in
//! docs/algorithms.md and docs/stability.md.

use crate::common;

use common::*;
use ferrofmm_field::{
    DenseConfig, DenseM2l, M2lInteractions, M2lScheme, OperatorParams, Operators, SurfaceRadii,
    SvdConfig, SvdM2l,
};
use ferrofmm_kernels::{Kernel, Laplace3d, Real};
use ferrofmm_testing::points::in_shell;

#[test]
#[ignore]
fn radii_sweep() {
    let pairs = [
        (1.01, 2.95),
        (1.02, 2.95),
        (1.03, 2.95),
        (1.05, 2.95),
        (1.02, 2.98),
        (1.05, 2.9),
        (1.05, 2.5),
        (1.05, 2.0),
        (1.1, 2.9),
        (1.2, 2.8),
        (1.3, 2.7),
        (1.5, 2.5),
    ];
    println!("| r_ue = r_dc | r_uc = r_de | p=4 | p=6 | p=8 | p=10 |");
    println!("|---|---|---|---|---|---|");
    for (ue, uc) in pairs {
        let mut row = format!("| {ue} | {uc} |");
        for p in [4, 6, 8, 10] {
            let mut params = OperatorParams::new(p);
            params.radii = SurfaceRadii {
                upward_equivalent: ue,
                upward_check: uc,
                downward_equivalent: uc,
                downward_check: ue,
            };
            let ops = Operators::<f64>::new(&Laplace3d, &params, 1.0, 3).unwrap();
            let e = (0..4)
                .map(|s| full_chain_error(&Laplace3d, &ops, 2, 150, 10 + s))
                .fold(0.0, f64::max);
            row += &format!(" {e:.2e} |");
        }
        println!("{row}");
    }
}

fn cutoff_row<T: Real>(p: usize, rcond: Option<f64>) -> (f64, f64) {
    let mut params = OperatorParams::new(p);
    params.pinv_rcond = rcond;
    let ops = Operators::<T>::new(&Laplace3d, &params, 1.0, 0).unwrap();
    let e = (0..2)
        .map(|s| chain_error(&Laplace3d, &ops, 0, 150, 20 + s))
        .fold(0.0, f64::max);
    (e, ops.diagnostics().rounding_amplification)
}

#[test]
#[ignore]
fn cutoff_sweep() {
    let cutoffs = [
        Some(1e-4),
        Some(1e-5),
        Some(1e-6),
        Some(1e-7),
        Some(1e-8),
        Some(1e-10),
        Some(1e-12),
        Some(1e-14),
        Some(1e-15),
        Some(1e-16),
        Some(0.0),
    ];
    for (name, f32_) in [("f64", false), ("f32", true)] {
        println!("\n{name}: P2M->M2L->DC2E->L2P error (worst of 12 box pairs) by cutoff");
        print!("| p |");
        for c in cutoffs {
            print!(" {:.0e} |", c.unwrap());
        }
        println!("\n|---|{}", "---|".repeat(cutoffs.len()));
        let orders: &[usize] = if f32_ {
            &[3, 4, 5, 6, 7, 8, 10, 12]
        } else {
            &[6, 8, 10, 12, 14, 16]
        };
        for &p in orders {
            print!("| {p} |");
            for c in cutoffs {
                let (e, _) = if f32_ {
                    cutoff_row::<f32>(p, c)
                } else {
                    cutoff_row::<f64>(p, c)
                };
                print!(" {e:.1e} |");
            }
            println!();
        }
    }
}

#[test]
#[ignore]
fn cutoff_sweep_f64_fine() {
    let cutoffs = [1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15];
    println!("f64: full chain P2M->M2M->M2L->L2L->L2P, worst of 4 seeds x 6 box pairs, by cutoff");
    print!("| p |");
    for c in cutoffs {
        print!(" {c:.0e} |");
    }
    println!("\n|---|{}", "---|".repeat(cutoffs.len()));
    for p in [6, 8, 9, 10, 11, 12, 14, 16] {
        print!("| {p} |");
        for c in cutoffs {
            let mut params = OperatorParams::new(p);
            params.pinv_rcond = Some(c);
            let ops = Operators::<f64>::new(&Laplace3d, &params, 1.0, 3).unwrap();
            let e = (0..4)
                .map(|s| full_chain_error(&Laplace3d, &ops, 2, 150, 40 + s))
                .fold(0.0, f64::max);
            print!(" {e:.1e} |");
        }
        println!();
    }
}

#[test]
#[ignore]
fn stability_table() {
    println!("| p | type | cutoff | error | rank UC2E/n | eps*cond | warning |");
    println!("|---|---|---|---|---|---|---|");
    for p in [8, 10, 12, 14, 16] {
        for f32_ in [false, true] {
            for rcond in [None, Some(0.0)] {
                let mut params = OperatorParams::new(p);
                params.pinv_rcond = rcond;
                let (e, d, name) = if f32_ {
                    let ops = Operators::<f32>::new(&Laplace3d, &params, 1.0, 0).unwrap();
                    let e = (0..2)
                        .map(|s| chain_error(&Laplace3d, &ops, 0, 150, 20 + s))
                        .fold(0.0, f64::max);
                    (e, ops.diagnostics(), "f32")
                } else {
                    let ops = Operators::<f64>::new(&Laplace3d, &params, 1.0, 0).unwrap();
                    let e = (0..2)
                        .map(|s| chain_error(&Laplace3d, &ops, 0, 150, 20 + s))
                        .fold(0.0, f64::max);
                    (e, ops.diagnostics(), "f64")
                };
                println!(
                    "| {p} | {name} | {} | {e:.1e} | {}/{} | {:.1e} | {} |",
                    rcond.map(|c| format!("{c:e}")).unwrap_or("default".into()),
                    d.uc2e[0].rank,
                    d.uc2e[0].n,
                    d.rounding_amplification,
                    if d.warnings.is_empty() { "no" } else { "yes" }
                );
            }
        }
    }
}

/// P2M -> scheme M2L -> DC2E -> L2P for the chain vectors; worst error.
fn scheme_chain_error<T: Real, K: Kernel, S: M2lScheme<T>>(
    kernel: &K,
    ops: &Operators<T>,
    scheme: &S,
    level: u32,
    count: usize,
    seed: u64,
) -> f64 {
    let n = ops.n_surface();
    chain_error_with(
        kernel,
        ops,
        level,
        count,
        seed,
        &CHAIN_VECTORS,
        |v, _, _, phi| m2l_pair(scheme, level, n, v, phi),
    )
}

/// Multipoles of a uniform level-3 grid (8^3 boxes, 30 sources each).
fn grid_multipoles<T: Real, K: Kernel>(kernel: &K, ops: &Operators<T>) -> Vec<T> {
    let mut rng = SplitMix64(7);
    let side = 8;
    let h = ops.half_width(3);
    let mut all = Vec::new();
    for x in 0..side {
        for y in 0..side {
            for z in 0..side {
                let c = box_center(3, [x, y, z]);
                let src = in_box(&mut rng, 30, c, h);
                let q = positive_from(&mut rng, 30);
                all.extend(p2m(kernel, ops, 3, c, &src, &q));
            }
        }
    }
    all
}

/// Tolerances of the sweep (0 = the default); `FERROFMM_SVD_DEFAULT_ONLY`
/// restricts it to the default.
fn tolerances() -> Vec<f64> {
    if std::env::var_os("FERROFMM_SVD_DEFAULT_ONLY").is_some() {
        vec![0.0]
    } else {
        vec![
            0.0, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-12,
        ]
    }
}

#[test]
#[ignore]
fn svd_tolerance_sweep() {
    println!(
        "| p | tolerance | rank k / n | check error vs dense | chain error dense | chain error svd |"
    );
    println!("|---|---|---|---|---|---|");
    for p in [4, 5, 6, 7, 8, 10] {
        let params = OperatorParams::new(p);
        let ops = Operators::<f64>::new(&Laplace3d, &params, 1.0, 3).unwrap();
        let n = ops.n_surface();
        let multipoles = grid_multipoles(&Laplace3d, &ops);
        let pairs = uniform_v_lists(8);
        let inter = M2lInteractions::new(512, 512, &pairs);
        let dense = DenseM2l::<f64>::precompute(&Laplace3d, &params, &DenseConfig, 1.0, 3).unwrap();
        let mut want = vec![0.0; n * 512];
        dense.apply(3, &inter, &multipoles, &mut want);
        let chain = (0..3)
            .map(|s| scheme_chain_error(&Laplace3d, &ops, &dense, 3, 100, 50 + s))
            .fold(0.0, f64::max);
        for tol in tolerances() {
            let cfg = SvdConfig {
                rank: None,
                tolerance: tol,
            };
            let svd = SvdM2l::<f64>::precompute(&Laplace3d, &params, &cfg, 1.0, 3).unwrap();
            let mut got = vec![0.0; n * 512];
            svd.apply(3, &inter, &multipoles, &mut got);
            let svd_chain = (0..3)
                .map(|s| scheme_chain_error(&Laplace3d, &ops, &svd, 3, 100, 50 + s))
                .fold(0.0, f64::max);
            println!(
                "| {p} | {} | {}/{n} | {:.2e} | {chain:.2e} | {svd_chain:.2e} |",
                if tol == 0.0 {
                    format!("default {:.1e}", svd.tolerance())
                } else {
                    format!("{tol:.0e}")
                },
                svd.rank(),
                relative_l2(&got, &want)
            );
        }
    }
}

/// P2L -> DC2E -> L2P with sources just outside the near field (the X-list
/// and closest V-list particles sit at 3 half-widths), and P2M -> M2P with
/// targets just at 3 half-widths, for candidate radii.
#[test]
#[ignore]
fn near_boundary_sweep() {
    println!(
        "| r_ue = r_dc | r_uc = r_de | p | P2L->L2P, sources at 3h..3.1h | P2M->M2P, targets at 3h..3.1h |"
    );
    println!("|---|---|---|---|---|");
    for (ue, uc) in [(1.02, 2.98), (1.05, 2.95), (1.1, 2.9)] {
        for p in [4, 6, 8, 10] {
            let mut params = OperatorParams::new(p);
            params.radii = SurfaceRadii {
                upward_equivalent: ue,
                upward_check: uc,
                downward_equivalent: uc,
                downward_check: ue,
            };
            let ops = Operators::<f64>::new(&Laplace3d, &params, 1.0, 0).unwrap();
            let level = 2;
            let h = ops.half_width(level);
            let c = box_center(level, [1, 1, 1]);
            let mut rng = SplitMix64(99);
            let (mut e_l, mut e_m) = (0.0f64, 0.0f64);
            for _ in 0..4 {
                let far = in_shell(&mut rng, 300, c, 3.0 * h, 3.1 * h);
                let q = positive_from(&mut rng, 300);
                let inner = in_box(&mut rng, 300, c, h);
                let check = check_potential(
                    &Laplace3d,
                    &ops,
                    ferrofmm_field::SurfaceKind::DownwardCheck,
                    level,
                    c,
                    &far,
                    &q,
                );
                let mut psi = vec![0.0; ops.n_surface()];
                ops.dc2e(level, &check, &mut psi);
                let approx = eval_density(
                    &Laplace3d,
                    &ops,
                    ferrofmm_field::SurfaceKind::DownwardEquivalent,
                    level,
                    c,
                    &psi,
                    &inner,
                );
                e_l = e_l.max(relative_l2(&approx, &direct(&Laplace3d, &far, &q, &inner)));
                let qi = positive_from(&mut rng, 300);
                let phi = p2m(&Laplace3d, &ops, level, c, &inner, &qi);
                let approx = eval_density(
                    &Laplace3d,
                    &ops,
                    ferrofmm_field::SurfaceKind::UpwardEquivalent,
                    level,
                    c,
                    &phi,
                    &far,
                );
                e_m = e_m.max(relative_l2(&approx, &direct(&Laplace3d, &inner, &qi, &far)));
            }
            println!("| {ue} | {uc} | {p} | {e_l:.2e} | {e_m:.2e} |");
        }
    }
}
