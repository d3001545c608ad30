//! Degenerate point sets, the domain, and error cases.

use crate::common;

use common::*;
use ferrofmm_tree::{DEEPEST_LEVEL, Domain, Octree, PointSet, TreeError, TreeOptions};

fn build_and_check(src: &[f64], tgt: Option<&[f64]>, opts: &TreeOptions) -> Octree {
    let tree = Octree::new(src, tgt, opts).unwrap();
    check_tree(&tree, src, tgt, opts);
    check_lists(&tree);
    tree
}

#[test]
fn single_point() {
    for p in [[0.0, 0.0, 0.0], [1e6, -3.0, 2.5], [1e-300, 0.0, 0.0]] {
        let tree = build_and_check(&p, None, &TreeOptions::adaptive(1));
        assert_eq!(tree.n_boxes(), 1);
        assert_eq!(tree.leaves(), &[0]);
        assert_eq!(tree.u_list(0), &[0]);
        assert!(tree.domain().width > 0.0);
        assert!(tree.domain().contains(p));
    }
}

#[test]
fn coincident_points_stop_at_deepest_level() {
    let pts: Vec<f64> = [0.3, -0.7, 12.0].repeat(500);
    let tree = build_and_check(&pts, None, &TreeOptions::adaptive(10));
    assert_eq!(tree.depth(), DEEPEST_LEVEL);
    assert_eq!(tree.leaves().len(), 1);
    let leaf = tree.leaves()[0];
    assert_eq!(tree.source_range(leaf).len(), 500);
    // Deduplicated positions: sources sorted by original index among ties.
    assert!(tree.source_permutation().windows(2).all(|w| w[0] < w[1]));
}

#[test]
fn two_coincident_groups_and_max_level() {
    let mut pts = [0.1, 0.1, 0.1].repeat(40);
    pts.extend([0.9, 0.9, 0.9].repeat(40));
    let tree = build_and_check(&pts, None, &TreeOptions::adaptive(5));
    assert_eq!(tree.depth(), DEEPEST_LEVEL);
    let opts = TreeOptions::adaptive(5).with_max_level(4);
    let tree = build_and_check(&pts, None, &opts);
    assert_eq!(tree.depth(), 4);
    for &b in tree.leaves() {
        assert_eq!(tree.source_range(b).len(), 40);
    }
}

#[test]
fn coplanar_and_collinear() {
    let mut r = ferrofmm_testing::seeded(7);
    use rand::RngExt;
    let plane: Vec<f64> = (0..400)
        .flat_map(|_| [r.random::<f64>(), r.random::<f64>(), 0.25])
        .collect();
    build_and_check(&plane, None, &TreeOptions::adaptive(4));
    let line: Vec<f64> = (0..400)
        .flat_map(|_| {
            let t = r.random::<f64>();
            [t, 2.0 * t, -t]
        })
        .collect();
    build_and_check(&line, None, &TreeOptions::adaptive(3));
    let axis: Vec<f64> = (0..200).flat_map(|i| [0.0, 0.0, i as f64]).collect();
    build_and_check(&axis, None, &TreeOptions::adaptive(2));
}

#[test]
fn points_on_box_faces_and_corners() {
    // A lattice with spacing 1/8 on [0, 1]: every point lies on faces, edges
    // and corners of boxes of levels up to 3 of the unit-cube domain,
    // including the upper faces of the domain.
    let g: Vec<f64> = (0..=8).map(|i| i as f64 / 8.0).collect();
    let mut pts = Vec::new();
    for &x in &g {
        for &y in &g {
            for &z in &g {
                pts.extend([x, y, z]);
            }
        }
    }
    let d = Domain::new([0.0; 3], 1.0).unwrap();
    for leaf_size in [1, 4, 30] {
        let opts = TreeOptions::adaptive(leaf_size).with_domain(d);
        let tree = build_and_check(&pts, None, &opts);
        assert_eq!(tree.domain(), &d);
        // With leaf size 1 every lattice point gets its own leaf.
        if leaf_size == 1 {
            assert_eq!(tree.leaves().len(), 729);
        }
    }
    // And with a computed domain.
    build_and_check(&pts, None, &TreeOptions::adaptive(2));
}

#[test]
fn two_tiny_clusters_far_apart() {
    let mut r = ferrofmm_testing::seeded(11);
    use rand::RngExt;
    let mut pts = Vec::new();
    for (c, s) in [([0.0, 0.0, 0.0], 1e-5), ([1.0, 1.0, 1.0], 1e-4)] {
        for _ in 0..150 {
            for x in c {
                pts.push(x + s * r.random::<f64>());
            }
        }
    }
    let tree = build_and_check(&pts, None, &TreeOptions::adaptive(8));
    assert!(tree.depth() >= 16, "depth {}", tree.depth());
    // Very non-uniform: few boxes per level despite the depth.
    assert!(tree.n_boxes() < 3000, "{} boxes", tree.n_boxes());
}

