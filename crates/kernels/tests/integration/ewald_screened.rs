//! The screened (Yukawa) Ewald sum and periodic Green's function,
//! `K(r) = e^{-kappa r} / (4 pi r)`, against brute-force image sums (which
//! converge for screening strong enough), against themselves (`alpha`
//! independence, tolerances), and against Laplace as `kappa -> 0`.

use ferrofmm_kernels::{
    EvalMode, EwaldOptions, EwaldSum, INV_4PI, KernelError, PeriodicCell, PeriodicGreen,
};
use ferrofmm_testing::{charges, points};

/// 60 points in an orthorhombic cell, positive (not neutral) charges.
fn small_set() -> (PeriodicCell, Vec<f64>, Vec<f64>) {
    let cell = PeriodicCell::new([-0.5, 0.0, 0.25], [1.0, 0.9, 1.1]).unwrap();
    let n = 60;
    let pos: Vec<f64> = points::uniform_cube(n, 0.0, 1.0, 11)
        .chunks_exact(3)
        .flat_map(|p| [p[0] - 0.5, 0.9 * p[1], 0.25 + 1.1 * p[2]])
        .collect();
    (cell, pos, charges::uniform_in(n, 0.0, 1.0, 12))
}

/// `[phi, grad]` at source `i` from every image of every source but
/// itself, `|n|_inf <= m`.
fn brute_force(
    cell: &PeriodicCell,
    pos: &[f64],
    q: &[f64],
    kappa: f64,
    i: usize,
    m: i64,
) -> [f64; 4] {
    let l = cell.lengths();
    let y = &pos[3 * i..3 * i + 3];
    // Neumaier's compensated sums: ~4e5 positive terms.
    let mut acc = [0.0f64; 4];
    let mut carry = [0.0f64; 4];
    let mut add = |a: usize, v: f64| {
        let t = acc[a] + v;
        carry[a] += if acc[a].abs() >= v.abs() {
            (acc[a] - t) + v
        } else {
            (v - t) + acc[a]
        };
        acc[a] = t;
    };
    for (j, (x, &qj)) in pos.chunks_exact(3).zip(q).enumerate() {
        for nx in -m..=m {
            for ny in -m..=m {
                for nz in -m..=m {
                    if j == i && nx == 0 && ny == 0 && nz == 0 {
                        continue;
                    }
                    let d = [
                        y[0] - x[0] - nx as f64 * l[0],
                        y[1] - x[1] - ny as f64 * l[1],
                        y[2] - x[2] - nz as f64 * l[2],
                    ];
                    let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    let k = INV_4PI * qj * (-kappa * r).exp() / r;
                    add(0, k);
                    let g = -k * (1.0 + kappa * r) / (r * r);
                    for (a, da) in d.iter().enumerate() {
                        add(1 + a, g * da);
                    }
                }
            }
        }
    }
    [0, 1, 2, 3].map(|a| acc[a] + carry[a])
}

/// `max |a - b|` over potentials and over gradients, relative to the
/// largest of each in `b`.
fn rel_errors(a: &[f64], b: &[f64]) -> (f64, f64) {
    let scale = |cols: std::ops::Range<usize>| {
        b.chunks_exact(4)
            .flat_map(|c| c[cols.clone()].to_vec())
            .fold(0.0f64, |m, v| m.max(v.abs()))
    };
    let (sp, sg) = (scale(0..1), scale(1..4));
    let mut e = (0.0f64, 0.0f64);
    for (x, y) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        e.0 = e.0.max((x[0] - y[0]).abs() / sp);
        for c in 1..4 {
            e.1 = e.1.max((x[c] - y[c]).abs() / sg);
        }
    }
    e
}

/// With `kappa L = 6` the images beyond 10 cells add below `1e-20`: the
/// Ewald sum must match the plain image sum to rounding, self images
/// included, for a charged (non-neutral) cell.
#[test]
fn screened_sum_matches_image_sums() {
    let (cell, pos, q) = small_set();
    let kappa = 6.0;
    let ewald =
        EwaldSum::with_options(cell, &pos, &q, EwaldOptions::new(1e-15).screening(kappa)).unwrap();
    assert_eq!(ewald.screening(), kappa);
    let idx = [0usize, 17, 59];
    let got = ewald.at_sources(&idx, EvalMode::PotentialGradient).unwrap();
    let want: Vec<f64> = idx
        .iter()
        .flat_map(|&i| brute_force(&cell, &pos, &q, kappa, i, 10))
        .collect();
    let (ep, eg) = rel_errors(&got, &want);
    assert!(ep < 1e-13 && eg < 1e-13, "{ep:.1e} {eg:.1e}");
}

