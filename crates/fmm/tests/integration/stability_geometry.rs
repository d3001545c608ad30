//! Stability suite, geometry: point sets where tree-based methods fail
//! quietly. Every case is checked against direct summation with the
//! order-derived tolerance of `stability_common::tol` (10x the worst single
//! interaction chain), and the measured errors are in docs/stability.md.

use crate::stability_common;

use ferrofmm_fmm::{FmmBuilder, FmmError, Geometry, relative_errors};
use ferrofmm_kernels::{EvalMode, Laplace3d, Real};
use ferrofmm_tree::{DEEPEST_LEVEL, Domain};
use stability_common::{
    Scheme, assert_meets_tol, cancellation, charges_in, evaluate, measure, potential_error, tol,
    uniform,
};

const P: usize = 6;

fn repeat_point(p: [f64; 3], n: usize) -> Vec<f64> {
    p.repeat(n)
}

#[test]
fn coincident_points_give_exact_zeros_and_a_capped_tree() {
    // Every pair coincides, so phi = 0 exactly (K(x, x) := 0). The tree
    // cannot separate the points: it refines to the key's deepest level and
    // stops there with one leaf holding all 500 points.
    let n = 500;
    let pts = repeat_point([0.3, -0.7, 2.0], n);
    let q: Vec<f64> = charges_in(n, -1.0, 1.0, 1);
    let fmm = FmmBuilder::new(&pts)
        .order(P)
        .leaf_size(16)
        .build_dense()
        .unwrap();
    assert_eq!(fmm.tree().depth(), DEEPEST_LEVEL);
    let v = fmm.evaluate(&q).unwrap();
    assert!(v.iter().all(|&x| x == 0.0), "nonzero self-potential");

    // The same cloud seen from separate targets around it.
    let targets: Vec<f64> = uniform(300, -1.0, 3.0, 2);
    let e = measure(
        "coincident sources, separate targets",
        &pts,
        Some(&targets),
        &q,
        P,
        16,
        Scheme::Dense,
    );
    assert_meets_tol::<f64>(e, P);
}

#[test]
fn many_exact_duplicates() {
    // 100 distinct points, each given 20 times, leaf size 8: the boxes
    // holding a duplicate refine to the deepest level and keep 20 points.
    let base: Vec<f64> = uniform(100, 0.0, 1.0, 3);
    let pts: Vec<f64> = (0..2000)
        .flat_map(|i| {
            let k = i % 100;
            [base[3 * k], base[3 * k + 1], base[3 * k + 2]]
        })
        .collect();
    let q: Vec<f64> = charges_in(2000, 0.0, 1.0, 4);
    let fmm = FmmBuilder::new(&pts)
        .order(P)
        .leaf_size(8)
        .build_dense()
        .unwrap();
    assert_eq!(fmm.tree().depth(), DEEPEST_LEVEL);
    let e = potential_error(&pts, &pts, &q, &fmm.evaluate(&q).unwrap());
    eprintln!("duplicates x20: relative L2 error {e:.2e}");
    assert!(e <= tol::<f64>(P), "error {e:.2e}");
    // Targets exactly at the distinct points, given separately.
    let e = measure(
        "duplicates, distinct targets",
        &pts,
        Some(&base),
        &q,
        P,
        8,
        Scheme::Dense,
    );
    assert_meets_tol::<f64>(e, P);
}

#[test]
fn collinear_and_coplanar_points() {
    let n = 2000;
    let t: Vec<f64> = uniform::<f64>(n, 0.0, 1.0, 5);
    let q: Vec<f64> = charges_in(n, 0.0, 1.0, 6);
    let cases: [(&str, Vec<f64>); 4] = [
        (
            "collinear, axis-aligned",
            (0..n).flat_map(|i| [t[3 * i], 0.5, 0.5]).collect(),
        ),
        (
            "collinear, diagonal",
            (0..n).flat_map(|i| [t[3 * i]; 3]).collect(),
        ),
        (
            "coplanar z = 0.25",
            (0..n)
                .flat_map(|i| [t[3 * i], t[3 * i + 1], 0.25])
                .collect(),
        ),
        (
            "coplanar, tilted",
            (0..n)
                .flat_map(|i| [t[3 * i], t[3 * i + 1], 0.3 * t[3 * i] - 0.2 * t[3 * i + 1]])
                .collect(),
        ),
    ];
    for (name, pts) in cases {
        let e = measure(name, &pts, None, &q, P, 16, Scheme::Dense);
        assert!(e <= tol::<f64>(P), "{name}: error {e:.2e}");
    }
}

