//! Shared helpers: point generators, a full invariant check of a tree, and
//! brute-force interaction lists.
#![allow(dead_code, clippy::needless_range_loop)]

use std::collections::HashMap;

use ferrofmm_tree::{DEEPEST_LEVEL, MortonKey, Octree, TreeOptions};

pub use ferrofmm_testing::points::clustered;

/// `n` points uniform in the unit cube.
pub fn uniform(n: usize, seed: u64) -> Vec<f64> {
    ferrofmm_testing::points::uniform_cube(n, 0.0, 1.0, seed)
}

pub fn point(p: &[f64], i: usize) -> [f64; 3] {
    [p[3 * i], p[3 * i + 1], p[3 * i + 2]]
}

fn set_size(tree: &Octree, b: usize) -> usize {
    tree.source_range(b).len().max(tree.target_range(b).len())
}

/// Checks every structural invariant of `tree` built from `src` / `tgt` with
/// `opts`. Panics with a message on the first violation.
pub fn check_tree(tree: &Octree, src: &[f64], tgt: Option<&[f64]>, opts: &TreeOptions) {
    let n = tree.n_boxes();
    let keys = tree.keys();
    let domain = *tree.domain();
    assert_eq!(keys[0], MortonKey::ROOT);
    // (level, Morton) order, levels contiguous, index_of.
    for b in 1..n {
        assert!(
            (keys[b - 1].level(), keys[b - 1]) < (keys[b].level(), keys[b]),
            "keys not sorted by (level, Morton)"
        );
    }
    for l in 0..=tree.depth() + 1 {
        for b in tree.level_range(l) {
            assert_eq!(tree.key(b).level(), l);
        }
    }
    assert!(tree.level_range(tree.depth() + 1).is_empty());
    for b in 0..n {
        assert_eq!(tree.index_of(keys[b]), Some(b));
        assert_eq!(tree.level(b), keys[b].level());
    }
    // Parents and children.
    assert_eq!(tree.parent(0), None);
    for b in 1..n {
        let p = tree.parent(b).expect("non-root box has a parent");
        assert_eq!(keys[p], keys[b].parent());
        assert!(tree.children(p).contains(&b));
    }
    for b in 0..n {
        let ch = tree.children(b);
        for c in ch.clone() {
            assert_eq!(tree.parent(c), Some(b));
        }
        assert_eq!(tree.is_leaf(b), ch.is_empty());
        // Every existing child of the key is in the range.
        if keys[b].level() < DEEPEST_LEVEL {
            let existing = keys[b]
                .children()
                .iter()
                .filter(|&&k| tree.index_of(k).is_some())
                .count();
            assert_eq!(existing, ch.len());
        }
        // No empty box; point ranges nest.
        assert!(tree.has_sources(b) || tree.has_targets(b), "empty box {b}");
        if !ch.is_empty() {
            assert_eq!(
                tree.source_range(ch.start).start,
                tree.source_range(b).start
            );
            assert_eq!(tree.source_range(ch.end - 1).end, tree.source_range(b).end);
            assert_eq!(
                tree.target_range(ch.start).start,
                tree.target_range(b).start
            );
            assert_eq!(tree.target_range(ch.end - 1).end, tree.target_range(b).end);
            for w in ch.clone().collect::<Vec<_>>().windows(2) {
                assert_eq!(tree.source_range(w[0]).end, tree.source_range(w[1]).start);
                assert_eq!(tree.target_range(w[0]).end, tree.target_range(w[1]).start);
            }
        }
    }
    let leaves: Vec<usize> = (0..n).filter(|&b| tree.is_leaf(b)).collect();
    assert_eq!(tree.leaves(), &leaves[..]);

    // Leaves partition the domain together with the missing (empty) children
    // of internal boxes: volumes in finest cells add up, and no two leaves
    // overlap.
    let mut volume: u128 = 0;
    let cells = |level: u32| 1u128 << (3 * (DEEPEST_LEVEL - level));
    for b in 0..n {
        if tree.is_leaf(b) {
            volume += cells(tree.level(b));
        } else {
            volume += (8 - tree.children(b).len() as u128) * cells(tree.level(b) + 1);
        }
    }
    assert_eq!(
        volume,
        cells(0),
        "leaves and empty cells do not tile the domain"
    );
    let mut sorted_leaf_keys: Vec<MortonKey> = leaves.iter().map(|&b| keys[b]).collect();
    sorted_leaf_keys.sort();
    for w in sorted_leaf_keys.windows(2) {
        assert!(w[0].finest_last_descendant() < w[1], "overlapping leaves");
    }

    // Points: permutations, sorted coordinates, every point in exactly one
    // leaf, and that leaf's box contains it.
    let sets: Vec<(&[f64], bool)> = match tgt {
        Some(t) => vec![(src, true), (t, false)],
        None => vec![(src, true)],
    };
    assert_eq!(tree.sources_are_targets(), tgt.is_none());
    for (pts, is_src) in sets {
        let np = pts.len() / 3;
        let (perm, inv, sorted) = if is_src {
            (
                tree.source_permutation(),
                tree.source_inverse_permutation(),
                tree.sorted_sources(),
            )
        } else {
            (
                tree.target_permutation(),
                tree.target_inverse_permutation(),
                tree.sorted_targets(),
            )
        };
        assert_eq!(perm.len(), np);
        let mut seen = vec![false; np];
        for (k, &i) in perm.iter().enumerate() {
            assert!(!seen[i], "point {i} twice");
            seen[i] = true;
            assert_eq!(inv[i], k);
            assert_eq!(&sorted[3 * k..3 * k + 3], &pts[3 * i..3 * i + 3]);
        }
        let range = |b: usize| {
            if is_src {
                tree.source_range(b)
            } else {
                tree.target_range(b)
            }
        };
        let mut owner = vec![usize::MAX; np];
        for &b in &leaves {
            for k in range(b) {
                assert_eq!(owner[k], usize::MAX, "point in two leaves");
                owner[k] = b;
            }
        }
        // Box geometry is rounded: allow a few ulps of the coordinates.
        let magnitude = domain
            .origin
            .iter()
            .fold(domain.width, |m, o| m.max(o.abs()));
        let tol = domain.width * 1e-12 + 8.0 * f64::EPSILON * magnitude;
        for k in 0..np {
            let b = owner[k];
            assert_ne!(b, usize::MAX, "point {k} in no leaf");
            let p = point(sorted, k);
            let key = keys[b];
            assert_eq!(MortonKey::from_point(p, &domain, key.level()), key);
            let c = key.center(&domain);
            let h = key.half_width(&domain);
            for a in 0..3 {
                assert!(
                    (p[a] - c[a]).abs() <= h + tol,
                    "point {p:?} outside its leaf {key}"
                );
            }
        }
    }

    // Leaf sizes and refinement.
    match opts.uniform_depth {
        Some(d) => {
            for &b in &leaves {
                assert_eq!(tree.level(b), d, "uniform tree leaf off its depth");
            }
        }
        None => {
            for &b in &leaves {
                if set_size(tree, b) > opts.leaf_size {
                    assert_eq!(
                        tree.level(b),
                        opts.max_level,
                        "oversized leaf above max_level"
                    );
                }
                assert!(tree.level(b) <= opts.max_level);
            }
            if opts.balance {
                check_balance(tree);
            }
            // Minimality: a box split although it was small enough must have
            // been split by balance, i.e. touch an internal box one level
            // deeper (without balance: never).
            for b in 0..n {
                if !tree.is_leaf(b) && set_size(tree, b) <= opts.leaf_size {
                    assert!(opts.balance, "box {} split without balance", keys[b]);
                    let l = tree.level(b);
                    let forced = tree
                        .level_range(l + 1)
                        .any(|q| !tree.is_leaf(q) && keys[q].is_adjacent(keys[b]));
                    assert!(forced, "box {} split without reason", keys[b]);
                }
            }
        }
    }
}

