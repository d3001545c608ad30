//! Slabs (periodic in `x` and `y`) and rods (periodic in `x`) for the
//! Laplace and Yukawa kernels (issue 32): random boxes against the
//! library's pairwise slab and rod sums at several orders and a verified
//! tolerance, Madelung constants of a square lattice and a chain,
//! invariance under lattice shifts and moves across a face, the
//! free-space limit, and refusals.

use super::periodic::{random_box, split_errors as errors};
use ferrofmm_field::FftM2l;
use ferrofmm_fmm::{FmmBuilder, FmmError, Periodic, PeriodicAxes, SurfaceTerm};
use ferrofmm_kernels::{
    EvalMode, INV_4PI, Laplace3d, ModifiedHelmholtz3d, PeriodicCell, RodGreen, SlabGreen, Stokes3d,
};

/// The pairwise slab or rod sum of `q` at every source, potential and
/// gradient.
fn reference(points: &[f64], q: &[f64], cell: Periodic, kappa: f64) -> Vec<f64> {
    let c = PeriodicCell::new(cell.origin(), cell.lengths()).unwrap();
    let all: Vec<usize> = (0..q.len()).collect();
    let mode = EvalMode::PotentialGradient;
    match cell.axes() {
        PeriodicAxes::Xy => SlabGreen::screened(c, kappa, 1e-15)
            .unwrap()
            .sum_at_sources(points, q, &all, mode),
        _ => RodGreen::screened(c, kappa, 1e-15)
            .unwrap()
            .sum_at_sources(points, q, &all, mode),
    }
    .unwrap()
}

fn run_laplace(points: &[f64], q: &[f64], cell: Periodic, order: usize) -> Vec<f64> {
    FmmBuilder::new(points)
        .cache_dir(crate::ops_cache())
        .periodic(cell)
        .mode(EvalMode::PotentialGradient)
        .order(order)
        .leaf_size(24)
        .build_with::<FftM2l<f64>>(Default::default())
        .unwrap()
        .evaluate(q)
        .unwrap()
}

fn run_yukawa(points: &[f64], q: &[f64], cell: Periodic, kappa: f64, order: usize) -> Vec<f64> {
    FmmBuilder::new(points)
        .kernel(ModifiedHelmholtz3d::new(kappa).unwrap())
        .periodic(cell)
        .mode(EvalMode::PotentialGradient)
        .order(order)
        .leaf_size(24)
        .build_with::<FftM2l<f64>>(Default::default())
        .unwrap()
        .evaluate(q)
        .unwrap()
}

/// Uniform and clustered (a ball straddling the `x = origin` face) boxes,
/// zero-mean charges for Laplace, positive ones for Yukawa: the error falls
/// with the order and follows the free-space rule of thumb.
#[test]
fn random_boxes_against_pairwise_sums() {
    for axes in [PeriodicAxes::Xy, PeriodicAxes::X] {
        for (clustered, origin) in [(false, [0.0; 3]), (true, [-3.0, 1.0, 1e3])] {
            let (points, zero_mean) = random_box(500, 2.0, origin, clustered, 11);
            let cell = Periodic::cube(2.0).with_origin(origin).with_axes(axes);
            let positive: Vec<f64> = zero_mean.iter().map(|q| q + 0.5).collect();
            let laplace_truth = reference(&points, &zero_mean, cell, 0.0);
            let yukawa_truth = reference(&points, &positive, cell, 1.5);
            let mut last = [f64::INFINITY; 2];
            for order in [4, 8] {
                let bound = 10f64.powi(2 - order as i32);
                let (ep, eg) = errors(
                    &run_laplace(&points, &zero_mean, cell, order),
                    &laplace_truth,
                );
                assert!(
                    ep <= bound && eg <= 10.0 * bound,
                    "{axes} Laplace p {order}: {ep:e} {eg:e}"
                );
                let (yp, yg) = errors(
                    &run_yukawa(&points, &positive, cell, 1.5, order),
                    &yukawa_truth,
                );
                assert!(
                    yp <= bound && yg <= 10.0 * bound,
                    "{axes} Yukawa p {order}: {yp:e} {yg:e}"
                );
                assert!(ep < last[0] && yp < last[1], "{axes}: the error falls");
                last = [ep, yp];
            }
        }
    }
}

/// A tolerance is chosen and verified against the pairwise sum, and met.
#[test]
fn a_tolerance_is_met_and_verified() {
    for axes in [PeriodicAxes::Xy, PeriodicAxes::X] {
        let (points, q) = random_box(1500, 1.0, [0.0; 3], false, 12);
        let cell = Periodic::cube(1.0).with_axes(axes);
        let truth = reference(&points, &q, cell, 0.0);
        for eps in [1e-4, 1e-8] {
            let mut fmm = FmmBuilder::new(&points)
                .cache_dir(crate::ops_cache())
                .periodic(cell)
                .mode(EvalMode::PotentialGradient)
                .tolerance(eps)
                .build_with::<FftM2l<f64>>(Default::default())
                .unwrap();
            let out = fmm.evaluate_verified(&q).unwrap();
            let (ep, eg) = errors(&out.values, &truth);
            assert!(ep.max(eg) <= eps, "{axes} eps {eps:e}: {ep:e} {eg:e}");
            let v = out.verification.expect("verified");
            assert!(v.met, "{axes} eps {eps:e}: {:?}", v.measured());
        }
    }
}

