//! Nothing modelled that the scene does not need: memory grows with the
//! occupied boxes, not with the depth of the tree.
//!
//! Two clusters 1000x apart in size need a tree about 17 levels deep, where
//! a full octree would have `8^17 ~ 2e15` boxes; uniform points of the same
//! N need 4 or 5 levels. Both must hold about the same number of boxes and
//! the same expansion storage.

use ferrofmm_field::SvdM2l;
use ferrofmm_fmm::{Charges, Fmm, FmmBuilder, Geometry};
use ferrofmm_kernels::Laplace3d;

const N: usize = 100_000;
const LEAF: usize = 64;
const ORDER: usize = 4;

fn build(g: Geometry) -> Fmm<f64, Laplace3d, SvdM2l<f64>> {
    let points: Vec<f64> = g.points(N, 5);
    FmmBuilder::new(&points)
        .order(ORDER)
        .leaf_size(LEAF)
        .build_svd()
        .unwrap()
}

#[test]
fn expansion_storage_is_proportional_to_occupied_boxes() {
    let uniform = build(Geometry::Cube);
    let clusters = build(Geometry::TwoClusters);
    let n = ferrofmm_field::n_surface_points(ORDER);
    for (name, fmm) in [("uniform", &uniform), ("two clusters", &clusters)] {
        let s = fmm.summary();
        let m = fmm.memory();
        eprintln!(
            "{name}: depth {} boxes {} leaves {} memory {m:?}",
            s.depth, s.n_boxes, s.n_leaves
        );
        // The accounting: n values per existing box for multipoles and locals.
        assert_eq!(m.n_boxes, s.n_boxes);
        assert_eq!(m.expansions, 2 * n * s.n_boxes * size_of::<f64>());
        assert_eq!(s.memory, m);
        assert_eq!(fmm.memory_bytes(), m.total);
        // Boxes are bounded by the points, not by the depth: every leaf
        // holds a point, and a box splits only when it holds more than LEAF
        // (balancing adds at most a few).
        assert!(s.n_boxes <= 16 * N / LEAF, "{name}: {} boxes", s.n_boxes);
        let full_tree = 8f64.powi(s.depth as i32);
        assert!((s.n_boxes as f64) < 1e-3 * full_tree || s.depth <= 5);
        // Every level holds at most as many boxes as points.
        for level in 0..=s.depth {
            assert!(fmm.tree().level_range(level).len() <= N);
        }
    }
    let (u, c) = (uniform.summary(), clusters.summary());
    assert!(
        c.depth >= u.depth + 10,
        "depths {} and {}",
        c.depth,
        u.depth
    );
    // Same N, same leaf size: the same order of boxes and bytes, although
    // the two-cluster tree is over ten levels deeper.
    let ratio = c.n_boxes as f64 / u.n_boxes as f64;
    assert!((0.3..=3.0).contains(&ratio), "box ratio {ratio}");
    let bytes = clusters.memory().total as f64 / uniform.memory().total as f64;
    assert!((0.3..=3.0).contains(&bytes), "memory ratio {bytes}");
}

#[test]
fn evaluation_works_with_the_accounted_buffers() {
    // The accounting matches the buffers the passes use: one evaluation of
    // the deep tree succeeds and its expansions are n values per box.
    let fmm = build(Geometry::TwoClusters);
    // Positive charges: every potential is positive.
    let q: Vec<f64> = Charges::Positive.generate(N, 1);
    let v = fmm.evaluate(&q).unwrap();
    assert_eq!(v.len(), N);
    assert!(v.iter().all(|x| x.is_finite() && *x > 0.0));
    let m = fmm.memory();
    assert!(m.expansions > 0 && m.expansions < m.total);
    assert!(m.tree > 0 && m.points >= N * 3 * size_of::<f64>());
}
