//! Ewald summation (periodic Laplace): Madelung constants, independence of
//! the splitting parameter, gradients, tolerances, the pairwise periodic
//! Green's function against the Ewald sum and against brute-force cubic
//! lattice sums, and bad input.

use ferrofmm_kernels::{
    EvalMode, EwaldOptions, EwaldSum, INV_4PI, KernelError, PeriodicCell, PeriodicGreen,
};
use ferrofmm_testing::{charges, points};
use std::f64::consts::PI;

/// Ions `(position, charge)` of a crystal given by fractional sites of a
/// cubic conventional cell of side `a`.
fn crystal(a: f64, sites: &[([f64; 3], f64)]) -> (PeriodicCell, Vec<f64>, Vec<f64>) {
    let cell = PeriodicCell::cubic([-0.3, 0.1, 0.7], a).unwrap();
    let o = cell.origin();
    let mut pos = Vec::new();
    let mut q = Vec::new();
    for (f, c) in sites {
        pos.extend([o[0] + a * f[0], o[1] + a * f[1], o[2] + a * f[2]]);
        q.push(*c);
    }
    (cell, pos, q)
}

/// Madelung constant from site potentials and from the energy, with the
/// nearest-neighbour distance `d`: `phi_i = -q_i M / (4 pi d)` for unit
/// charges and `E = -(N/2) M / (4 pi d)`.
fn madelung(a: f64, d: f64, sites: &[([f64; 3], f64)]) -> (Vec<f64>, f64) {
    let (cell, pos, q) = crystal(a, sites);
    let ewald = EwaldSum::new(cell, &pos, &q, 1e-15).unwrap();
    let phi = ewald.all(EvalMode::Potential).unwrap();
    let per_site = phi
        .iter()
        .zip(&q)
        .map(|(p, qi)| -p * qi * 4.0 * PI * d)
        .collect();
    let n = q.len() as f64;
    let from_energy = -ewald.energy() * 4.0 * PI * d / (0.5 * n);
    (per_site, from_energy)
}

fn assert_madelung(name: &str, got: (Vec<f64>, f64), want: f64) {
    for m in got.0.iter().chain([&got.1]) {
        let rel = (m - want).abs() / want;
        assert!(rel < 1e-12, "{name}: {m} vs {want} (rel {rel:.1e})");
    }
}

#[test]
fn madelung_nacl() {
    // Rock salt: a simple cubic lattice of alternating charges, a = 2 d.
    let mut sites = Vec::new();
    for i in 0..8 {
        let f = [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64];
        let s = if (i & 1) ^ ((i >> 1) & 1) ^ ((i >> 2) & 1) == 0 {
            1.0
        } else {
            -1.0
        };
        sites.push(([f[0] / 2.0, f[1] / 2.0, f[2] / 2.0], s));
    }
    assert_madelung("NaCl", madelung(2.0, 1.0, &sites), 1.747_564_594_633_182);
}

#[test]
fn madelung_cscl() {
    let sites = [([0.0; 3], 1.0), ([0.5; 3], -1.0)];
    let a = 1.3;
    assert_madelung(
        "CsCl",
        madelung(a, a * 3f64.sqrt() / 2.0, &sites),
        1.762_674_773_070,
    );
}

#[test]
fn madelung_zincblende() {
    let fcc = [
        [0.0, 0.0, 0.0],
        [0.0, 0.5, 0.5],
        [0.5, 0.0, 0.5],
        [0.5, 0.5, 0.0],
    ];
    let mut sites = Vec::new();
    for f in fcc {
        sites.push((f, 1.0));
        sites.push(([f[0] + 0.25, f[1] + 0.25, f[2] + 0.25], -1.0));
    }
    let a = 0.9;
    assert_madelung(
        "ZnS",
        madelung(a, a * 3f64.sqrt() / 4.0, &sites),
        1.638_055_053_388,
    );
}

