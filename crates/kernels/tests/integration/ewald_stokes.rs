//! Hasimoto's Ewald sum of the Stokeslet and the periodic Stokeslet:
//! Hasimoto's simple cubic constant, `alpha` independence, tolerances,
//! gradients against differences, the divergence, the Green's function
//! against the sum, and the free-space limit of a tight cluster.

use ferrofmm_kernels::{
    EvalMode, EwaldOptions, Kernel, KernelError, PeriodicCell, PeriodicStokeslet, Stokes3d,
    StokesEwaldSum,
};
use ferrofmm_testing::{charges, errors::relative_l2, points};
use std::f64::consts::PI;

/// Hasimoto's constant of the simple cubic lattice (the self-mobility
/// correction `-zeta F / (6 pi mu L)`).
const HASIMOTO_SC: f64 = 2.837_297_479_480_6;

/// 50 points in an orthorhombic cell with random forces (net force not
/// zero).
fn small_set() -> (PeriodicCell, Vec<f64>, Vec<f64>) {
    let cell = PeriodicCell::new([-0.5, 0.0, 0.25], [1.0, 0.9, 1.2]).unwrap();
    let n = 50;
    let pos: Vec<f64> = points::uniform_cube(n, 0.0, 1.0, 21)
        .chunks_exact(3)
        .flat_map(|p| [p[0] - 0.5, 0.9 * p[1], 0.25 + 1.2 * p[2]])
        .collect();
    (cell, pos, charges::uniform_in(3 * n, -1.0, 1.0, 22))
}

#[test]
fn simple_cubic_self_term_is_hasimotos() {
    for (l, mu) in [(1.0, 1.0), (2.5, 0.3)] {
        let cell = PeriodicCell::cubic([0.0; 3], l).unwrap();
        let f = [0.3, -1.0, 0.7];
        let ewald = StokesEwaldSum::new(cell, &[0.1, 0.2, 0.3], &f, mu, 1e-14).unwrap();
        let u = ewald.at_sources(&[0], EvalMode::PotentialGradient).unwrap();
        let scale = -HASIMOTO_SC / (6.0 * PI * mu * l);
        for a in 0..3 {
            assert!(
                (u[a] - scale * f[a]).abs() < 1e-12 * scale.abs(),
                "{a}: {} {}",
                u[a],
                scale * f[a]
            );
        }
        // The lattice is symmetric: no gradient at the source.
        assert!(
            u[3..].iter().all(|g| g.abs() < 1e-11 / (mu * l * l)),
            "{u:?}"
        );
    }
}

#[test]
fn independent_of_alpha_at_sources_and_points() {
    let (cell, pos, f) = small_set();
    let targets = points::uniform_cube(20, -2.0, 4.0, 23);
    let mut results = Vec::new();
    for alpha in [4.0, 7.0, 11.0] {
        let opts = EwaldOptions::new(1e-15).with_alpha(alpha);
        let ewald = StokesEwaldSum::with_options(cell, &pos, &f, 1.7, opts).unwrap();
        let mut v = ewald.all(EvalMode::PotentialGradient).unwrap();
        v.extend(
            ewald
                .at_points(&targets, EvalMode::PotentialGradient)
                .unwrap(),
        );
        results.push(v);
    }
    for other in &results[1..] {
        let e = relative_l2(other, &results[0]);
        assert!(e < 1e-13, "alpha dependence {e:e}");
    }
}

#[test]
fn tolerance_is_met() {
    let (cell, pos, f) = small_set();
    let exact = StokesEwaldSum::new(cell, &pos, &f, 1.0, 1e-15)
        .unwrap()
        .all(EvalMode::PotentialGradient)
        .unwrap();
    for tol in [1e-4, 1e-8, 1e-11] {
        let got = StokesEwaldSum::new(cell, &pos, &f, 1.0, tol)
            .unwrap()
            .all(EvalMode::PotentialGradient)
            .unwrap();
        let split = |v: &[f64], r: std::ops::Range<usize>| -> Vec<f64> {
            v.chunks_exact(12)
                .flat_map(|c| c[r.clone()].to_vec())
                .collect()
        };
        for r in [0..3, 3..12] {
            let e = relative_l2(&split(&got, r.clone()), &split(&exact, r.clone()));
            assert!(e < tol, "tol {tol:e}, columns {r:?}: {e:e}");
        }
    }
}

#[test]
fn gradient_matches_differences_and_is_divergence_free() {
    let (cell, pos, f) = small_set();
    let ewald = StokesEwaldSum::new(cell, &pos, &f, 1.0, 1e-15).unwrap();
    let y = [0.123, 0.456, 0.789];
    let g = ewald.at_points(&y, EvalMode::PotentialGradient).unwrap();
    let h = 1e-5;
    for c in 0..3 {
        let (mut p, mut m) = (y, y);
        p[c] += h;
        m[c] -= h;
        let up = ewald.at_points(&p, EvalMode::Potential).unwrap();
        let um = ewald.at_points(&m, EvalMode::Potential).unwrap();
        for a in 0..3 {
            let fd = (up[a] - um[a]) / (2.0 * h);
            assert!(
                (fd - g[3 + 3 * c + a]).abs() < 1e-7 * (1.0 + fd.abs()),
                "d{c} u{a}: {fd} {}",
                g[3 + 3 * c + a]
            );
        }
    }
    let div = g[3] + g[7] + g[11];
    let size = g[3..].iter().map(|v| v.abs()).fold(0.0, f64::max);
    assert!(div.abs() < 1e-12 * size, "divergence {div:e} of {size:e}");
}