/// 2:1 balance: adjacent leaves differ by at most one level, and (the form
/// we enforce) no internal box finer than a leaf touches it.
pub fn check_balance(tree: &Octree) {
    let keys = tree.keys();
    let leaves = tree.leaves();
    for &a in leaves {
        for &b in leaves {
            if keys[a].is_adjacent(keys[b]) {
                let (la, lb) = (keys[a].level() as i64, keys[b].level() as i64);
                assert!(
                    (la - lb).abs() <= 1,
                    "unbalanced leaves {} {}",
                    keys[a],
                    keys[b]
                );
            }
        }
        for q in 0..tree.n_boxes() {
            if !tree.is_leaf(q) && keys[q].level() > keys[a].level() {
                assert!(
                    !keys[q].is_adjacent(keys[a]),
                    "internal {} touches coarser leaf {}",
                    keys[q],
                    keys[a]
                );
            }
        }
    }
}

/// Brute-force lists straight from the definitions.
pub struct BruteLists {
    pub u: Vec<Vec<usize>>,
    pub v: Vec<Vec<usize>>,
    pub w: Vec<Vec<usize>>,
    pub x: Vec<Vec<usize>>,
}

fn unpruned_w_contains(tree: &Octree, b: usize, a: usize) -> bool {
    let (kb, ka) = (tree.key(b), tree.key(a));
    tree.is_leaf(b)
        && ka.level() > kb.level()
        && ka.ancestor(kb.level()).is_adjacent(kb)
        && !ka.is_adjacent(kb)
        && ka.parent().is_adjacent(kb)
}

