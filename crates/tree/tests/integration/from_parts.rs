//! `Octree::from_parts`: a tree rebuilt from another's keys, ranges and
//! lists is the same tree; parts that do not form a tree are
//! `TreeError::InvalidParts`, never a panic.

use std::ops::Range;

use ferrofmm_tree::{Csr, InteractionLists, MortonKey, Octree, TreeError, TreeOptions};

type Parts = Vec<(MortonKey, Range<usize>, Range<usize>)>;

fn parts() -> (Octree, Parts) {
    let pts: Vec<f64> = (0..2400).map(|i| (i as f64 * 0.618_034).fract()).collect();
    let tree = Octree::new(&pts, None, &TreeOptions::adaptive(12)).unwrap();
    let boxes = (0..tree.n_boxes())
        .map(|b| (tree.key(b), tree.source_range(b), tree.target_range(b)))
        .collect();
    (tree, boxes)
}

#[test]
fn a_tree_from_its_own_parts_is_the_same_tree() {
    let (tree, boxes) = parts();
    let copy =
        Octree::from_parts(*tree.domain(), &boxes, tree.interaction_lists().clone()).unwrap();
    assert_eq!(copy.keys(), tree.keys());
    assert_eq!(copy.leaves(), tree.leaves());
    for b in 0..tree.n_boxes() {
        assert_eq!(copy.parent(b), tree.parent(b));
        assert_eq!(copy.children(b), tree.children(b));
        assert_eq!(copy.source_range(b), tree.source_range(b));
        assert_eq!(copy.u_list(b), tree.u_list(b));
        assert_eq!(copy.x_list(b), tree.x_list(b));
    }
    assert_eq!(copy.n_sources(), 0);
}

#[test]
fn parts_that_are_not_a_tree_are_errors() {
    let (tree, boxes) = parts();
    let lists = || tree.interaction_lists().clone();
    let d = *tree.domain();
    let bad = |r: Result<Octree, TreeError>| matches!(r, Err(TreeError::InvalidParts { .. }));
    assert!(bad(Octree::from_parts(d, &[], lists())));
    assert!(bad(Octree::from_parts(d, &boxes[1..], lists())));
    let mut swapped = boxes.clone();
    let n = swapped.len();
    swapped.swap(n - 1, n - 2);
    assert!(bad(Octree::from_parts(d, &swapped, lists())));
    // A box whose parent is missing: drop an internal box of level 1.
    let internal = (1..tree.n_boxes())
        .find(|&b| tree.level(b) == 1 && !tree.is_leaf(b))
        .unwrap();
    let mut orphaned = boxes.clone();
    orphaned.remove(internal);
    let rows = vec![Vec::new(); orphaned.len()];
    let empty = InteractionLists {
        u: Csr::from_rows(&rows),
        v: Csr::from_rows(&rows),
        w: Csr::from_rows(&rows),
        x: Csr::from_rows(&rows),
    };
    assert!(bad(Octree::from_parts(d, &orphaned, empty)));
    let mut reversed = boxes.clone();
    reversed[3].1 = Range { start: 5, end: 2 };
    assert!(bad(Octree::from_parts(d, &reversed, lists())));
    // Lists with a row too few, or an entry out of range.
    let mut short = lists();
    short.v = Csr::from_rows(&vec![Vec::new(); n - 1]);
    assert!(bad(Octree::from_parts(d, &boxes, short)));
    let mut far = lists();
    let mut rows = vec![Vec::new(); n];
    rows[0] = vec![n];
    far.u = Csr::from_rows(&rows);
    assert!(bad(Octree::from_parts(d, &boxes, far)));
}
