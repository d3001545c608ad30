//! The Green's functions of slabs and rods ([`SlabGreen`], [`RodGreen`]):
//! known Madelung constants, direct image sums of a strongly screened
//! kernel, independence of the splitting parameter, gradients against
//! differences, the far images, and the pairwise sums.

use ferrofmm_kernels::{EvalMode, INV_4PI, KernelError, PeriodicCell, RodGreen, SlabGreen};
use ferrofmm_testing::{charges, points};

/// The Madelung constant of the square lattice of alternating charges
/// (the "two-dimensional rock salt").
const SQUARE_MADELUNG: f64 = 1.615_542_626_712_824_7;

fn cell(l: [f64; 3]) -> PeriodicCell {
    PeriodicCell::new([0.0; 3], l).unwrap()
}

fn neutral(n: usize, seed: u64) -> Vec<f64> {
    let mut q = charges::uniform_in(n, -1.0, 1.0, seed);
    let mean = q.iter().sum::<f64>() / n as f64;
    q.iter_mut().for_each(|q| *q -= mean);
    q
}

#[test]
fn square_lattice_madelung_constant() {
    // Unit cell of side 1 holding the checkerboard of spacing a = 1/2, in
    // the plane z = 0.4 (any height).
    let g = SlabGreen::new(cell([1.0; 3]), 1e-15).unwrap();
    let pos = [0.0, 0.0, 0.4, 0.5, 0.0, 0.4, 0.0, 0.5, 0.4, 0.5, 0.5, 0.4];
    let q = [1.0, -1.0, -1.0, 1.0];
    let phi = g
        .sum_at_sources(&pos, &q, &[0, 1], EvalMode::PotentialGradient)
        .unwrap();
    for (i, sign) in [(0, 1.0), (1, -1.0)] {
        let m = -sign * phi[4 * i] / INV_4PI * 0.5;
        assert!((m - SQUARE_MADELUNG).abs() < 1e-13, "{m}");
        // A symmetric site: no field.
        assert!(phi[4 * i + 1..4 * i + 4].iter().all(|g| g.abs() < 1e-13));
    }
}

#[test]
fn alternating_chain_madelung_constant() {
    let g = RodGreen::new(cell([0.8, 1.0, 1.0]), 1e-15).unwrap();
    let pos = [0.1, 0.3, -0.2, 0.5, 0.3, -0.2];
    let phi = g
        .sum_at_sources(&pos, &[1.0, -1.0], &[0], EvalMode::Potential)
        .unwrap();
    let m = -phi[0] / INV_4PI * 0.4;
    assert!((m - 2.0 * 2f64.ln()).abs() < 1e-13, "{m}");
}

/// `sum_n e^{-kappa |r + n|} / (4 pi |r + n|)` over images `n` with
/// components `n_a L_a` along the periodic axes `axes`, `|n_a| <= m`.
fn screened_images(r: [f64; 3], l: [f64; 3], axes: usize, kappa: f64, m: i64) -> [f64; 4] {
    let mut out = [0.0; 4];
    let range = |a: usize| if a < axes { -m..=m } else { 0..=0 };
    for nx in range(0) {
        for ny in range(1) {
            let d = [r[0] + nx as f64 * l[0], r[1] + ny as f64 * l[1], r[2]];
            let rho = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let k = INV_4PI * (-kappa * rho).exp() / rho;
            out[0] += k;
            let dk = -k * (kappa + 1.0 / rho) / rho;
            for a in 0..3 {
                out[1 + a] += dk * d[a];
            }
        }
    }
    out
}

#[test]
fn screened_sums_match_direct_image_sums() {
    let l = [1.0, 1.3, 1.0];
    for kappa in [3.0f64, 9.0] {
        // e^{-kappa m L} / (m L) < 1e-17 beyond m.
        let m = (45.0 / kappa).ceil() as i64;
        let slab = SlabGreen::screened(cell(l), kappa, 1e-15).unwrap();
        let rod = RodGreen::screened(cell(l), kappa, 1e-15).unwrap();
        for r in [[0.3, -0.2, 0.4], [-0.45, 0.6, -1.1], [0.05, 0.0, 0.01]] {
            for (got, want) in [
                (slab.potential(r), screened_images(r, l, 2, kappa, m)),
                (rod.potential(r), screened_images(r, l, 1, kappa, m)),
            ] {
                let scale = want[0].abs().max(1e-3);
                for a in 0..4 {
                    assert!(
                        (got[a] - want[a]).abs() < 1e-13 * scale.max(want[a].abs()),
                        "kappa {kappa} r {r:?} {a}: {} {}",
                        got[a],
                        want[a]
                    );
                }
            }
        }
    }
}