#[test]
fn green_function_is_the_sum_of_one_force_and_its_far_images() {
    let (cell, _, _) = small_set();
    let mu = 0.8;
    let g = PeriodicStokeslet::new(cell, mu, 1e-15).unwrap();
    let stokes = Stokes3d::new(mu).unwrap();
    let l = cell.lengths();
    let source = [0.2, 0.3, 0.4];
    for r in [[0.31, -0.22, 0.13], [1.2, 0.05, -1.6], [0.0, 0.0, 0.01]] {
        let whole = g.velocity(r);
        let far = g.far_images(r);
        for b in 0..3 {
            let mut e = [0.0; 3];
            e[b] = 1.0;
            let t = [source[0] + r[0], source[1] + r[1], source[2] + r[2]];
            let sum = StokesEwaldSum::new(cell, &source, &e, mu, 1e-15).unwrap();
            let u = sum.at_points(&t, EvalMode::Potential).unwrap();
            let mut near = [0.0; 3];
            for n in 0..27i64 {
                let s = [n % 3 - 1, (n / 3) % 3 - 1, n / 9 - 1];
                let x: Vec<f64> = (0..3).map(|d| source[d] + s[d] as f64 * l[d]).collect();
                stokes.evaluate(EvalMode::Potential, &x, &e, &t, &mut near);
            }
            // Rounding relative to the largest term, the direct one.
            let rn = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
            let scale = (1.0 + 1.0 / rn) / (8.0 * PI * mu);
            for a in 0..3 {
                assert!((whole[a][b] - u[a]).abs() < 1e-13 * scale, "{r:?} {a}{b}");
                assert!(
                    (far[a][b] + near[a] - u[a]).abs() < 1e-13 * scale,
                    "{r:?} {a}{b}"
                );
            }
        }
    }
    // The matrix form, in the assemble layout.
    let t = [0.1, 0.2, 0.3, -0.4, 0.5, 0.6];
    let s = [0.0, 0.0, 0.0, 0.3, -0.2, 0.1, 0.5, 0.5, 0.5];
    let m = g.far_images_matrix(&t, &s).unwrap();
    let f = g.far_images([-0.4 - 0.3, 0.5 + 0.2, 0.6 - 0.1]);
    for a in 0..3 {
        for b in 0..3 {
            assert_eq!(m[(3 + a) * 9 + 3 + b], f[a][b]);
        }
    }
}

/// A tight cluster in a large cell: the periodic velocity is the free one
/// plus the images, which act as the net force `F` at the cluster:
/// Hasimoto's `-zeta F / (6 pi mu L)`, to `O(a / L)` of that.
#[test]
fn a_tight_cluster_sees_its_images_as_one_force() {
    let l = 10.0;
    let a = 0.01;
    let cell = PeriodicCell::cubic([0.0; 3], l).unwrap();
    let n = 30;
    let pos: Vec<f64> = points::uniform_cube(n, 5.0, a, 31);
    let f = charges::uniform_in(3 * n, 0.0, 1.0, 32);
    let total = [0, 1, 2].map(|c| f.iter().skip(c).step_by(3).sum::<f64>());
    let ewald = StokesEwaldSum::new(cell, &pos, &f, 1.0, 1e-14).unwrap();
    let per = ewald.all(EvalMode::Potential).unwrap();
    let mut free = vec![0.0; 3 * n];
    Stokes3d::new(1.0)
        .unwrap()
        .evaluate(EvalMode::Potential, &pos, &f, &pos, &mut free);
    let images = -HASIMOTO_SC / (6.0 * PI * l);
    for i in 0..n {
        for c in 0..3 {
            let want = free[3 * i + c] + images * total[c];
            let bound = 10.0 * a / l * (images * total[c]).abs();
            assert!((per[3 * i + c] - want).abs() < bound, "{i} {c}");
        }
    }
}

#[test]
fn bad_input_is_refused() {
    let cell = PeriodicCell::cubic([0.0; 3], 1.0).unwrap();
    let p = [0.1, 0.2, 0.3];
    assert!(matches!(
        StokesEwaldSum::new(cell, &p, &[1.0], 1.0, 1e-10),
        Err(KernelError::ChargesLength { .. })
    ));
    assert!(StokesEwaldSum::new(cell, &p, &[1.0, 0.0, f64::NAN], 1.0, 1e-10).is_err());
    assert!(StokesEwaldSum::new(cell, &p, &[1.0; 3], 0.0, 1e-10).is_err());
    assert!(StokesEwaldSum::new(cell, &p, &[1.0; 3], 1.0, 0.0).is_err());
    let opts = EwaldOptions::new(1e-10).screening(1.0);
    assert!(StokesEwaldSum::with_options(cell, &p, &[1.0; 3], 1.0, opts).is_err());
    let ewald = StokesEwaldSum::new(cell, &p, &[1.0; 3], 1.0, 1e-10).unwrap();
    assert!(ewald.at_sources(&[1], EvalMode::Potential).is_err());
    assert!(
        ewald
            .at_points(&p, EvalMode::PotentialGradientHessian)
            .is_err()
    );
    assert!(PeriodicStokeslet::new(cell, -1.0, 1e-10).is_err());
}