#[test]
fn separate_sets_without_overlap() {
    let src = uniform(300, 1);
    let tgt: Vec<f64> = uniform(250, 2)
        .chunks(3)
        .flat_map(|c| [c[0] + 5.0, c[1], c[2] * 0.5])
        .collect();
    let tree = build_and_check(&src, Some(&tgt), &TreeOptions::adaptive(10));
    assert!(!tree.sources_are_targets());
    assert_eq!((tree.n_sources(), tree.n_targets()), (300, 250));
    // No box holds both kinds, so no U list crosses between the sets and no
    // source-only box has lists.
    for b in 0..tree.n_boxes() {
        if !tree.has_targets(b) {
            assert!(tree.u_list(b).is_empty() && tree.v_list(b).is_empty());
            assert!(tree.w_list(b).is_empty() && tree.x_list(b).is_empty());
        }
        for &a in tree
            .u_list(b)
            .iter()
            .chain(tree.v_list(b))
            .chain(tree.w_list(b))
            .chain(tree.x_list(b))
        {
            assert!(tree.has_sources(a));
        }
    }
    // One set far smaller than the other.
    build_and_check(&src[..3], Some(&tgt), &TreeOptions::adaptive(4));
    build_and_check(&src, Some(&tgt[..3]), &TreeOptions::adaptive(4));
}

#[test]
fn targets_equal_to_sources_given_twice() {
    let pts = clustered(300, 3, 3.0, 5);
    let a = Octree::new(&pts, None, &TreeOptions::adaptive(6)).unwrap();
    let b = build_and_check(&pts, Some(&pts), &TreeOptions::adaptive(6));
    assert_eq!(a.keys(), b.keys());
    for k in 0..a.n_boxes() {
        assert_eq!(a.u_list(k), b.u_list(k));
        assert_eq!(a.v_list(k), b.v_list(k));
    }
}

#[test]
fn domain_from_points() {
    // Far from the origin with tiny offsets.
    let pts: Vec<f64> = (0..100)
        .flat_map(|i| {
            let t = i as f64 * 1e-9;
            [1e6 + t, 1e6 - t, 1e6 + 0.5 * t]
        })
        .collect();
    let d = Domain::from_points(&[&pts]).unwrap();
    assert!(d.width > 0.0 && d.width < 1e-6, "width {}", d.width);
    for c in pts.chunks(3) {
        let p = [c[0], c[1], c[2]];
        assert!((0..3).all(|i| p[i] >= d.origin[i] && p[i] < d.origin[i] + d.width));
    }
    build_and_check(&pts, None, &TreeOptions::adaptive(3));

    // Tiny extent.
    let tiny: Vec<f64> = [0.0, 0.0, 0.0, 1e-8, 1e-8, 1e-8, 5e-9, 0.0, 1e-8].to_vec();
    let d = Domain::from_points(&[&tiny]).unwrap();
    assert!(d.width >= 1e-8 && d.width < 1.1e-8);
    build_and_check(&tiny, None, &TreeOptions::adaptive(1));

    // Points on the upper faces fall strictly inside; several sets.
    let a = [0.0, 0.0, 0.0];
    let b = [1.0, 2.0, 3.0];
    let d = Domain::from_points(&[&a, &[], &b]).unwrap();
    for i in 0..3 {
        assert!(b[i] < d.origin[i] + d.width && a[i] >= d.origin[i]);
    }
    assert!(d.width >= 3.0 && d.width < 3.0001);

    // Zero extent away from the origin.
    let d = Domain::from_points(&[&[1e6, 1e6, 1e6]]).unwrap();
    assert!(d.width > 0.0 && d.contains([1e6; 3]));
}

