//! Periodic trees: the lists of boxes at levels >= 1 cover every
//! interaction between a target leaf and the images (shift in {-1, 0, 1}
//! on periodic axes) of every source leaf exactly once; entries are
//! separated (or adjacent, for U) in the shifted geometry; the 2:1 balance
//! wraps across periodic faces; a one-leaf tree sees its own images; bad
//! options are errors. Geometry here is recomputed from the keys, not taken
//! from the crate's helpers.

use ferrofmm_tree::{
    DEEPEST_LEVEL, Domain, FINEST_GRID, MortonKey, Octree, PointSet, TreeError, TreeOptions,
};

const XYZ: [bool; 3] = [true; 3];
const SLAB: [bool; 3] = [true, true, false];
const ROD: [bool; 3] = [true, false, false];

fn cell() -> Domain {
    Domain::new([0.0; 3], 1.0).unwrap()
}

/// A deterministic generator in [0, 1).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn uniform(n: usize, seed: u64) -> Vec<f64> {
    let mut r = Rng(seed);
    (0..3 * n).map(|_| r.next()).collect()
}

/// Points in a ball, wrapped into the unit cell (a ball across a face is
/// cut in pieces on both sides).
fn ball(n: usize, centre: [f64; 3], radius: f64, seed: u64) -> Vec<f64> {
    let mut r = Rng(seed);
    let mut out = Vec::with_capacity(3 * n);
    while out.len() < 3 * n {
        let d: [f64; 3] = std::array::from_fn(|_| 2.0 * r.next() - 1.0);
        if d.iter().map(|x| x * x).sum::<f64>() <= 1.0 {
            out.extend((0..3).map(|a| {
                let x = (centre[a] + radius * d[a]).rem_euclid(1.0);
                if x >= 1.0 { 0.0 } else { x }
            }));
        }
    }
    out
}

/// Two small balls, one across the x = 0 face (and the y = 1 face), one
/// touching the z = 0 face from inside, plus a sparse background.
fn clustered(seed: u64) -> Vec<f64> {
    let mut p = ball(250, [0.0, 0.98, 0.4], 0.03, seed);
    p.extend(ball(250, [0.6, 0.3, 0.02], 0.02, seed + 1));
    p.extend(uniform(60, seed + 2));
    p
}

/// Points on faces, edges and corners of the cell (lower faces; upper
/// faces minus a little), and a few inside.
fn faces() -> Vec<f64> {
    let vals = [0.0, 1e-9, 0.25, 0.5, 0.75, 1.0 - 1e-9];
    let mut p = Vec::new();
    for &x in &vals {
        for &y in &vals {
            for &z in &vals {
                if [x, y, z].iter().any(|&v| v == 0.0 || v > 0.99) {
                    p.extend([x, y, z]);
                }
            }
        }
    }
    p.extend(uniform(40, 7));
    p
}

/// Shifts allowed on `axes`: {-1, 0, 1} on periodic ones, 0 elsewhere.
fn shifts(axes: [bool; 3]) -> Vec<[i8; 3]> {
    let r = |a: usize| if axes[a] { -1i8..=1 } else { 0..=0 };
    let mut out = Vec::new();
    for z in r(2) {
        for y in r(1) {
            for x in r(0) {
                out.push([x, y, z]);
            }
        }
    }
    out
}

fn shift_index(s: [i8; 3]) -> usize {
    s.iter()
        .enumerate()
        .map(|(a, &x)| {
            assert!((-1..=1).contains(&x), "shift {s:?} beyond one cell");
            (x + 1) as usize * 3usize.pow(a as u32)
        })
        .sum()
}

/// Lower and upper corners of `key` translated by `s` cells, in finest cells.
fn extent(key: MortonKey, s: [i8; 3]) -> ([i64; 3], [i64; 3]) {
    let w = 1i64 << (DEEPEST_LEVEL - key.level());
    let a = key.anchor();
    let lo: [i64; 3] = std::array::from_fn(|i| a[i] as i64 + s[i] as i64 * FINEST_GRID as i64);
    (lo, lo.map(|x| x + w))
}

/// `a + s` and `b` touch and have disjoint interiors.
fn touching(a: MortonKey, s: [i8; 3], b: MortonKey) -> bool {
    let ((la, ha), (lb, hb)) = (extent(a, s), extent(b, [0; 3]));
    let closed = (0..3).all(|i| la[i] <= hb[i] && lb[i] <= ha[i]);
    let open_overlap = (0..3).all(|i| la[i] < hb[i] && lb[i] < ha[i]);
    closed && !open_overlap
}