/// The result does not depend on the splitting parameter, and every
/// tolerance is met, at weak screening (where the `k = 0` term is large)
/// and at strong screening (`b = kappa / (2 alpha)` well above 1).
#[test]
fn screened_sum_is_independent_of_alpha_and_meets_tolerances() {
    let (cell, pos, q) = small_set();
    for kappa in [0.3, 80.0] {
        let opts = EwaldOptions::new(1e-15).screening(kappa);
        let base = EwaldSum::with_options(cell, &pos, &q, opts).unwrap();
        let alpha = base.parameters().alpha;
        let want = base.all(EvalMode::PotentialGradient).unwrap();
        for factor in [0.7, 1.6] {
            let other = EwaldSum::with_options(cell, &pos, &q, opts.with_alpha(alpha * factor))
                .unwrap()
                .all(EvalMode::PotentialGradient)
                .unwrap();
            let (ep, eg) = rel_errors(&other, &want);
            assert!(
                ep < 1e-13 && eg < 1e-13,
                "kappa {kappa} alpha x{factor}: {ep:.1e} {eg:.1e}"
            );
        }
        for tol in [1e-4, 1e-8, 1e-12] {
            let got =
                EwaldSum::with_options(cell, &pos, &q, EwaldOptions::new(tol).screening(kappa))
                    .unwrap()
                    .all(EvalMode::PotentialGradient)
                    .unwrap();
            let (ep, eg) = rel_errors(&got, &want);
            assert!(
                ep < tol && eg < tol,
                "kappa {kappa} tol {tol:.0e}: {ep:.1e} {eg:.1e}"
            );
        }
    }
}

/// Screening far stronger than the cell (`kappa L ~ 2000`): the sum is
/// the nearest images' direct sum, with Laplace's splitting parameter and
/// wave vectors (no growth with `kappa`), and finite everywhere.
#[test]
fn very_strong_screening_is_the_nearest_images() {
    let (cell, pos, q) = small_set();
    let kappa = 2000.0;
    let opts = EwaldOptions::new(1e-15).screening(kappa);
    let sum = EwaldSum::with_options(cell, &pos, &q, opts).unwrap();
    let laplace = EwaldSum::new(cell, &pos, &q, 1e-15).unwrap();
    assert_eq!(sum.parameters().alpha, laplace.parameters().alpha);
    assert_eq!(sum.n_wave_vectors(), laplace.n_wave_vectors());
    let idx: Vec<usize> = (0..60).collect();
    let got = sum.at_sources(&idx, EvalMode::PotentialGradient).unwrap();
    assert!(got.iter().all(|v| v.is_finite()));
    let want: Vec<f64> = idx
        .iter()
        .flat_map(|&i| brute_force(&cell, &pos, &q, kappa, i, 1))
        .collect();
    // `e^{-kappa r}` at `kappa r ~ 500` carries the rounding of `r` times
    // `kappa r`: agreement to ~`5e-14`, relative.
    for (g, w) in got.chunks_exact(4).zip(want.chunks_exact(4)) {
        for c in 0..4 {
            assert!(
                (g[c] - w[c]).abs() <= 1e-12 * w[c].abs() + 1e-300,
                "{g:?} {w:?}"
            );
        }
    }
    let green = PeriodicGreen::screened(cell, kappa, 1e-15).unwrap();
    let far = green.far_images([0.3, -0.2, 0.1]);
    assert!(far.is_finite() && far.abs() < 1e-200, "{far}");
}

