//! `TreeFmm` (the passes one at a time over a caller's tree) on the whole
//! tree equals `Fmm::evaluate` on the same points: the public pass-level
//! API a distributed driver uses runs the same passes and operators.
//! Also: the callback sees every level's check potentials, and what it
//! does to them reaches the result; wrong lengths are errors.

use ferrofmm_field::{OperatorParams, SvdConfig, SvdM2l};
use ferrofmm_fmm::{EvalTimings, FmmBuilder, FmmError, Geometry, LocalTree, TreeFmm, m2l_usage};
use ferrofmm_kernels::{EvalMode, Laplace3d};
use ferrofmm_tree::{Octree, TreeOptions};

fn setup() -> (Vec<f64>, Vec<f64>, Octree) {
    let points: Vec<f64> = Geometry::Plummer.points(3000, 4);
    let q: Vec<f64> = (0..3000)
        .map(|i| ((i * 37) % 101) as f64 / 101.0 - 0.5)
        .collect();
    let tree = Octree::new(&points, None, &TreeOptions::adaptive(40)).unwrap();
    (points, q, tree)
}

/// `TreeFmm` on the whole of `tree` (sources = targets) at `order`.
fn try_tree_fmm(
    tree: Octree,
    order: usize,
) -> Result<TreeFmm<f64, Laplace3d, SvdM2l<f64>>, FmmError> {
    let usage = m2l_usage(&tree);
    let sources = tree.sorted_sources().to_vec();
    let depth = tree.depth();
    let local = LocalTree {
        tree,
        sources: &sources,
        targets: None,
        depth,
        usage: &usage,
    };
    TreeFmm::new(
        Laplace3d,
        EvalMode::PotentialGradient,
        &OperatorParams::new(order),
        &SvdConfig::default(),
        local,
    )
}

fn tree_fmm(tree: Octree) -> TreeFmm<f64, Laplace3d, SvdM2l<f64>> {
    try_tree_fmm(tree, 5).unwrap()
}

#[test]
fn passes_one_at_a_time_equal_fmm_evaluate() {
    let (points, q, tree) = setup();
    let perm = tree.source_permutation().to_vec();
    let fmm = FmmBuilder::new(&points)
        .domain(*tree.domain())
        .order(5)
        .leaf_size(40)
        .mode(EvalMode::PotentialGradient)
        .build_svd()
        .unwrap();
    let want = fmm.evaluate(&q).unwrap();

    let t = tree_fmm(tree);
    let sorted_q: Vec<f64> = perm.iter().map(|&i| q[i]).collect();
    let mut timings = EvalTimings::default();
    let m = t.upward(&sorted_q, &mut timings).unwrap();
    let mut levels = Vec::new();
    let l = t
        .downward(&sorted_q, &m, &mut timings, |level, range, checks| {
            assert_eq!(checks.len(), t.n_surface() * range.len());
            levels.push(level);
        })
        .unwrap();
    assert_eq!(levels, (1..=t.tree().depth()).collect::<Vec<_>>());
    let got = t.leaf_passes(&sorted_q, &m, &l, &mut timings).unwrap();
    for (k, &i) in perm.iter().enumerate() {
        for c in 0..4 {
            let (g, w) = (got[4 * k + c], want[4 * i + c]);
            assert!(
                (g - w).abs() <= 1e-13 * w.abs().max(1.0),
                "point {i}: {g} vs {w}"
            );
        }
    }

    // What the callback does to the checks reaches the result.
    let l2 = t
        .downward(&sorted_q, &m, &mut timings, |_, _, checks| {
            checks.iter_mut().for_each(|x| *x *= 2.0)
        })
        .unwrap();
    assert_ne!(l, l2);
}

#[test]
fn wrong_lengths_are_errors() {
    let (_, q, tree) = setup();
    let t = tree_fmm(tree);
    let mut timings = EvalTimings::default();
    assert!(matches!(
        t.upward(&q[1..], &mut timings),
        Err(FmmError::ChargeCount { .. })
    ));
    let m = t.upward(&q, &mut timings).unwrap();
    assert!(t.downward(&q, &m[1..], &mut timings, |_, _, _| {}).is_err());
    assert!(t.leaf_passes(&q, &m, &m[1..], &mut timings).is_err());
}

#[test]
fn an_order_out_of_range_is_an_error() {
    let (_, _, tree) = setup();
    let r = try_tree_fmm(tree, 1);
    assert!(matches!(r, Err(FmmError::InvalidOrder { order: 1, .. })));
}

/// Active boxes: with every box active the passes give `Fmm`'s values
/// (the filtered UC2E, DC2E and L2L paths); with a subtree inactive its
/// boxes keep zero multipoles and locals while the active boxes' locals
/// are unchanged; a mask of the wrong length is an error.
#[test]
fn active_boxes_restrict_the_box_work() {
    let (_, q, tree) = setup();
    let perm = tree.source_permutation().to_vec();
    let sorted_q: Vec<f64> = perm.iter().map(|&i| q[i]).collect();
    let n_boxes = tree.n_boxes();
    let base = tree_fmm(tree.clone());
    let mut timings = EvalTimings::default();
    let m0 = base.upward(&sorted_q, &mut timings).unwrap();
    let l0 = base
        .downward(&sorted_q, &m0, &mut timings, |_, _, _| {})
        .unwrap();
    let v0 = base.leaf_passes(&sorted_q, &m0, &l0, &mut timings).unwrap();

    let all = tree_fmm(tree.clone())
        .with_active_boxes(vec![true; n_boxes])
        .unwrap();
    let m = all.upward(&sorted_q, &mut timings).unwrap();
    let l = all
        .downward(&sorted_q, &m, &mut timings, |_, _, _| {})
        .unwrap();
    let v = all.leaf_passes(&sorted_q, &m, &l, &mut timings).unwrap();
    // Relative difference (0 for two zero vectors: a level-1 local is zero).
    let rel = |a: &[f64], b: &[f64]| {
        let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
        let den: f64 = b.iter().map(|x| x * x).sum();
        if num == 0.0 { 0.0 } else { (num / den).sqrt() }
    };
    assert!(rel(&v, &v0) <= 1e-14, "{}", rel(&v, &v0));

    // The subtree of the root's first child with boxes below it: inactive.
    let t = all.tree();
    let n = all.n_surface();
    let first = t.level_range(1).start;
    let inactive: Vec<bool> = (0..n_boxes)
        .map(|b| {
            let mut a = Some(b);
            while let Some(x) = a {
                if x == first {
                    return true;
                }
                a = t.parent(x);
            }
            false
        })
        .collect();
    assert!(inactive.iter().filter(|&&x| x).count() > 8);
    let part = tree_fmm(tree)
        .with_active_boxes(inactive.iter().map(|&x| !x).collect())
        .unwrap();
    let m = part.upward(&sorted_q, &mut timings).unwrap();
    let l = part
        .downward(&sorted_q, &m0, &mut timings, |_, _, _| {})
        .unwrap();
    for b in 0..n_boxes {
        let (mb, lb) = (&m[n * b..n * (b + 1)], &l[n * b..n * (b + 1)]);
        if inactive[b] {
            assert!(mb.iter().chain(lb).all(|&x| x == 0.0), "box {b}");
        } else if b != 0 {
            assert!(rel(lb, &l0[n * b..n * (b + 1)]) <= 1e-14, "box {b}");
        }
    }
    let e = tree_fmm(setup().2).with_active_boxes(vec![true; 3]).err();
    assert!(matches!(e, Some(FmmError::InvalidParameter(_))), "{e:?}");
}
