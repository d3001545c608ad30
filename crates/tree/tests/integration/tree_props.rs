//! Property tests of tree structure, balance and interaction lists on small
//! random adaptive trees (clustered points, planes, lines, separate target
//! sets).

use crate::common;

use common::*;
use ferrofmm_tree::{Octree, TreeOptions};
use proptest::prelude::*;

fn options(leaf_size: usize, max_level: u32) -> TreeOptions {
    TreeOptions::adaptive(leaf_size).with_max_level(max_level)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Structure, points, balance, brute-force lists and exact-once coverage
    /// with sources = targets.
    #[test]
    fn adaptive_tree_same_sets(
        n in 1usize..300,
        clusters in 1usize..5,
        max_exp in 0.5f64..5.0,
        leaf_size in 1usize..12,
        max_level in 3u32..=19,
        seed in any::<u64>(),
    ) {
        let pts = clustered(n, clusters, max_exp, seed);
        let opts = options(leaf_size, max_level);
        let tree = Octree::new(&pts, None, &opts).unwrap();
        check_tree(&tree, &pts, None, &opts);
        check_lists(&tree);
    }

    /// The same with separate source and target sets (overlapping or not).
    #[test]
    fn adaptive_tree_separate_sets(
        ns in 1usize..200,
        nt in 1usize..200,
        clusters in 1usize..4,
        max_exp in 0.5f64..4.0,
        leaf_size in 1usize..10,
        shift in prop_oneof![Just(0.0), 0.0f64..3.0],
        seed in any::<u64>(),
    ) {
        let src = clustered(ns, clusters, max_exp, seed);
        let mut tgt = clustered(nt, clusters, max_exp, seed ^ 0x5eed);
        for c in tgt.chunks_mut(3) {
            c[0] += shift;
        }
        let opts = TreeOptions::adaptive(leaf_size);
        let tree = Octree::new(&src, Some(&tgt), &opts).unwrap();
        check_tree(&tree, &src, Some(&tgt), &opts);
        check_lists(&tree);
    }

    /// Uniform trees: every leaf at the requested depth, lists still exact.
    #[test]
    fn uniform_tree(n in 1usize..300, depth in 0u32..5, seed in any::<u64>()) {
        let pts = clustered(n, 3, 2.0, seed);
        let opts = TreeOptions::uniform(depth);
        let tree = Octree::new(&pts, None, &opts).unwrap();
        prop_assert_eq!(tree.depth(), depth);
        check_tree(&tree, &pts, None, &opts);
        check_lists(&tree);
        for b in 0..tree.n_boxes() {
            prop_assert!(tree.w_list(b).is_empty() && tree.x_list(b).is_empty());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    /// List-size bounds on larger clustered trees (no brute force).
    #[test]
    fn list_size_bounds(
        n in 1000usize..6000,
        clusters in 1usize..6,
        leaf_size in 1usize..40,
        seed in any::<u64>(),
    ) {
        let pts = clustered(n, clusters, 4.0, seed);
        let tree = Octree::new(&pts, None, &TreeOptions::adaptive(leaf_size)).unwrap();
        check_balance(&tree);
        let [u, v, w, x] = max_sizes(&tree);
        prop_assert!(u <= 57, "U = {}", u);
        prop_assert!(v <= 189, "V = {}", v);
        prop_assert!(w <= 152, "W = {}", w);
        prop_assert!(x <= 19, "X = {}", x);
    }
}