/// A neutral cell's screened sum tends to the tin-foil Laplace sum as
/// `kappa -> 0`: `G_kappa = 1 / (V kappa^2) + G_0 + O(kappa^2)`, whose
/// constant a neutral cell cancels, and the self term's regular part
/// `lim (G_kappa - e^{-kappa r} / (4 pi r))` carries `+kappa / (4 pi)` more
/// than Laplace's, so `phi_i(kappa) = phi_i(0) + q_i kappa / (4 pi) +
/// O(kappa^2)`.
#[test]
fn weak_screening_tends_to_laplace() {
    let (cell, pos, mut q) = small_set();
    let mean = q.iter().sum::<f64>() / q.len() as f64;
    q.iter_mut().for_each(|v| *v -= mean);
    let laplace = EwaldSum::new(cell, &pos, &q, 1e-15)
        .unwrap()
        .all(EvalMode::PotentialGradient)
        .unwrap();
    let mut last = f64::INFINITY;
    for kappa in [1e-2, 1e-3] {
        let opts = EwaldOptions::new(1e-15).screening(kappa);
        let mut got = EwaldSum::with_options(cell, &pos, &q, opts)
            .unwrap()
            .all(EvalMode::PotentialGradient)
            .unwrap();
        for (o, qi) in got.chunks_exact_mut(4).zip(&q) {
            o[0] -= qi * kappa * INV_4PI;
        }
        let (ep, eg) = rel_errors(&got, &laplace);
        let e = ep.max(eg);
        assert!(e < 10.0 * kappa * kappa, "kappa {kappa}: {ep:.1e} {eg:.1e}");
        assert!(e < last / 50.0, "kappa {kappa}: {e:.1e} after {last:.1e}");
        last = e;
    }
}

/// The screened Green's function is the Ewald sum of one charge, its far
/// part plus the 27 nearest images, and its self constant is what a lone
/// charge's Ewald sum gives at the charge.
#[test]
fn screened_green_agrees_with_the_sum() {
    for (cell, kappa) in [
        (PeriodicCell::cubic([0.0; 3], 1.0).unwrap(), 2.5),
        (PeriodicCell::new([0.0; 3], [1.0, 0.7, 1.6]).unwrap(), 0.4),
    ] {
        let g = PeriodicGreen::screened(cell, kappa, 1e-15).unwrap();
        assert_eq!(g.screening(), kappa);
        let lone = EwaldSum::with_options(
            cell,
            &[0.0; 3],
            &[1.0],
            EwaldOptions::new(1e-15).screening(kappa),
        )
        .unwrap();
        let at_self = lone.at_sources(&[0], EvalMode::Potential).unwrap()[0];
        assert!(
            (g.self_potential() - at_self).abs() < 1e-13 * at_self.abs(),
            "{} {at_self}",
            g.self_potential()
        );
        let l = cell.lengths();
        for r in [[0.3, -0.2, 0.1], [0.45, 0.3, -0.6], [1e-7, 0.0, 0.0]] {
            let ewald = lone.at_points(&r, EvalMode::Potential).unwrap()[0];
            let pot = g.potential(r);
            assert!((pot - ewald).abs() < 1e-13 * ewald.abs(), "{pot} {ewald}");
            let mut near = 0.0;
            for n in 0..27 {
                let n = [n % 3 - 1, (n / 3) % 3 - 1, n / 9 - 1];
                let d: Vec<f64> = (0..3).map(|a| r[a] - n[a] as f64 * l[a]).collect();
                let rho = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                near += INV_4PI * (-kappa * rho).exp() / rho;
            }
            let far = g.far_images(r);
            assert!(
                (far + near - pot).abs() < 1e-13 * pot.abs().max(near),
                "{far} + {near} vs {pot}"
            );
        }
        // Smooth through the points where an image of the source sits
        // (`F` near a lattice vector, where its series takes over).
        let at = |t: f64| g.far_images([l[0] + t, 0.0, 0.0]);
        let (a, b, c) = (at(-1e-4), at(0.0), at(1e-4));
        assert!(
            (a - 2.0 * b + c).abs() < 1e-6 * b.abs().max(1.0),
            "{a} {b} {c}"
        );
    }
}

#[test]
fn bad_screening_is_an_error() {
    let cell = PeriodicCell::cubic([0.0; 3], 1.0).unwrap();
    for kappa in [-1.0, f64::NAN, f64::INFINITY] {
        let opts = EwaldOptions::new(1e-6).screening(kappa);
        assert!(matches!(
            EwaldSum::with_options(cell, &[0.1, 0.2, 0.3], &[1.0], opts),
            Err(KernelError::InvalidParameter { .. })
        ));
        assert!(PeriodicGreen::screened(cell, kappa, 1e-6).is_err());
    }
}
