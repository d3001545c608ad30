//! List-size bounds: constructions that attain the worst cases, and the
//! maxima seen on larger random trees.
//!
//! Bounds for the 2:1 balance enforced here (see the `lists` module docs):
//! |U| <= 57, |V| <= 189, |W| <= 152, |X| <= 19. The often quoted W <= 148
//! does not hold for the standard W definition: a leaf whose 26 colleagues
//! are all split into 8 children has 6*4 + 12*6 + 8*7 = 152 W entries, and
//! that tree is balanced (the construction below).

use crate::common;

use common::*;
use ferrofmm_tree::{Domain, MortonKey, Octree, TreeOptions};

const UNIT: Domain = Domain {
    origin: [0.0; 3],
    width: 1.0,
};

fn centre(cell: [u32; 3], level: u32) -> [f64; 3] {
    let w = 1.0 / (1u32 << level) as f64;
    cell.map(|c| (c as f64 + 0.5) * w)
}

fn child_centres(cell: [u32; 3], level: u32) -> Vec<f64> {
    let mut out = Vec::new();
    for o in 0..8u32 {
        let c = [
            2 * cell[0] + (o & 1),
            2 * cell[1] + (o >> 1 & 1),
            2 * cell[2] + (o >> 2 & 1),
        ];
        out.extend(centre(c, level + 1));
    }
    out
}

fn key_of(cell: [u32; 3], level: u32) -> MortonKey {
    MortonKey::from_point(centre(cell, level), &UNIT, level)
}

/// A leaf whose 26 colleagues are all split into 8 leaves: |U| = 57 and
/// |W| = 152.
#[test]
fn u_and_w_worst_case() {
    let mut pts = Vec::new();
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..3 {
                if [i, j, k] == [1, 1, 1] {
                    pts.extend(centre([1, 1, 1], 2));
                } else {
                    pts.extend(child_centres([i, j, k], 2));
                }
            }
        }
    }
    let opts = TreeOptions::adaptive(1).with_domain(UNIT);
    let tree = Octree::new(&pts, None, &opts).unwrap();
    check_tree(&tree, &pts, None, &opts);
    check_lists(&tree);
    let b = tree.index_of(key_of([1, 1, 1], 2)).unwrap();
    assert!(tree.is_leaf(b));
    assert_eq!(tree.u_list(b).len(), 57);
    assert_eq!(tree.w_list(b).len(), 152);
    assert_eq!(max_sizes(&tree)[0], 57);
    assert_eq!(max_sizes(&tree)[2], 152);
}

/// A split box whose 26 neighbours are leaves: its corner children have
/// |X| = 19.
#[test]
fn x_worst_case() {
    let mut pts = Vec::new();
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..3 {
                if [i, j, k] == [1, 1, 1] {
                    pts.extend(centre([2, 2, 2], 3));
                    pts.extend(centre([3, 3, 3], 3));
                } else {
                    pts.extend(centre([i, j, k], 2));
                }
            }
        }
    }
    let opts = TreeOptions::adaptive(1).with_domain(UNIT);
    let tree = Octree::new(&pts, None, &opts).unwrap();
    check_tree(&tree, &pts, None, &opts);
    check_lists(&tree);
    let b = tree.index_of(key_of([2, 2, 2], 3)).unwrap();
    assert_eq!(tree.x_list(b).len(), 19);
    assert_eq!(max_sizes(&tree)[3], 19);
}

/// Interior box of a full uniform tree: |V| = 189.
#[test]
fn v_worst_case() {
    let mut pts = Vec::new();
    for i in 0..8 {
        for j in 0..8 {
            for k in 0..8 {
                pts.extend(centre([i, j, k], 3));
            }
        }
    }
    let opts = TreeOptions::uniform(3).with_domain(UNIT);
    let tree = Octree::new(&pts, None, &opts).unwrap();
    check_tree(&tree, &pts, None, &opts);
    check_lists(&tree);
    let b = tree.index_of(key_of([2, 2, 2], 3)).unwrap();
    assert_eq!(tree.v_list(b).len(), 189);
    assert_eq!(max_sizes(&tree)[1], 189);
    // 27 adjacent-or-self leaves in a full uniform tree.
    assert_eq!(tree.u_list(b).len(), 27);
}

/// Maxima on larger random trees (printed; run with `--nocapture`).
#[test]
fn measured_maxima() {
    let mut max = [0usize; 4];
    for seed in 0..6u64 {
        let pts = if seed % 2 == 0 {
            clustered(20_000, 1 + seed as usize, 4.0, seed)
        } else {
            uniform(20_000, seed)
        };
        for leaf_size in [8, 40] {
            let tree = Octree::new(&pts, None, &TreeOptions::adaptive(leaf_size)).unwrap();
            let m = max_sizes(&tree);
            for i in 0..4 {
                max[i] = max[i].max(m[i]);
            }
        }
    }
    eprintln!(
        "max list sizes on random trees: U {} V {} W {} X {}",
        max[0], max[1], max[2], max[3]
    );
    assert!(max[0] <= 57 && max[1] <= 189 && max[2] <= 152 && max[3] <= 19);
}