#[test]
fn dyadic_lattice_on_box_faces_and_corners() {
    // 9^3 points i/8: every point lies on box faces, edges or corners at
    // levels 1..3, and with the given domain [0, 1]^3 the points with a
    // coordinate 1 lie on the domain's upper faces (accepted: the domain is
    // closed and they go to the last box).
    let pts: Vec<f64> = (0..729)
        .flat_map(|i| {
            [
                (i % 9) as f64 / 8.0,
                ((i / 9) % 9) as f64 / 8.0,
                (i / 81) as f64 / 8.0,
            ]
        })
        .collect();
    let q: Vec<f64> = charges_in(729, 0.0, 1.0, 7);
    let e = measure(
        "lattice i/8, computed domain",
        &pts,
        None,
        &q,
        P,
        8,
        Scheme::Dense,
    );
    assert_meets_tol::<f64>(e, P);
    let fmm = FmmBuilder::new(&pts)
        .order(P)
        .leaf_size(8)
        .domain(Domain::new([0.0; 3], 1.0).unwrap())
        .build_dense()
        .unwrap();
    assert!(fmm.tree().depth() >= 3);
    let e = potential_error(&pts, &pts, &q, &fmm.evaluate(&q).unwrap());
    eprintln!("lattice i/8, domain [0, 1]^3: relative L2 error {e:.2e}");
    assert!(e <= tol::<f64>(P), "error {e:.2e}");
}

/// Relative L2 error on the targets `range` only.
fn error_on(pts: &[f64], q: &[f64], values: &[f64], range: std::ops::Range<usize>) -> f64 {
    let sample: Vec<usize> = range.collect();
    relative_errors(
        &Laplace3d,
        EvalMode::Potential,
        pts,
        q,
        pts,
        values,
        &sample,
    )
    .potential
}

#[test]
fn clusters_of_very_different_sizes_reach_the_depth_limit() {
    // 1000 points uniform in the unit cube plus 1000 in a cube of side s
    // inside it, s = 1e-4 .. 1e-9 (size ratios 1e4 .. 1e9), and s = 0 (a
    // point mass of 1000 coincident points). The potential inside the small
    // cluster is ~1/s times larger than in the background, so the two
    // groups of targets are measured separately.
    let q: Vec<f64> = charges_in(2000, 0.0, 1.0, 8);
    let background: Vec<f64> = uniform(1000, 0.0, 1.0, 9);
    for s in [1e-4, 1e-6, 1e-9, 0.0] {
        let small: Vec<f64> = uniform(1000, 0.7, s, 10);
        let pts: Vec<f64> = background.iter().chain(&small).copied().collect();
        let fmm = FmmBuilder::new(&pts)
            .order(P)
            .leaf_size(16)
            .build_dense()
            .unwrap();
        let depth = fmm.tree().depth();
        if s <= 1e-6 {
            // Finest cells are 2^-19 ~ 1.9e-6 of the domain wide.
            assert_eq!(depth, DEEPEST_LEVEL, "s = {s:e}");
        } else {
            assert!(depth >= 12, "s = {s:e}: depth {depth}");
        }
        let v = fmm.evaluate(&q).unwrap();
        let e_bg = error_on(&pts, &q, &v, 0..1000);
        let e_cl = error_on(&pts, &q, &v, 1000..2000);
        eprintln!(
            "cluster of size {s:e} in a unit cube: depth {depth}, error background {e_bg:.2e}, \
             cluster {e_cl:.2e}"
        );
        assert!(
            e_bg <= tol::<f64>(P),
            "s = {s:e}: background error {e_bg:.2e}"
        );
        assert!(e_cl <= tol::<f64>(P), "s = {s:e}: cluster error {e_cl:.2e}");
    }
    // Two separate clusters, 1e5 apart in size, at opposite corners.
    let a: Vec<f64> = uniform(1000, 0.0, 1.0, 11);
    let b: Vec<f64> = uniform(1000, 5.0, 1e-5, 12);
    let pts: Vec<f64> = a.iter().chain(&b).copied().collect();
    let fmm = FmmBuilder::new(&pts)
        .order(P)
        .leaf_size(16)
        .build_dense()
        .unwrap();
    let v = fmm.evaluate(&q).unwrap();
    let (e_a, e_b) = (
        error_on(&pts, &q, &v, 0..1000),
        error_on(&pts, &q, &v, 1000..2000),
    );
    eprintln!(
        "two clusters, sizes 1 and 1e-5: depth {}, errors {e_a:.2e} / {e_b:.2e}",
        fmm.tree().depth()
    );
    assert!(e_a <= tol::<f64>(P) && e_b <= tol::<f64>(P));
}