#[test]
fn independent_of_alpha() {
    let l = [1.0f64, 0.8, 1.0];
    let pos = points::uniform_cube(40, 0.0, 0.8, 31);
    let q = neutral(40, 32);
    let targets = points::uniform_cube(10, -1.0, 2.0, 33);
    for kappa in [0.0, 2.0] {
        let mut slabs = Vec::new();
        let mut rods = Vec::new();
        for scale in [0.9, 1.8, 3.5] {
            let alpha = scale / (l[0] * l[1]).sqrt();
            let s = SlabGreen::with_alpha(cell(l), kappa, 1e-15, alpha).unwrap();
            slabs.push(
                s.sum_at_points(&pos, &q, &targets, EvalMode::PotentialGradient)
                    .unwrap(),
            );
            let r = RodGreen::with_alpha(cell(l), kappa, 1e-15, scale / l[0]).unwrap();
            rods.push(
                r.sum_at_sources(&pos, &q, &[0, 7, 39], EvalMode::PotentialGradient)
                    .unwrap(),
            );
        }
        for set in [&slabs, &rods] {
            let size = set[0].iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for other in &set[1..] {
                for (a, b) in set[0].iter().zip(other) {
                    assert!((a - b).abs() < 2e-13 * size, "kappa {kappa}: {a} {b}");
                }
            }
        }
    }
}

#[test]
fn gradients_match_differences() {
    let l = [1.0; 3];
    let h = 1e-5;
    for kappa in [0.0, 1.5] {
        let slab = SlabGreen::screened(cell(l), kappa, 1e-15).unwrap();
        let rod = RodGreen::screened(cell(l), kappa, 1e-15).unwrap();
        let fs: [&dyn Fn([f64; 3]) -> [f64; 4]; 2] =
            [&|r| slab.potential(r), &|r| rod.potential(r)];
        for (which, f) in fs.iter().enumerate() {
            for r in [[0.3, -0.2, 0.4], [0.1, 0.45, -0.7]] {
                let g = f(r);
                for a in 0..3 {
                    let mut p = r;
                    let mut m = r;
                    p[a] += h;
                    m[a] -= h;
                    let d = (f(p)[0] - f(m)[0]) / (2.0 * h);
                    assert!(
                        (d - g[1 + a]).abs() < 1e-8,
                        "kappa {kappa} {which} {a}: {d} {}",
                        g[1 + a]
                    );
                }
            }
        }
    }
}