#[test]
fn errors() {
    let ok = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0];
    let opts = TreeOptions::adaptive(4);
    assert!(matches!(
        Octree::new(&ok[..5], None, &opts),
        Err(TreeError::BadLength {
            set: PointSet::Sources,
            len: 5
        })
    ));
    assert!(matches!(
        Octree::new(&ok, Some(&ok[..4]), &opts),
        Err(TreeError::BadLength {
            set: PointSet::Targets,
            len: 4
        })
    ));
    let nan = [0.0, 0.0, 0.0, 1.0, f64::NAN, 1.0];
    assert!(matches!(
        Octree::new(&nan, None, &opts),
        Err(TreeError::NonFinite {
            set: PointSet::Sources,
            index: 1,
            ..
        })
    ));
    let inf = [f64::INFINITY, 0.0, 0.0];
    assert!(matches!(
        Octree::new(&ok, Some(&inf), &opts),
        Err(TreeError::NonFinite {
            set: PointSet::Targets,
            index: 0,
            ..
        })
    ));
    assert!(matches!(
        Octree::new(&[], None, &opts),
        Err(TreeError::Empty {
            set: PointSet::Sources
        })
    ));
    assert!(matches!(
        Octree::new(&ok, Some(&[]), &opts),
        Err(TreeError::Empty {
            set: PointSet::Targets
        })
    ));
    assert!(matches!(
        Octree::new(&ok, None, &TreeOptions::adaptive(0)),
        Err(TreeError::ZeroLeafSize)
    ));
    assert!(matches!(
        Octree::new(&ok, None, &TreeOptions::adaptive(4).with_max_level(20)),
        Err(TreeError::LevelTooDeep { level: 20 })
    ));
    assert!(matches!(
        Octree::new(&ok, None, &TreeOptions::uniform(25)),
        Err(TreeError::LevelTooDeep { level: 25 })
    ));
    let small = Domain::new([0.0; 3], 0.5).unwrap();
    assert!(matches!(
        Octree::new(&ok, None, &opts.clone().with_domain(small)),
        Err(TreeError::OutsideDomain {
            set: PointSet::Sources,
            index: 1,
            ..
        })
    ));
    let bad_domain = TreeOptions {
        domain: Some(Domain {
            origin: [0.0; 3],
            width: -1.0,
        }),
        ..TreeOptions::default()
    };
    assert!(matches!(
        Octree::new(&ok, None, &bad_domain),
        Err(TreeError::InvalidDomain { .. })
    ));
    // Domain constructors.
    assert!(Domain::new([0.0; 3], 0.0).is_err());
    assert!(Domain::new([0.0; 3], f64::NAN).is_err());
    assert!(Domain::new([f64::INFINITY, 0.0, 0.0], 1.0).is_err());
    assert!(Domain::new([1e20, 0.0, 0.0], 1e-10).is_err()); // below resolution
    assert!(matches!(Domain::from_points(&[]), Err(TreeError::NoPoints)));
    assert!(matches!(
        Domain::from_points(&[&[], &[]]),
        Err(TreeError::NoPoints)
    ));
    assert!(matches!(
        Domain::from_points(&[&ok, &[1.0, 2.0]]),
        Err(TreeError::BadLength {
            set: PointSet::Set(1),
            len: 2
        })
    ));
    assert!(matches!(
        Domain::from_points(&[&[-1e308, 0.0, 0.0, 1e308, 0.0, 0.0]]),
        Err(TreeError::InvalidDomain { .. })
    ));
    // Errors print something useful.
    let e = Octree::new(&nan, None, &opts).unwrap_err();
    assert!(e.to_string().contains("sources: point 1"), "{e}");
}

/// `balance: false` keeps the plain refinement: the same leaves as the
/// balanced tree minus the ones balance split, leaves of adjacent levels
/// that differ by more than one, and no interaction lists.
#[test]
fn unbalanced_tree_is_the_plain_refinement() {
    // A tight cluster in one corner of a sparse cloud forces balance to act.
    let mut pts = uniform(200, 3);
    let tight = uniform(2000, 4);
    pts.extend(tight.iter().map(|x| 0.01 + 1e-4 * x));
    let plain = TreeOptions::adaptive(8).with_balance(false);
    let tree = Octree::new(&pts, None, &plain).unwrap();
    check_tree(&tree, &pts, None, &plain);
    assert!(!tree.has_lists());
    for b in 0..tree.n_boxes() {
        for list in [
            tree.u_list(b),
            tree.v_list(b),
            tree.w_list(b),
            tree.x_list(b),
        ] {
            assert!(list.is_empty());
        }
    }
    let keys = tree.keys();
    let leaves = tree.leaves();
    let jump = leaves.iter().any(|&a| {
        leaves
            .iter()
            .any(|&b| keys[a].is_adjacent(keys[b]) && keys[a].level().abs_diff(keys[b].level()) > 1)
    });
    assert!(jump, "this input must need balancing");

    let balanced = Octree::new(&pts, None, &TreeOptions::adaptive(8)).unwrap();
    assert!(balanced.has_lists());
    assert!(balanced.n_boxes() > tree.n_boxes());
    // Every box of the plain refinement is in the balanced tree.
    for &k in keys {
        assert!(balanced.index_of(k).is_some(), "{k} lost by balancing");
    }
}