pub fn brute_lists(tree: &Octree) -> BruteLists {
    let n = tree.n_boxes();
    let k = |b: usize| tree.key(b);
    let mut out = BruteLists {
        u: vec![Vec::new(); n],
        v: vec![Vec::new(); n],
        w: vec![Vec::new(); n],
        x: vec![Vec::new(); n],
    };
    for b in 0..n {
        if !tree.has_targets(b) {
            continue;
        }
        for a in 0..n {
            if !tree.has_sources(a) {
                continue;
            }
            if tree.is_leaf(b) && tree.is_leaf(a) && (a == b || k(a).is_adjacent(k(b))) {
                out.u[b].push(a);
            }
            if b != 0
                && a != 0
                && k(a).level() == k(b).level()
                && k(a).parent().is_adjacent(k(b).parent())
                && !k(a).is_adjacent(k(b))
            {
                out.v[b].push(a);
            }
            if unpruned_w_contains(tree, b, a) {
                out.w[b].push(a);
            }
            if tree.is_leaf(a) && unpruned_w_contains(tree, a, b) {
                out.x[b].push(a);
            }
        }
    }
    out
}

/// Checks the lists against brute force, the X/W duality, and that every
/// (source leaf, target leaf) pair is covered exactly once.
pub fn check_lists(tree: &Octree) {
    let n = tree.n_boxes();
    let brute = brute_lists(tree);
    for b in 0..n {
        assert_eq!(tree.u_list(b), &brute.u[b][..], "U({})", tree.key(b));
        assert_eq!(tree.v_list(b), &brute.v[b][..], "V({})", tree.key(b));
        assert_eq!(tree.w_list(b), &brute.w[b][..], "W({})", tree.key(b));
        assert_eq!(tree.x_list(b), &brute.x[b][..], "X({})", tree.key(b));
        // Levels and transfer vectors promised to the driver.
        let kb = tree.key(b);
        for &a in tree.v_list(b) {
            let t = kb.transfer_vector(tree.key(a));
            assert!(t.iter().all(|x| x.abs() <= 3) && t.iter().any(|x| x.abs() >= 2));
        }
        for &a in tree.w_list(b) {
            assert_eq!(tree.level(a), kb.level() + 1, "W entry not one level finer");
        }
        for &a in tree.x_list(b) {
            assert_eq!(
                tree.level(a) + 1,
                kb.level(),
                "X entry not one level coarser"
            );
        }
    }
    check_coverage(tree);
}

/// Ancestors-or-self of `b`, as box indices.
pub fn ancestors_or_self(tree: &Octree, b: usize) -> Vec<usize> {
    let mut out = vec![b];
    let mut c = b;
    while let Some(p) = tree.parent(c) {
        out.push(p);
        c = p;
    }
    out
}

/// For every target leaf `B` and source leaf `A`, the number of times an
/// ancestor-or-self `A'` of `A` appears in any of U, V, W, X of an
/// ancestor-or-self `B'` of `B` must be exactly 1.
pub fn check_coverage(tree: &Octree) {
    let leaves = tree.leaves();
    for &b in leaves.iter().filter(|&&b| tree.has_targets(b)) {
        let mut hits: HashMap<usize, usize> = HashMap::new();
        for bp in ancestors_or_self(tree, b) {
            for list in [
                tree.u_list(bp),
                tree.v_list(bp),
                tree.w_list(bp),
                tree.x_list(bp),
            ] {
                for &a in list {
                    *hits.entry(a).or_default() += 1;
                }
            }
        }
        for &a in leaves.iter().filter(|&&a| tree.has_sources(a)) {
            let count: usize = ancestors_or_self(tree, a)
                .iter()
                .map(|ap| hits.get(ap).copied().unwrap_or(0))
                .sum();
            assert_eq!(
                count,
                1,
                "pair (source leaf {}, target leaf {}) covered {count} times",
                tree.key(a),
                tree.key(b)
            );
        }
    }
}

/// Largest U, V, W, X rows.
pub fn max_sizes(tree: &Octree) -> [usize; 4] {
    let l = tree.interaction_lists();
    [
        l.u.max_row_len(),
        l.v.max_row_len(),
        l.w.max_row_len(),
        l.x.max_row_len(),
    ]
}