/// `a + s` and `b` are the same box.
fn same(a: MortonKey, s: [i8; 3], b: MortonKey) -> bool {
    a == b && s == [0; 3]
}

/// Row `b` of a list with its shifts (which must exist and match).
fn row(list: &[usize], shifts: Option<&[[i8; 3]]>) -> Vec<(usize, [i8; 3])> {
    let s = shifts.expect("a periodic tree has shifts");
    assert_eq!(s.len(), list.len(), "shifts parallel to the list");
    list.iter().copied().zip(s.iter().copied()).collect()
}

fn build(p: &[f64], tgt: Option<&[f64]>, leaf: usize, axes: [bool; 3]) -> Octree {
    let opts = TreeOptions::adaptive(leaf)
        .with_domain(cell())
        .with_periodic(axes);
    Octree::new(p, tgt, &opts).unwrap()
}

/// Every interaction (target leaf B, image A + s of source leaf A) with s
/// allowed on the tree's axes is reached exactly once via U(B), W(B),
/// V(B') and X(B') for B' = B or an ancestor of level >= 1; the root's V
/// and X lists are empty; shifts are 0 on open axes and within one cell.
fn check_coverage(tree: &Octree) {
    let axes = tree.periodic_axes();
    assert!(tree.is_periodic());
    let n = tree.n_boxes();
    let leaves: Vec<usize> = tree
        .leaves()
        .iter()
        .copied()
        .filter(|&a| tree.has_sources(a))
        .collect();
    let mut leaf_id = vec![usize::MAX; n];
    for (k, &a) in leaves.iter().enumerate() {
        leaf_id[a] = k;
    }
    // Source leaves below each box.
    let mut below: Vec<Vec<usize>> = vec![Vec::new(); n];
    for b in (0..n).rev() {
        if tree.is_leaf(b) {
            if tree.has_sources(b) {
                below[b].push(leaf_id[b]);
            }
        } else {
            let mut v = Vec::new();
            for c in tree.children(b) {
                v.extend_from_slice(&below[c]);
            }
            below[b] = v;
        }
    }
    assert!(tree.v_list(0).is_empty() && tree.x_list(0).is_empty());
    let allowed = shifts(axes);
    let mut count = vec![0u32; leaves.len() * 27];
    let mut checked = 0usize;
    for &b in tree.leaves() {
        if !tree.has_targets(b) {
            continue;
        }
        count.fill(0);
        let mut add = |a: usize, s: [i8; 3], what: &str| {
            for (axis, &x) in s.iter().enumerate() {
                assert!(axes[axis] || x == 0, "{what}: shift {s:?} on an open axis");
            }
            for &l in &below[a] {
                count[l * 27 + shift_index(s)] += 1;
            }
        };
        for (a, s) in row(tree.u_list(b), tree.u_shifts(b)) {
            assert!(tree.is_leaf(a), "U entry not a leaf");
            add(a, s, "U");
        }
        for (a, s) in row(tree.w_list(b), tree.w_shifts(b)) {
            add(a, s, "W");
        }
        let mut anc = Some(b);
        while let Some(x) = anc {
            if tree.level(x) >= 1 {
                for (a, s) in row(tree.v_list(x), tree.v_shifts(x)) {
                    add(a, s, "V");
                }
                for (a, s) in row(tree.x_list(x), tree.x_shifts(x)) {
                    add(a, s, "X");
                }
            }
            anc = tree.parent(x);
        }
        for (k, &a) in leaves.iter().enumerate() {
            for si in 0..27 {
                let s = [
                    (si % 3) as i8 - 1,
                    (si / 3 % 3) as i8 - 1,
                    (si / 9) as i8 - 1,
                ];
                let want = u32::from(allowed.contains(&s));
                assert_eq!(
                    count[k * 27 + si],
                    want,
                    "target {} source {} shift {s:?}",
                    tree.key(b),
                    tree.key(a)
                );
                checked += want as usize;
            }
        }
    }
    assert!(checked > 0);
}