/// The square lattice of alternating charges (a slab of one layer) and
/// the alternating chain (a rod), through the FMM at order 10.
#[test]
fn madelung_constants_of_a_layer_and_a_chain() {
    const SQUARE: f64 = 1.615_542_626_712_824_7;
    let layer = [0.0, 0.0, 0.3, 0.5, 0.0, 0.3, 0.0, 0.5, 0.3, 0.5, 0.5, 0.3];
    let chain = [0.0, 0.2, 0.6, 0.5, 0.2, 0.6];
    for (points, q, axes, want) in [
        (
            &layer[..],
            &[1.0, -1.0, -1.0, 1.0][..],
            PeriodicAxes::Xy,
            SQUARE,
        ),
        (
            &chain[..],
            &[1.0, -1.0][..],
            PeriodicAxes::X,
            2.0 * 2f64.ln(),
        ),
    ] {
        let phi = FmmBuilder::new(points)
            .cache_dir(crate::ops_cache())
            .periodic(Periodic::cube(1.0).with_axes(axes))
            .mode(EvalMode::Potential)
            .order(10)
            .leaf_size(4)
            .build_with::<FftM2l<f64>>(Default::default())
            .unwrap()
            .evaluate(q)
            .unwrap();
        let m = -phi[0] / INV_4PI * 0.5;
        assert!((m - want).abs() < 1e-8 * want, "{axes}: {m} against {want}");
    }
}

/// Shifting every point by a lattice vector (along the repeating axes), or
/// moving one across a periodic face, changes nothing.
#[test]
fn invariant_under_lattice_shifts() {
    for (axes, shift) in [
        (PeriodicAxes::Xy, [1.0, -2.0, 0.0]),
        (PeriodicAxes::X, [-3.0, 0.0, 0.0]),
    ] {
        let (points, q) = random_box(400, 1.0, [0.0; 3], false, 13);
        let cell = Periodic::cube(1.0).with_axes(axes);
        let base = run_laplace(&points, &q, cell, 6);
        let shifted: Vec<f64> = points
            .chunks_exact(3)
            .flat_map(|p| [p[0] + shift[0], p[1] + shift[1], p[2] + shift[2]])
            .collect();
        let mut moved = points.clone();
        moved[0] -= 1.0;
        for other in [shifted, moved] {
            let out = run_laplace(&other, &q, cell, 6);
            let (ep, eg) = errors(&out, &base);
            assert!(ep < 1e-12 && eg < 1e-12, "{axes}: {ep:e} {eg:e}");
        }
    }
}

/// A tight neutral cluster in a huge slab or rod is free space, to the
/// size of its images' fields.
#[test]
fn a_tight_cluster_in_a_huge_cell_is_free_space() {
    let (points, q) = random_box(300, 1.0, [0.0; 3], true, 14);
    for axes in [PeriodicAxes::Xy, PeriodicAxes::X] {
        let cell = Periodic::cube(1e4).with_origin([-5e3; 3]).with_axes(axes);
        let periodic = run_laplace(&points, &q, cell, 8);
        let free = FmmBuilder::new(&points)
            .mode(EvalMode::PotentialGradient)
            .order(8)
            .leaf_size(24)
            .build_svd()
            .unwrap()
            .evaluate(&q)
            .unwrap();
        let (ep, eg) = errors(&periodic, &free);
        assert!(ep < 1e-5 && eg < 1e-5, "{axes}: {ep:e} {eg:e}");
    }
}

#[test]
fn slabs_and_rods_refuse_what_they_cannot_sum() {
    let (points, q) = random_box(200, 1.0, [0.0; 3], false, 15);
    let slab = Periodic::cube(1.0).with_axes(PeriodicAxes::Xy);
    // A point outside the cell along the open axis.
    let mut outside = points.clone();
    outside[2] = 1.5;
    let Err(err) = FmmBuilder::new(&outside)
        .cache_dir(crate::ops_cache())
        .periodic(slab)
        .order(4)
        .build_svd()
    else {
        panic!("a point outside the slab was accepted");
    };
    assert!(
        matches!(&err, FmmError::InvalidParameter(m) if m.contains("open axis")),
        "{err}"
    );
    // Stokes, the vacuum term, and a charged Laplace cell.
    assert!(
        FmmBuilder::new(&points)
            .kernel(Stokes3d::new(1.0).unwrap())
            .periodic(slab)
            .order(4)
            .build_svd()
            .is_err()
    );
    assert!(
        FmmBuilder::new(&points)
            .cache_dir(crate::ops_cache())
            .periodic(slab.with_surface(SurfaceTerm::Vacuum))
            .order(4)
            .build_svd()
            .is_err()
    );
    let fmm = FmmBuilder::new(&points)
        .kernel(Laplace3d)
        .periodic(Periodic::cube(1.0).with_axes(PeriodicAxes::X))
        .order(4)
        .build_svd()
        .unwrap();
    let charged: Vec<f64> = q.iter().map(|q| q + 1.0).collect();
    assert!(matches!(
        fmm.evaluate(&charged),
        Err(FmmError::NotNeutral { .. })
    ));
}

/// The periodisation operator is kept in the operator cache: one file for
/// the cell, read back by a second run with the same values bit for bit.
#[test]
fn the_periodisation_operator_is_cached() {
    let dir = ferrofmm_testing::TempDir::new("periodisation");
    let (points, q) = random_box(300, 1.0, [0.0; 3], false, 16);
    let cell = Periodic::cube(1.0).with_axes(PeriodicAxes::Xy);
    let run = || {
        FmmBuilder::new(&points)
            .cache_dir(crate::ops_cache())
            .periodic(cell)
            .order(6)
            .leaf_size(24)
            .cache_dir(dir.path())
            .build_with::<FftM2l<f64>>(Default::default())
            .unwrap()
            .evaluate(&q)
            .unwrap()
    };
    let first = run();
    let entries = || -> Vec<String> {
        std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with("periodisation"))
            .collect()
    };
    assert_eq!(entries().len(), 1, "{:?}", entries());
    assert_eq!(run(), first);
    assert_eq!(entries().len(), 1);
}