#[test]
fn a_single_point() {
    // One source evaluated at itself: nothing but the excluded self pair.
    let one = [0.1f64, 0.2, 0.3];
    let v = evaluate(&one, None, &[2.0], P, 16, Scheme::Dense);
    assert_eq!(v, vec![0.0]);
    // One source, many targets; many sources, one target.
    let targets: Vec<f64> = uniform(200, -1.0, 2.0, 13);
    let e = measure(
        "single source",
        &one,
        Some(&targets),
        &[2.0],
        P,
        4,
        Scheme::Dense,
    );
    assert_meets_tol::<f64>(e, P);
    let q: Vec<f64> = charges_in(200, 0.0, 1.0, 14);
    let e = measure(
        "single target",
        &targets,
        Some(&one),
        &q,
        P,
        4,
        Scheme::Dense,
    );
    assert_meets_tol::<f64>(e, P);
}

#[test]
fn sources_and_targets_apart() {
    let n = 2000;
    let sources: Vec<f64> = uniform(n, 0.0, 1.0, 15);
    let q: Vec<f64> = charges_in(n, 0.0, 1.0, 16);
    // Disjoint boxes side by side.
    let targets: Vec<f64> = uniform(500, 2.0, 1.0, 17);
    let e = measure(
        "targets in [2, 3)^3",
        &sources,
        Some(&targets),
        &q,
        P,
        16,
        Scheme::Dense,
    );
    assert_meets_tol::<f64>(e, P);
    // Targets 1000 widths away: the sources shrink into a few deep boxes.
    let targets: Vec<f64> = uniform(500, 1e3, 1.0, 17);
    let e = measure(
        "targets in [1e3, 1e3 + 1)^3",
        &sources,
        Some(&targets),
        &q,
        P,
        16,
        Scheme::Dense,
    );
    assert_meets_tol::<f64>(e, P);
    // Targets all around, on a sphere of radius 1e3.
    let targets: Vec<f64> = Geometry::Sphere
        .points::<f64>(500, 18)
        .iter()
        .map(|x| 1e3 * x)
        .collect();
    let e = measure(
        "targets on a sphere of radius 1e3",
        &sources,
        Some(&targets),
        &q,
        P,
        16,
        Scheme::Dense,
    );
    assert_meets_tol::<f64>(e, P);
}

/// Error of the unit-cube problem shifted to `offset` (and scaled by
/// `width`), next to the same problem at the origin.
fn shifted<T: Real>(offset: f64, width: f64, order: usize) -> (f64, f64) {
    let n = 2000;
    let at_origin: Vec<T> = uniform(n, 0.0, width, 19);
    let far: Vec<T> = uniform(n, offset, width, 19);
    let q: Vec<T> = charges_in(n, 0.0, 1.0, 20);
    let e0 = measure(
        "unit problem at the origin",
        &at_origin,
        None,
        &q,
        order,
        32,
        Scheme::Dense,
    );
    let e1 = measure(
        &format!("same problem at {offset:e}"),
        &far,
        None,
        &q,
        order,
        32,
        Scheme::Dense,
    );
    (e0, e1)
}