#[test]
fn far_images_leave_out_the_nearest() {
    let l = [1.0, 1.0, 1.0];
    let kernel = |d: [f64; 3]| INV_4PI / (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let slab = SlabGreen::new(cell(l), 1e-15).unwrap();
    let rod = RodGreen::new(cell(l), 1e-15).unwrap();
    let r = [0.3, -0.2, 0.4];
    let mut near_slab = 0.0;
    for nx in -1..=1 {
        for ny in -1..=1 {
            near_slab += kernel([r[0] + nx as f64, r[1] + ny as f64, r[2]]);
        }
    }
    let near_rod: f64 = (-1..=1)
        .map(|n| kernel([r[0] + n as f64, r[1], r[2]]))
        .sum();
    assert!((slab.potential(r)[0] - slab.far_images(r) - near_slab).abs() < 1e-14);
    assert!((rod.potential(r)[0] - rod.far_images(r) - near_rod).abs() < 1e-14);
    // Periodic along the repeating axes only.
    let shifted = [r[0] + 2.0, r[1] - 1.0, r[2]];
    assert!((slab.potential(r)[0] - slab.potential(shifted)[0]).abs() < 1e-14);
    let m = slab
        .far_images_matrix(&[0.1, 0.2, 0.3, 0.0, 0.0, 0.0], &[0.0; 3])
        .unwrap();
    assert!((m[0] - slab.far_images([0.1, 0.2, 0.3])).abs() < 1e-16);
    assert!((m[1] - slab.far_images([0.0; 3])).abs() < 1e-16);
}

#[test]
fn a_neutral_pair_far_from_its_images_is_a_free_dipole() {
    // A tight pair in a huge cell: its images are 1e4 separations away.
    let l = [1e3; 3];
    let pos = [0.0, 0.0, 0.0, 0.1, 0.0, 0.0];
    let q = [1.0, -1.0];
    let t = [0.02, 0.3, 0.2];
    let free = {
        let d = |s: &[f64]| {
            let r = [t[0] - s[0], t[1] - s[1], t[2] - s[2]];
            INV_4PI / (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt()
        };
        d(&pos[..3]) - d(&pos[3..])
    };
    for v in [
        SlabGreen::new(cell(l), 1e-15)
            .unwrap()
            .sum_at_points(&pos, &q, &t, EvalMode::Potential)
            .unwrap()[0],
        RodGreen::new(cell(l), 1e-15)
            .unwrap()
            .sum_at_points(&pos, &q, &t, EvalMode::Potential)
            .unwrap()[0],
    ] {
        // The images' dipole fields: ~ 0.1 / (4 pi 1e6) per image.
        assert!((v - free).abs() < 1e-7 * free.abs(), "{v} {free}");
    }
}

#[test]
fn bad_input_is_refused() {
    let g = SlabGreen::new(cell([1.0; 3]), 1e-10).unwrap();
    assert!(matches!(
        g.sum_at_points(&[0.0; 3], &[1.0, 2.0], &[0.5; 3], EvalMode::Potential),
        Err(KernelError::ChargesLength { .. })
    ));
    assert!(
        g.sum_at_sources(&[0.0; 3], &[1.0], &[1], EvalMode::Potential)
            .is_err()
    );
    assert!(
        g.sum_at_points(
            &[0.0; 3],
            &[1.0],
            &[0.5; 3],
            EvalMode::PotentialGradientHessian
        )
        .is_err()
    );
    assert!(SlabGreen::new(cell([1.0; 3]), 0.0).is_err());
    assert!(RodGreen::screened(cell([1.0; 3]), -1.0, 1e-10).is_err());
    assert!(RodGreen::with_alpha(cell([1.0; 3]), 0.0, 1e-10, f64::NAN).is_err());
}

/// Many sources go through the Chebyshev grid (the nearest images
/// directly): it agrees with the sum pair by pair, for a box, a flat layer
/// and a cluster, at sources and at points outside the cell.
#[test]
fn many_sources_agree_with_pairs() {
    let n = 2500;
    let l = [1.0, 1.0, 1.0];
    let box_points = points::uniform_cube(n, 0.0, 1.0, 41);
    let flat: Vec<f64> = box_points
        .chunks_exact(3)
        .flat_map(|p| [p[0], p[1], 0.5])
        .collect();
    let cluster: Vec<f64> = box_points
        .chunks_exact(3)
        .flat_map(|p| [0.9 + 0.2 * p[0], 0.3 + 0.1 * p[1], 0.2 * p[2]])
        .collect();
    let q = neutral(n, 42);
    let sample = [0usize, 17, 1234, 2499];
    let targets = [
        0.3, 2.2, 0.7, -0.4, 0.1, 1.6, 0.5, 0.5, 0.5, 0.05, 0.95, -0.3,
    ];
    for kappa in [0.0, 2.0] {
        let slab = SlabGreen::screened(cell(l), kappa, 1e-13).unwrap();
        let rod = RodGreen::screened(cell(l), kappa, 1e-13).unwrap();
        for pos in [&box_points, &flat, &cluster] {
            let pair = |f: &dyn Fn([f64; 3]) -> [f64; 4], t: [f64; 3], skip: Option<usize>| {
                let mut acc = [0.0; 4];
                for (j, (s, q)) in pos.chunks_exact(3).zip(&q).enumerate() {
                    let v = if Some(j) == skip {
                        [0.0; 4]
                    } else {
                        f([t[0] - s[0], t[1] - s[1], t[2] - s[2]])
                    };
                    for a in 0..4 {
                        acc[a] += q * v[a];
                    }
                }
                acc
            };
            type Sum<'a> = &'a dyn Fn(&[usize]) -> Vec<f64>;
            type At<'a> = &'a dyn Fn(&[f64]) -> Vec<f64>;
            type Green<'a> = &'a dyn Fn([f64; 3]) -> [f64; 4];
            let slab_src = |s: &[usize]| {
                slab.sum_at_sources(pos, &q, s, EvalMode::PotentialGradient)
                    .unwrap()
            };
            let slab_at = |t: &[f64]| {
                slab.sum_at_points(pos, &q, t, EvalMode::PotentialGradient)
                    .unwrap()
            };
            let rod_src = |s: &[usize]| {
                rod.sum_at_sources(pos, &q, s, EvalMode::PotentialGradient)
                    .unwrap()
            };
            let rod_at = |t: &[f64]| {
                rod.sum_at_points(pos, &q, t, EvalMode::PotentialGradient)
                    .unwrap()
            };
            let cases: [(Sum, At, Green, f64); 2] = [
                (
                    &slab_src,
                    &slab_at,
                    &|r| slab.potential(r),
                    slab.self_potential(),
                ),
                (
                    &rod_src,
                    &rod_at,
                    &|r| rod.potential(r),
                    rod.self_potential(),
                ),
            ];
            for (at_sources, at_points, f, xi) in cases {
                let got = at_sources(&sample);
                let got_t = at_points(&targets);
                let mut want = Vec::new();
                for &i in &sample {
                    let t = [pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]];
                    let mut v = pair(f, t, Some(i));
                    v[0] += q[i] * xi;
                    want.extend(v);
                }
                for t in targets.chunks_exact(3) {
                    want.extend(pair(f, [t[0], t[1], t[2]], None));
                }
                let all: Vec<f64> = got.iter().chain(&got_t).copied().collect();
                let size = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                for (a, b) in all.iter().zip(&want) {
                    assert!((a - b).abs() < 1e-11 * size, "kappa {kappa}: {a} {b}");
                }
            }
        }
    }
}