/// 500 points in an orthorhombic cell: uniform with zero-mean charges, or
/// clustered with alternating unit charges.
fn test_sets() -> Vec<(&'static str, PeriodicCell, Vec<f64>, Vec<f64>)> {
    let cell = PeriodicCell::new([-0.5, -0.25, 0.0], [1.0, 1.2, 0.8]).unwrap();
    let n = 500;
    let mut uniform = points::uniform_cube(n, -0.5, 1.0, 3);
    for p in uniform.chunks_exact_mut(3) {
        p[1] = -0.25 + 1.2 * (p[1] + 0.5);
        p[2] = 0.8 * (p[2] + 0.5);
    }
    let mut q = charges::uniform_in(n, -1.0, 1.0, 4);
    let mean = q.iter().sum::<f64>() / n as f64;
    q.iter_mut().for_each(|v| *v -= mean);
    let clustered: Vec<f64> = points::clustered(n, 6, 2.0, 5)
        .chunks_exact(3)
        .flat_map(|p| [p[0] - 0.5, 1.2 * p[1] - 0.25, 0.8 * p[2]])
        .collect();
    let pm: Vec<f64> = (0..n)
        .map(|i| if i % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    // Not neutral: exercises the background term.
    let charged: Vec<f64> = charges::uniform_in(n, 0.0, 1.0, 6);
    vec![
        ("uniform", cell, uniform.clone(), q),
        ("clustered", cell, clustered, pm),
        ("charged", cell, uniform, charged),
    ]
}

fn rms(v: &[f64], stride: usize, cols: std::ops::Range<usize>) -> f64 {
    let vals: Vec<f64> = v
        .chunks_exact(stride)
        .flat_map(|c| c[cols.clone()].to_vec())
        .collect();
    (vals.iter().map(|x| x * x).sum::<f64>() / vals.len() as f64).sqrt()
}

/// `max |a - b| / rms(b)` over potentials and over gradients separately.
fn rel_errors(a: &[f64], b: &[f64]) -> (f64, f64) {
    let mut e = [0.0f64; 2];
    for (k, cols) in [(0usize, 0..1usize), (1, 1..4)] {
        let scale = rms(b, 4, cols.clone());
        for (x, y) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
            for c in cols.clone() {
                e[k] = e[k].max((x[c] - y[c]).abs() / scale);
            }
        }
    }
    (e[0], e[1])
}

#[test]
fn alpha_independence() {
    for (name, cell, pos, q) in test_sets() {
        let base = EwaldSum::new(cell, &pos, &q, 1e-15).unwrap();
        let alpha = base.parameters().alpha;
        let want = base.all(EvalMode::PotentialGradient).unwrap();
        // Rounding, not truncation, limits the agreement: more real-space
        // terms at small alpha, and the non-neutral set cancels its
        // real-space sum against the background.
        let bound = if name == "charged" { 3e-13 } else { 1e-13 };
        for factor in [0.7, 1.6] {
            let opts = EwaldOptions::new(1e-15).with_alpha(alpha * factor);
            let other = EwaldSum::with_options(cell, &pos, &q, opts).unwrap();
            let got = other.all(EvalMode::PotentialGradient).unwrap();
            let (ep, eg) = rel_errors(&got, &want);
            assert!(
                ep < bound && eg < bound,
                "{name} alpha x{factor}: {ep:.1e} {eg:.1e}"
            );
            let (e1, e2) = (base.energy(), other.energy());
            assert!(
                (e1 - e2).abs() < bound * e1.abs(),
                "{name}: energies {e1} {e2}"
            );
        }
    }
}

#[test]
fn tolerance_is_met() {
    for (name, cell, pos, q) in test_sets() {
        let want = EwaldSum::new(cell, &pos, &q, 1e-15)
            .unwrap()
            .all(EvalMode::PotentialGradient)
            .unwrap();
        for tol in [1e-3, 1e-6, 1e-10, 1e-13] {
            for hint in [None, Some(20)] {
                let mut opts = EwaldOptions::new(tol);
                if let Some(h) = hint {
                    opts = opts.expected_targets(h);
                }
                let e = EwaldSum::with_options(cell, &pos, &q, opts).unwrap();
                let got = e.all(EvalMode::PotentialGradient).unwrap();
                let (ep, eg) = rel_errors(&got, &want);
                assert!(
                    ep < tol && eg < tol,
                    "{name} tol {tol:.0e} hint {hint:?}: {ep:.1e} {eg:.1e}"
                );
            }
        }
    }
}