#[test]
fn coordinates_far_from_the_origin_f64() {
    // At 1e8 + [0, 1)^3 the coordinates keep 8 digits of the offset and 8
    // of the position; an FMM that places its surfaces in absolute
    // coordinates loses the latter (surface points off by ulp(1e8) = 1.5e-8,
    // 1e-7 of a leaf) and the error at p = 8 grows from 2e-9 to ~1e-7.
    // Computing in coordinates relative to the domain centre keeps the
    // error of the problem at the origin.
    let p = 8;
    let (e0, e1) = shifted::<f64>(1e8, 1.0, p);
    assert!(e1 <= tol::<f64>(p), "error {e1:.2e}");
    assert!(
        e1 <= 3.0 * e0,
        "offset costs accuracy: {e1:.2e} vs {e0:.2e}"
    );
}

#[test]
fn coordinates_far_from_the_origin_f32() {
    // In f32, 1e4 + [0, 1)^3 keeps only 3-4 digits of position
    // (ulp(1e4) = 9.8e-4); the points are what they are, but the FMM must
    // not lose more. Same for 1e6 + [0, 100)^3.
    for (offset, width) in [(1e4, 1.0), (1e6, 100.0)] {
        let (e0, e1) = shifted::<f32>(offset, width, P);
        assert!(e1 <= tol::<f32>(P), "offset {offset:e}: error {e1:.2e}");
        assert!(
            e1 <= 3.0 * e0.max(1e-6),
            "offset {offset:e}: {e1:.2e} vs {e0:.2e}"
        );
    }
}

#[test]
fn tiny_and_huge_domains() {
    let n = 2000;
    let q64: Vec<f64> = charges_in(n, 0.0, 1.0, 21);
    let q32: Vec<f32> = charges_in(n, 0.0, 1.0, 21);
    for width in [1e-8, 1e8] {
        let pts: Vec<f64> = uniform(n, 0.0, width, 22);
        let e = measure(
            &format!("width {width:e}"),
            &pts,
            None,
            &q64,
            P,
            16,
            Scheme::Dense,
        );
        assert!(e <= tol::<f64>(P), "width {width:e}: error {e:.2e}");
        let pts: Vec<f32> = uniform(n, 0.0, width, 22);
        let e = measure(
            &format!("width {width:e}"),
            &pts,
            None,
            &q32,
            P,
            16,
            Scheme::Dense,
        );
        assert!(e <= tol::<f32>(P), "width {width:e}: error {e:.2e}");
    }
    // Also through the SVD scheme, whose operators are rescaled per level.
    let pts: Vec<f64> = uniform(n, 0.0, 1e-8, 22);
    let e = measure("width 1e-8", &pts, None, &q64, 4, 16, Scheme::Svd);
    assert!(e <= tol::<f64>(4), "error {e:.2e}");
}

#[test]
fn scales_beyond_the_float_range_are_refused() {
    // Squared distances of 1e-200 underflow to 0 in f64: every pair would
    // count as coincident and the FMM (and a naive direct sum) return
    // exact zeros; at 1e200 they overflow. f32 reaches the same limits
    // near 1e-19 and 1e19. The builder refuses such domains.
    let unit: Vec<f64> = uniform(300, 0.0, 1.0, 23);
    for scale in [1e-200, 1e200] {
        let pts: Vec<f64> = unit.iter().map(|x| x * scale).collect();
        let r = FmmBuilder::new(&pts).order(4).build_dense();
        assert!(
            matches!(r, Err(FmmError::DomainOutOfRange { .. })),
            "f64 scale {scale:e}: {:?}",
            r.err()
        );
    }
    for scale in [1e-30, 1e30] {
        let pts: Vec<f32> = unit.iter().map(|x| (x * scale) as f32).collect();
        let r = FmmBuilder::new(&pts).order(4).build_dense();
        assert!(
            matches!(r, Err(FmmError::DomainOutOfRange { .. })),
            "f32 scale {scale:e}: {:?}",
            r.err()
        );
    }
    // The f32 limit is well away from ordinary scales.
    for scale in [1e-12f64, 1e12] {
        let pts: Vec<f32> = unit.iter().map(|x| (x * scale) as f32).collect();
        assert!(FmmBuilder::new(&pts).order(4).build_dense().is_ok());
    }
}