/// U entries are adjacent leaves or the box itself; V, W and X entries are
/// separated from the target in the shifted geometry and have the
/// free-space relations (V: children of the parent's colleagues, W:
/// children of colleagues... up to balance, X: dual of W); V transfer
/// vectors are in -3..=3 with one component of magnitude >= 2; rows are
/// ordered by (box, shift) without repeats.
fn check_separation(tree: &Octree) {
    let mut sizes = [0usize; 4];
    for b in 0..tree.n_boxes() {
        let kb = tree.key(b);
        let u = row(tree.u_list(b), tree.u_shifts(b));
        let v = row(tree.v_list(b), tree.v_shifts(b));
        let w = row(tree.w_list(b), tree.w_shifts(b));
        let x = row(tree.x_list(b), tree.x_shifts(b));
        for (r, name) in [(&u, "U"), (&v, "V"), (&w, "W"), (&x, "X")] {
            assert!(
                r.windows(2).all(|p| p[0] < p[1]),
                "{name} row of {kb} not ordered by (box, shift) or repeated"
            );
        }
        sizes = [
            sizes[0].max(u.len()),
            sizes[1].max(v.len()),
            sizes[2].max(w.len()),
            sizes[3].max(x.len()),
        ];
        for &(a, s) in &u {
            let ka = tree.key(a);
            assert!(
                same(ka, s, kb) || touching(ka, s, kb),
                "U: {ka}{s:?} of {kb}"
            );
        }
        for &(a, s) in &v {
            let ka = tree.key(a);
            assert_eq!(ka.level(), kb.level());
            assert!(
                !same(ka, s, kb) && !touching(ka, s, kb),
                "V: {ka}{s:?} of {kb}"
            );
            assert!(touching(ka.parent(), s, kb.parent()) || same(ka.parent(), s, kb.parent()));
            let t = kb.shifted_transfer_vector(ka, s);
            let by_hand: [i64; 3] = {
                let (la, _) = extent(ka, s);
                let (lb, _) = extent(kb, [0; 3]);
                let w = 1i64 << (DEEPEST_LEVEL - kb.level());
                std::array::from_fn(|i| (la[i] - lb[i]) / w)
            };
            assert_eq!(t.map(i64::from), by_hand);
            assert!(t.iter().all(|c| (-3..=3).contains(c)), "V transfer {t:?}");
            assert!(t.iter().any(|c| c.abs() >= 2), "V transfer {t:?}");
        }
        for &(a, s) in &w {
            let ka = tree.key(a);
            assert!(tree.is_leaf(b));
            assert!(ka.level() > kb.level());
            assert!(!touching(ka, s, kb), "W: {ka}{s:?} of {kb}");
            assert!(touching(ka.parent(), s, kb), "W parent: {ka}{s:?} of {kb}");
        }
        for &(a, s) in &x {
            let ka = tree.key(a);
            assert!(tree.is_leaf(a));
            assert!(ka.level() < kb.level());
            assert!(!touching(ka, s, kb), "X: {ka}{s:?} of {kb}");
            assert!(touching(ka, s, kb.parent()), "X: {ka}{s:?} of {kb}");
        }
    }
    assert!(sizes[0] <= 57 && sizes[1] <= 189 && sizes[2] <= 152 && sizes[3] <= 19);
}

/// The wrapped 2:1 balance: no internal box of level >= l + 1 touches a
/// leaf of level l, in any image (so adjacent leaves, across periodic
/// faces too, differ by at most one level).
fn check_balance(tree: &Octree) {
    let all = shifts(tree.periodic_axes());
    let internal: Vec<usize> = (0..tree.n_boxes()).filter(|&b| !tree.is_leaf(b)).collect();
    for &l in tree.leaves() {
        let kl = tree.key(l);
        for &i in &internal {
            let ki = tree.key(i);
            if ki.level() <= kl.level() {
                continue;
            }
            for &s in &all {
                assert!(!touching(ki, s, kl), "internal {ki}{s:?} touches leaf {kl}");
            }
        }
        for &m in tree.leaves() {
            let km = tree.key(m);
            for &s in &all {
                if touching(km, s, kl) {
                    assert!(km.level().abs_diff(kl.level()) <= 1, "{km}{s:?} by {kl}");
                }
            }
        }
    }
}

fn check_all(tree: &Octree) {
    check_coverage(tree);
    check_separation(tree);
    check_balance(tree);
}

#[test]
fn uniform_points_all_periodicities() {
    let p = uniform(700, 1);
    for axes in [XYZ, SLAB, ROD] {
        let tree = build(&p, None, 6, axes);
        assert!(tree.depth() >= 3);
        check_all(&tree);
    }
}

#[test]
fn clustered_points_across_faces() {
    let p = clustered(11);
    for axes in [XYZ, SLAB, ROD] {
        let tree = build(&p, None, 4, axes);
        assert!(tree.depth() >= 6, "depth {}", tree.depth());
        check_all(&tree);
    }
}

#[test]
fn face_and_corner_points() {
    let p = faces();
    for axes in [XYZ, SLAB, ROD] {
        let tree = build(&p, None, 3, axes);
        check_all(&tree);
    }
}