#[test]
fn sources_points_and_all_agree() {
    let (_, cell, pos, q) = test_sets().remove(0);
    let e = EwaldSum::new(cell, &pos, &q, 1e-14).unwrap();
    let all = e.all(EvalMode::PotentialGradient).unwrap();
    let idx = [7usize, 0, 499, 7];
    let at = e.at_sources(&idx, EvalMode::PotentialGradient).unwrap();
    // A target exactly at a source leaves out its direct term.
    let same: Vec<f64> = idx
        .iter()
        .flat_map(|&i| pos[3 * i..3 * i + 3].to_vec())
        .collect();
    let pts = e.at_points(&same, EvalMode::PotentialGradient).unwrap();
    let scale = rms(&all, 4, 0..4);
    for (k, &i) in idx.iter().enumerate() {
        for c in 0..4 {
            assert_eq!(at[4 * k + c], all[4 * i + c]);
            assert!((pts[4 * k + c] - all[4 * i + c]).abs() < 1e-12 * scale);
        }
    }
    let pot = e.at_sources(&idx, EvalMode::Potential).unwrap();
    for (k, &i) in idx.iter().enumerate() {
        assert!((pot[k] - all[4 * i]).abs() < 1e-14 * scale);
    }
}

#[test]
fn gradient_matches_finite_differences() {
    for (name, cell, pos, q) in test_sets() {
        let e = EwaldSum::new(cell, &pos, &q, 1e-15).unwrap();
        // Targets at least 0.05 from every source image (bounded third
        // derivatives for the difference quotient).
        let targets: Vec<f64> = points::uniform_cube(200, -0.6, 1.5, 9)
            .chunks_exact(3)
            .filter(|t| {
                pos.chunks_exact(3).all(|p| {
                    let r = cell.nearest_image([t[0] - p[0], t[1] - p[1], t[2] - p[2]]);
                    r[0] * r[0] + r[1] * r[1] + r[2] * r[2] > 0.05 * 0.05
                })
            })
            .take(20)
            .flatten()
            .copied()
            .collect();
        assert!(
            targets.len() / 3 >= 15,
            "{name}: {} targets",
            targets.len() / 3
        );
        let g = e.at_points(&targets, EvalMode::PotentialGradient).unwrap();
        let h = 1e-5;
        let scale = rms(&g, 4, 1..4);
        for (t, gt) in targets.chunks_exact(3).zip(g.chunks_exact(4)) {
            for d in 0..3 {
                let mut p = t.to_vec();
                p[d] += h;
                let mut m = t.to_vec();
                m[d] -= h;
                let both = [p, m].concat();
                let v = e.at_points(&both, EvalMode::Potential).unwrap();
                let fd = (v[0] - v[1]) / (2.0 * h);
                assert!(
                    (fd - gt[1 + d]).abs() < 1e-7 * scale.max(gt[1 + d].abs()),
                    "{name}: fd {fd} vs {}",
                    gt[1 + d]
                );
            }
        }
    }
}

