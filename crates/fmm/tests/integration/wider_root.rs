//! Roots wider than the points' bounding cube (issue 36,
//! `tuning::choose_root`): the run chosen on a wider root meets its
//! tolerance against direct summation like any other, on zero-mean and
//! positive charges and on a thin set, and agrees with the bounding
//! cube's run.

use ferrofmm_fmm::{Charges, FmmBuilder, Geometry, relative_errors, sample_indices};
use ferrofmm_kernels::{EvalMode, Laplace3d};
use ferrofmm_tree::Domain;

const GRAD: EvalMode = EvalMode::PotentialGradient;
const EPS: f64 = 1e-6;

fn worst_error(points: &[f64], q: &[f64], values: &[f64]) -> f64 {
    relative_errors(
        &Laplace3d,
        GRAD,
        points,
        q,
        points,
        values,
        &sample_indices(points.len() / 3, 300),
    )
    .worst()
}

fn build(
    points: &[f64],
    search: bool,
) -> ferrofmm_fmm::Fmm<f64, Laplace3d, ferrofmm_field::FftM2l<f64>> {
    FmmBuilder::new(points)
        .mode(GRAD)
        .tolerance(EPS)
        .root_search(search)
        .build_with::<ferrofmm_field::FftM2l<f64>>(Default::default())
        .unwrap()
}

#[test]
fn a_cube_between_two_depths_runs_on_a_wider_root_and_meets_its_tolerance() {
    // 2.5e5 points: leaves of 61 or 488 on the bounding cube, 122 or 244
    // on the wider roots.
    let n = 250_000;
    let points: Vec<f64> = Geometry::Cube.points(n, 11);
    let tight = Domain::from_points(&[&points]).unwrap();
    let mut wide = build(&points, true);
    let chosen = wide.chosen_parameters().unwrap().clone();
    assert!(chosen.root_scale > 1.0, "{chosen:?}");
    let d = *wide.tree().domain();
    assert_eq!(d.origin, tight.origin);
    assert!((d.width / tight.width - chosen.root_scale).abs() < 1e-12);
    let mut cube = build(&points, false);
    assert_eq!(cube.chosen_parameters().unwrap().root_scale, 1.0);
    assert_eq!(cube.tree().domain(), &tight);
    for charges in [Charges::Signed, Charges::Positive] {
        let q = charges.generate(n, 12);
        let out = wide.evaluate_verified(&q).unwrap();
        assert!(out.verification.expect("verified").met);
        let e = worst_error(&points, &q, &out.values);
        assert!(e <= EPS, "{charges:?}: {e:e} on the wider root");
        // Both runs are within the tolerance of the truth, so of each other.
        let other = cube.evaluate_verified(&q).unwrap().values;
        let norm = other.iter().map(|v| v * v).sum::<f64>().sqrt();
        let diff = out
            .values
            .iter()
            .zip(&other)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        assert!(diff <= 2.0 * EPS * norm, "{charges:?}: {:e}", diff / norm);
    }
}

#[test]
fn a_thin_set_meets_its_tolerance_whatever_root_it_gets() {
    let n = 120_000;
    for geometry in [Geometry::Plane, Geometry::Plummer] {
        let points: Vec<f64> = geometry.points(n, 13);
        let mut fmm = build(&points, true);
        let q = Charges::Signed.generate(n, 14);
        let out = fmm.evaluate_verified(&q).unwrap();
        assert!(out.verification.expect("verified").met);
        let e = worst_error(&points, &q, &out.values);
        assert!(e <= EPS, "{geometry:?}: {e:e}");
        let chosen = fmm.chosen_parameters().unwrap();
        assert!(ferrofmm_fmm::tuning::ROOT_SCALES.contains(&chosen.root_scale));
    }
}