#[test]
fn separate_targets_and_uniform_trees() {
    let src = clustered(5);
    let tgt = uniform(300, 9);
    for axes in [XYZ, SLAB, ROD] {
        let tree = build(&src, Some(&tgt), 5, axes);
        check_all(&tree);
        for depth in [1, 2, 3] {
            let opts = TreeOptions::uniform(depth)
                .with_domain(cell())
                .with_periodic(axes);
            let tree = Octree::new(&tgt, None, &opts).unwrap();
            check_all(&tree);
        }
    }
}

/// The balance wraps: a deep cluster at the x = 0 face refines the leaves
/// across the face (at x = 1) as it refines those at its inner side; in
/// free space the far side stays coarse.
#[test]
fn balance_wraps_across_a_periodic_face() {
    let mut p = ball(400, [0.001, 0.5, 0.5], 0.0005, 3);
    p.extend([0.999, 0.5, 0.5, 0.5, 0.5, 0.5]);
    let depth_at = |tree: &Octree, x: f64| {
        let leaf = tree
            .leaves()
            .iter()
            .copied()
            .find(|&l| {
                let k = MortonKey::from_point([x, 0.5, 0.5], &cell(), tree.level(l));
                k == tree.key(l)
            })
            .unwrap();
        tree.level(leaf)
    };
    let free = Octree::new(&p, None, &TreeOptions::adaptive(4).with_domain(cell())).unwrap();
    let rod = build(&p, None, 4, ROD);
    check_all(&rod);
    assert!(depth_at(&free, 0.999) + 3 < depth_at(&rod, 0.999));
    // Along an open axis nothing wraps.
    let slab_yz = build(&p, None, 4, [false, true, true]);
    check_all(&slab_yz);
    assert_eq!(depth_at(&slab_yz, 0.999), depth_at(&free, 0.999));
}

/// A tree that is a single leaf sees its own images in U: 27, 9 or 3.
#[test]
fn single_leaf_sees_its_images() {
    let p = [0.3, 0.6, 0.9, 0.1, 0.2, 0.3];
    for (axes, n) in [(XYZ, 27), (SLAB, 9), (ROD, 3), ([false, false, true], 3)] {
        let tree = build(&p, None, 10, axes);
        assert_eq!(tree.n_boxes(), 1);
        assert_eq!(tree.u_list(0), vec![0; n].as_slice());
        let mut s = tree.u_shifts(0).unwrap().to_vec();
        let mut want = shifts(axes);
        s.sort_unstable();
        want.sort_unstable();
        assert_eq!(s, want);
        assert!(tree.v_list(0).is_empty() && tree.w_list(0).is_empty());
        assert!(tree.x_list(0).is_empty());
        check_all(&tree);
    }
}

/// Level 1: a box sees the other boxes of its level both ways round.
#[test]
fn level_one_neighbours_wrap() {
    let p: Vec<f64> = (0..8)
        .flat_map(|o| {
            [
                0.25 + 0.5 * (o & 1) as f64,
                0.25 + 0.5 * (o >> 1 & 1) as f64,
                0.25 + 0.5 * (o >> 2) as f64,
            ]
        })
        .collect();
    let tree = build(&p, None, 1, ROD);
    assert_eq!(tree.depth(), 1);
    let b = tree.index_of(MortonKey::ROOT.children()[0]).unwrap();
    let other = tree.index_of(MortonKey::ROOT.children()[1]).unwrap();
    let u = row(tree.u_list(b), tree.u_shifts(b));
    assert!(u.contains(&(other, [0, 0, 0])) && u.contains(&(other, [-1, 0, 0])));
    assert_eq!(u.len(), 8 + 4);
    assert_eq!(tree.colleague(b, [-1, 0, 0]), Some(other));
    assert_eq!(tree.colleague_shift(b, [-1, 0, 0]), [-1, 0, 0]);
    assert_eq!(tree.colleague(b, [0, -1, 0]), None);
    check_all(&tree);
}

#[test]
fn free_space_trees_have_no_shifts() {
    let p = uniform(500, 2);
    let tree = Octree::new(&p, None, &TreeOptions::adaptive(8)).unwrap();
    assert!(!tree.is_periodic());
    assert_eq!(tree.periodic_axes(), [false; 3]);
    let l = tree.leaves()[0];
    assert!(tree.u_shifts(l).is_none() && tree.v_shifts(l).is_none());
    assert!(tree.w_shifts(l).is_none() && tree.x_shifts(l).is_none());
    let lists = tree.interaction_lists();
    for c in [&lists.u, &lists.v, &lists.w, &lists.x] {
        assert!(c.shifts().is_none());
    }
    // The same points in a periodic tree without balance: no lists, but
    // shift rows (empty).
    let opts = TreeOptions::adaptive(8)
        .with_domain(cell())
        .with_periodic(XYZ)
        .with_balance(false);
    let t = Octree::new(&p, None, &opts).unwrap();
    assert!(!t.has_lists());
    assert_eq!(t.u_shifts(l), Some(&[][..]));
}