/// `sum_{n in {-1,0,1}^3} K(r - n∘L)`.
fn near_images(cell: &PeriodicCell, r: [f64; 3]) -> f64 {
    let l = cell.lengths();
    let mut s = 0.0;
    for nx in -1..=1 {
        for ny in -1..=1 {
            for nz in -1..=1 {
                let d = [
                    r[0] - nx as f64 * l[0],
                    r[1] - ny as f64 * l[1],
                    r[2] - nz as f64 * l[2],
                ];
                s += INV_4PI / (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            }
        }
    }
    s
}

fn cells() -> Vec<PeriodicCell> {
    vec![
        PeriodicCell::cubic([0.0; 3], 1.0).unwrap(),
        PeriodicCell::new([1.0, -2.0, 0.5], [1.0, 0.7, 1.6]).unwrap(),
        PeriodicCell::cubic([0.0; 3], 3.5).unwrap(),
    ]
}

#[test]
fn green_matches_ewald_of_a_neutral_pair() {
    for cell in cells() {
        let l = cell.lengths();
        let o = cell.origin();
        let a = [o[0] + 0.2 * l[0], o[1] + 0.7 * l[1], o[2] + 0.4 * l[2]];
        let b = [o[0] + 0.9 * l[0], o[1] + 0.1 * l[1], o[2] + 0.5 * l[2]];
        let src = [a, b].concat();
        let e = EwaldSum::new(cell, &src, &[1.0, -1.0], 1e-15).unwrap();
        let g = PeriodicGreen::new(cell, 1e-15).unwrap();
        let targets: Vec<f64> = points::uniform_cube(30, -1.0, 3.0, 11)
            .chunks_exact(3)
            .flat_map(|p| [o[0] + p[0] * l[0], o[1] + p[1] * l[1], o[2] + p[2] * l[2]])
            .collect();
        let phi = e.at_points(&targets, EvalMode::Potential).unwrap();
        for (t, want) in targets.chunks_exact(3).zip(&phi) {
            let ra = [t[0] - a[0], t[1] - a[1], t[2] - a[2]];
            let rb = [t[0] - b[0], t[1] - b[1], t[2] - b[2]];
            let got = g.potential(ra) - g.potential(rb);
            assert!((got - want).abs() < 1e-13 / l[0], "{got} vs {want}");
            // far_images + 27 images is the whole potential (any r).
            for r in [ra, rb] {
                let whole = g.far_images(r) + near_images(&cell, r);
                assert!((whole - g.potential(r)).abs() < 1e-13 / l[0] * (1.0 + whole.abs() * l[0]));
            }
        }
        // The source's own images: G(r) - K(r) -> xi.
        let ea = EwaldSum::new(cell, &src, &[1.0, -1.0], 1e-15).unwrap();
        let at_a = ea.at_sources(&[0], EvalMode::Potential).unwrap()[0];
        let ab = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let want = g.self_potential() - g.potential(ab);
        assert!((at_a - want).abs() < 1e-13 / l[0], "{at_a} vs {want}");
    }
}

#[test]
fn far_images_is_smooth_with_laplacian_one_over_v() {
    for cell in cells() {
        let g = PeriodicGreen::new(cell, 1e-15).unwrap();
        let l = cell.lengths();
        let v = cell.volume();
        let h = 1e-3 * l[0].min(l[1]).min(l[2]);
        let rs = [
            [0.0, 0.0, 0.0],
            [1e-9, 0.0, 0.0],
            [0.3, -0.45, 0.1],
            [1.2, 1.1, -1.3],
            [0.5, 0.5, 0.5],
        ];
        for f in rs {
            let r = [f[0] * l[0], f[1] * l[1], f[2] * l[2]];
            let c = g.far_images(r);
            let mut lap = 0.0;
            for d in 0..3 {
                let mut p = r;
                p[d] += h;
                let mut m = r;
                m[d] -= h;
                lap += (g.far_images(p) - 2.0 * c + g.far_images(m)) / (h * h);
            }
            assert!(
                (lap - 1.0 / v).abs() < 1e-4 / v,
                "{r:?}: {lap} vs {}",
                1.0 / v
            );
        }
        // Continuous at r = 0 and equal to G - 27 images away from it.
        let z = g.far_images([0.0; 3]);
        let t = g.far_images([1e-9 * l[0], 0.0, 0.0]);
        assert!((z - t).abs() < 1e-12 / l[0]);
        let r = [0.37 * l[0], 0.2 * l[1], -0.61 * l[2]];
        assert!((g.far_images(r) - (g.potential(r) - near_images(&cell, r))).abs() < 1e-13 / l[0]);
        // Matrix = pairwise.
        let tg = points::uniform_cube(7, -0.5, 1.0, 1);
        let sr = points::uniform_cube(5, -0.5, 1.0, 2);
        let m = g.far_images_matrix(&tg, &sr).unwrap();
        for i in 0..7 {
            for j in 0..5 {
                let r = [0, 1, 2].map(|d| tg[3 * i + d] - sr[3 * j + d]);
                assert_eq!(m[5 * i + j], g.far_images(r));
            }
        }
    }
}

/// `sum_{n in [-M, M]^3 \ [-1, 1]^3} sum_j q_j K(y - x_j - n L)` (cubic cell).
fn cubic_shells(l: f64, m: i64, y: [f64; 3], src: &[[f64; 3]], q: &[f64]) -> f64 {
    let mut total = 0.0;
    for nz in -m..=m {
        for ny in -m..=m {
            let mut row = 0.0;
            for nx in -m..=m {
                if nx.abs() <= 1 && ny.abs() <= 1 && nz.abs() <= 1 {
                    continue;
                }
                for (x, qj) in src.iter().zip(q) {
                    let d = [
                        y[0] - x[0] - nx as f64 * l,
                        y[1] - x[1] - ny as f64 * l,
                        y[2] - x[2] - nz as f64 * l,
                    ];
                    row += qj / (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                }
            }
            total += row;
        }
    }
    INV_4PI * total
}

/// The convention the periodic FMM relies on: for a neutral set in a cubic
/// cell, the brute-force lattice sum over growing cubes of images equals
/// the tin-foil sum **minus** `1/(6V) sum_j q_j |y - x_j|^2` (the cubic
/// shape term; consistent with `E_cube - E_tinfoil = |D|^2 / (6V)`). Far images only (both sides without the 27 nearest), the cubic
/// sums extrapolated in `M` (error `O(M^-2)`).
#[test]
fn far_images_match_cubic_lattice_sums_with_shape_term() {
    let l = 1.0;
    let cell = PeriodicCell::cubic([0.0; 3], l).unwrap();
    let g = PeriodicGreen::new(cell, 1e-15).unwrap();
    let v = cell.volume();
    // A neutral set with dipole and second moments.
    let src = [
        [0.1, 0.2, 0.3],
        [0.8, 0.3, 0.6],
        [0.4, 0.9, 0.2],
        [0.6, 0.5, 0.85],
    ];
    let q = [1.0, -0.5, 0.75, -1.25];
    for y in [[0.5, 0.5, 0.5], [0.05, 0.9, 0.3], [0.7, 0.15, 0.95]] {
        let mut tin = 0.0f64;
        let mut shape = 0.0;
        for (x, qj) in src.iter().zip(q) {
            let r = [y[0] - x[0], y[1] - x[1], y[2] - x[2]];
            tin += qj * g.far_images(r);
            shape += qj * (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]) / (6.0 * v);
        }
        let s1 = cubic_shells(l, 24, y, &src, &q);
        let s2 = cubic_shells(l, 48, y, &src, &q);
        let extrapolated = (4.0 * s2 - s1) / 3.0;
        let want = tin - shape;
        println!(
            "y = {y:?}: cubic (extrapolated) - (tin-foil - shape) = {:.1e}",
            extrapolated - want
        );
        assert!(
            (extrapolated - want).abs() < 1e-6,
            "y = {y:?}: cubic {extrapolated} (M=24: {s1}, M=48: {s2}) vs tin-foil - shape {want} (tin-foil {tin})"
        );
        // Without the shape term the two disagree (the test can fail).
        assert!((extrapolated - tin).abs() > 1e-3 * shape.abs());
    }
}

#[test]
fn bad_input_is_an_error() {
    for l in [
        [1.0, 0.0, 1.0],
        [1.0, -1.0, 1.0],
        [f64::NAN, 1.0, 1.0],
        [1.0, 1.0, f64::INFINITY],
    ] {
        assert!(matches!(
            PeriodicCell::new([0.0; 3], l),
            Err(KernelError::InvalidCell {
                what: "lengths",
                ..
            })
        ));
    }
    assert!(PeriodicCell::new([f64::NAN, 0.0, 0.0], [1.0; 3]).is_err());
    let cell = PeriodicCell::cubic([0.0; 3], 1.0).unwrap();
    let pos = [0.1, 0.2, 0.3, 0.4, f64::NAN, 0.6];
    assert!(matches!(
        EwaldSum::new(cell, &pos, &[1.0, -1.0], 1e-10),
        Err(KernelError::NonFinite {
            what: "sources",
            index: 4,
            ..
        })
    ));
    let pos = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6];
    assert!(matches!(
        EwaldSum::new(cell, &pos, &[1.0], 1e-10),
        Err(KernelError::ChargesLength {
            n_sources: 2,
            n_charges: 1
        })
    ));
    assert!(matches!(
        EwaldSum::new(cell, &pos[..5], &[1.0], 1e-10),
        Err(KernelError::NotMultipleOf3 { .. })
    ));
    assert!(EwaldSum::new(cell, &pos, &[1.0, f64::INFINITY], 1e-10).is_err());
    for tol in [0.0, -1.0, 1.0, f64::NAN] {
        assert!(EwaldSum::new(cell, &pos, &[1.0, -1.0], tol).is_err());
        assert!(PeriodicGreen::new(cell, tol).is_err());
    }
    assert!(
        EwaldSum::with_options(
            cell,
            &pos,
            &[1.0, -1.0],
            EwaldOptions::new(1e-6).with_alpha(-1.0)
        )
        .is_err()
    );
    let e = EwaldSum::new(cell, &pos, &[1.0, -1.0], 1e-10).unwrap();
    assert!(matches!(
        e.at_sources(&[2], EvalMode::Potential),
        Err(KernelError::SourceIndex {
            index: 2,
            n_sources: 2
        })
    ));
    assert!(
        e.at_points(&[0.0, f64::NAN, 0.0], EvalMode::Potential)
            .is_err()
    );
    assert!(e.at_points(&[0.0, 0.0], EvalMode::Potential).is_err());
    assert!(matches!(
        e.all(EvalMode::PotentialGradientHessian),
        Err(KernelError::Unsupported { .. })
    ));
    let g = PeriodicGreen::new(cell, 1e-10).unwrap();
    assert!(g.far_images_matrix(&[0.0, 0.0], &[0.0; 3]).is_err());
    assert!(
        g.far_images_matrix(&[0.0; 3], &[f64::NAN, 0.0, 0.0])
            .is_err()
    );
    // Empty input is fine.
    let empty = EwaldSum::new(cell, &[], &[], 1e-10).unwrap();
    assert_eq!(empty.all(EvalMode::Potential).unwrap(), Vec::<f64>::new());
    assert_eq!(
        empty.at_points(&[0.5; 3], EvalMode::Potential).unwrap(),
        vec![0.0]
    );
}