#[test]
fn mixed_sign_charges_and_cancellation() {
    // Random charges in [-1, 1): moderate cancellation.
    let n = 2000;
    let pts: Vec<f64> = uniform(n, 0.0, 1.0, 24);
    let q: Vec<f64> = charges_in(n, -1.0, 1.0, 25);
    let kappa = cancellation(&pts, &q, &pts);
    let e = measure("charges in [-1, 1)", &pts, None, &q, P, 16, Scheme::Dense);
    eprintln!("  cancellation ratio {kappa:.1}");
    assert!(
        e <= tol::<f64>(P) * kappa,
        "error {e:.2e}, kappa {kappa:.1}"
    );

    // A rock-salt lattice (10^3 alternating charges): neutral, and every
    // multipole moment below the octupole vanishes, so on a sphere of
    // radius 1.5 around it the potential is a tiny difference of large
    // terms. The relative error measured against that tiny potential grows
    // by the cancellation ratio; measured against the size of the terms it
    // is as small as ever.
    let lattice: Vec<f64> = (0..1000)
        .flat_map(|i| {
            [
                (i % 10) as f64 * 0.1,
                ((i / 10) % 10) as f64 * 0.1,
                (i / 100) as f64 * 0.1,
            ]
        })
        .collect();
    let salt: Vec<f64> = (0..1000)
        .map(|i| {
            if (i % 10 + (i / 10) % 10 + i / 100) % 2 == 0 {
                1.0
            } else {
                -1.0
            }
        })
        .collect();
    let targets: Vec<f64> = Geometry::Sphere
        .points::<f64>(500, 26)
        .iter()
        .map(|x| 0.45 + 1.5 * x)
        .collect();
    let kappa = cancellation(&lattice, &salt, &targets);
    let e = measure(
        "rock-salt lattice, sphere of targets",
        &lattice,
        Some(&targets),
        &salt,
        P,
        16,
        Scheme::Dense,
    );
    eprintln!(
        "  cancellation ratio {kappa:.3e}, error / ratio {:.2e}",
        e / kappa
    );
    assert!(kappa > 100.0, "lattice does not cancel: {kappa}");
    assert!(
        e <= tol::<f64>(P) * kappa,
        "error {e:.2e}, kappa {kappa:.2e}"
    );

    // Tight dipoles (+q and -q 1e-6 apart, all along x) seen from separate
    // targets: every term is cancelled by its partner's, so the potential
    // is ~1e-6 of the terms' size (ratio 2.6e6). What matters to KIFMM is
    // cancellation between the far fields of whole boxes (each box's error
    // is relative to its own field, here itself a dipole field), and these
    // parallel dipoles' box fields hardly cancel: the error grows (7.5e-6
    // against 3e-7 for same-sign charges) but stays within the order's
    // tolerance, nowhere near tol * ratio.
    let centres: Vec<f64> = uniform(1000, 0.0, 1.0, 27);
    let dipoles: Vec<f64> = (0..2000)
        .flat_map(|i| {
            let k = i / 2;
            let dx = if i % 2 == 0 { 0.0 } else { 1e-6 };
            [centres[3 * k] + dx, centres[3 * k + 1], centres[3 * k + 2]]
        })
        .collect();
    let qd: Vec<f64> = (0..2000)
        .map(|i| if i % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    let targets: Vec<f64> = uniform(500, 0.0, 1.0, 28);
    let kappa = cancellation(&dipoles, &qd, &targets);
    let e = measure(
        "dipole pairs 1e-6 apart, separate targets",
        &dipoles,
        Some(&targets),
        &qd,
        P,
        16,
        Scheme::Dense,
    );
    eprintln!("  cancellation ratio {kappa:.3e}");
    assert!(kappa > 1e4, "dipoles do not cancel: {kappa}");
    assert!(e <= tol::<f64>(P), "error {e:.2e}");
}