#[test]
fn bad_periodic_options_are_errors() {
    let p = uniform(50, 4);
    let no_domain = TreeOptions::adaptive(4).with_periodic(SLAB);
    assert_eq!(no_domain.validate(), Err(TreeError::PeriodicWithoutDomain));
    assert_eq!(
        Octree::new(&p, None, &no_domain).unwrap_err(),
        TreeError::PeriodicWithoutDomain
    );
    // A point on the upper face of a periodic axis.
    let mut q = p.clone();
    q.extend([0.5, 1.0, 0.5]);
    let err = Octree::new(&q, None, &no_domain.clone().with_domain(cell())).unwrap_err();
    assert_eq!(
        err,
        TreeError::OnPeriodicFace {
            set: PointSet::Sources,
            index: 50,
            point: [0.5, 1.0, 0.5],
            axis: 1
        }
    );
    assert!(err.to_string().contains("upper face of periodic axis 1"));
    // ... of targets.
    let err = Octree::new(&p, Some(&q), &no_domain.clone().with_domain(cell())).unwrap_err();
    assert!(matches!(
        err,
        TreeError::OnPeriodicFace {
            set: PointSet::Targets,
            ..
        }
    ));
    // On the upper face of an open axis it is fine.
    let mut r = p.clone();
    r.extend([0.5, 0.5, 1.0]);
    assert!(Octree::new(&r, None, &no_domain.clone().with_domain(cell())).is_ok());
    // Outside the cell.
    let mut o = p;
    o.extend([1.5, 0.5, 0.5]);
    assert!(matches!(
        Octree::new(&o, None, &no_domain.with_domain(cell())),
        Err(TreeError::OutsideDomain { .. })
    ));
}

/// `from_parts` builds free-space trees: lists with shifts are refused.
#[test]
fn from_parts_refuses_periodic_lists() {
    let p = uniform(200, 3);
    let tree = build(&p, None, 8, XYZ);
    let boxes: Vec<_> = (0..tree.n_boxes())
        .map(|b| (tree.key(b), tree.source_range(b), tree.target_range(b)))
        .collect();
    let err = Octree::from_parts(*tree.domain(), &boxes, tree.interaction_lists().clone());
    assert!(matches!(err, Err(TreeError::InvalidParts { .. })));
}

/// `take_v_lists` hands over exactly the V lists (entries and shifts) and
/// leaves every box an empty V list; the other lists are untouched. Open
/// and periodic trees.
#[test]
fn taken_v_lists_are_the_lists_and_leave_empty_rows() {
    // Entries with their shifts (zero without shifts: an open tree).
    fn entries(list: &[usize], shifts: Option<&[[i8; 3]]>) -> Vec<(usize, [i8; 3])> {
        match shifts {
            Some(_) => row(list, shifts),
            None => list.iter().map(|&a| (a, [0; 3])).collect(),
        }
    }
    let p = clustered(11);
    for axes in [[false; 3], SLAB, XYZ] {
        let mut tree = build(&p, None, 16, axes);
        let n = tree.n_boxes();
        let before: Vec<Vec<(usize, [i8; 3])>> = (0..n)
            .map(|b| entries(tree.v_list(b), tree.v_shifts(b)))
            .collect();
        let others: Vec<(Vec<usize>, Vec<usize>, Vec<usize>)> = (0..n)
            .map(|b| {
                (
                    tree.u_list(b).to_vec(),
                    tree.w_list(b).to_vec(),
                    tree.x_list(b).to_vec(),
                )
            })
            .collect();
        assert!(
            before.iter().any(|r| !r.is_empty()),
            "{axes:?}: no V entries"
        );
        let taken = tree.take_v_lists();
        for b in 0..n {
            assert_eq!(
                entries(taken.get(b), taken.row_shifts(b)),
                before[b],
                "{axes:?} box {b}"
            );
            assert!(tree.v_list(b).is_empty(), "{axes:?} box {b}");
            assert!(tree.v_shifts(b).is_none_or(<[_]>::is_empty));
            let (u, w, x) = &others[b];
            assert_eq!(
                (tree.u_list(b), tree.w_list(b), tree.x_list(b)),
                (&u[..], &w[..], &x[..])
            );
        }
    }
}