/// Timings for the notes: `cargo test -p ferrofmm-kernels --test
/// integration ewald::timing -- --ignored --nocapture`.
#[test]
#[ignore = "timing run"]
fn timing() {
    use std::time::Instant;
    let cell = PeriodicCell::cubic([0.0; 3], 1.0).unwrap();
    for n in [10_000usize, 100_000] {
        let pos = points::uniform_cube(n, 0.0, 1.0, 21);
        let mut q = charges::uniform_in(n, -1.0, 1.0, 22);
        let mean = q.iter().sum::<f64>() / n as f64;
        q.iter_mut().for_each(|v| *v -= mean);
        let t0 = Instant::now();
        let e = EwaldSum::new(cell, &pos, &q, 1e-14).unwrap();
        let t1 = Instant::now();
        let all = e.all(EvalMode::PotentialGradient).unwrap();
        let t2 = Instant::now();
        let p = e.parameters();
        println!(
            "N = {n}: setup {:.2} s, all(gradient) {:.2} s; alpha {:.2}, r_c {:.3}, k_c {:.1}, {} wave vectors [{}]",
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64(),
            p.alpha,
            p.r_cut,
            p.k_cut,
            e.n_wave_vectors(),
            all.len()
        );
        let t1 = Instant::now();
        let _ = e.all(EvalMode::Potential).unwrap();
        println!("  all(potential) {:.2} s", t1.elapsed().as_secs_f64());
        let t0 = Instant::now();
        let e = EwaldSum::with_options(
            cell,
            &pos,
            &q,
            EwaldOptions::new(1e-14).expected_targets(500),
        )
        .unwrap();
        let idx: Vec<usize> = (0..500).map(|i| i * (n / 500)).collect();
        let s = e.at_sources(&idx, EvalMode::PotentialGradient).unwrap();
        println!(
            "  500 targets (hint): {:.2} s total, alpha {:.2}, {} wave vectors [{}]",
            t0.elapsed().as_secs_f64(),
            e.parameters().alpha,
            e.n_wave_vectors(),
            s.len()
        );
    }
    let g = PeriodicGreen::new(cell, 1e-15).unwrap();
    let t = points::uniform_cube(1352, -0.5, 1.0, 23);
    let s = points::uniform_cube(1352, -0.5, 1.0, 24);
    let t0 = Instant::now();
    let m = g.far_images_matrix(&t, &s).unwrap();
    println!(
        "far_images_matrix 1352 x 1352: {:.2} s [{}]",
        t0.elapsed().as_secs_f64(),
        m.len()
    );
}
