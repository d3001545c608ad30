//! Property tests of Morton keys: encode/decode, family relations,
//! neighbours, adjacency and ordering, against direct geometric definitions.

use ferrofmm_tree::{DEEPEST_LEVEL, Domain, FINEST_GRID, MortonKey};
use proptest::prelude::*;

fn key() -> impl Strategy<Value = MortonKey> {
    (
        0u32..=DEEPEST_LEVEL,
        [0u32..FINEST_GRID, 0u32..FINEST_GRID, 0u32..FINEST_GRID],
    )
        .prop_map(|(l, a)| MortonKey::from_anchor(a, l))
}

/// A key near `k` (same region, random level), to exercise adjacency.
fn nearby(k: MortonKey, level: u32, offset: [i32; 3]) -> MortonKey {
    let w = k.width_in_cells() as i64;
    let a = k.anchor();
    let p: [u32; 3] = std::array::from_fn(|i| {
        (a[i] as i64 + offset[i] as i64 * w / 2).clamp(0, FINEST_GRID as i64 - 1) as u32
    });
    MortonKey::from_anchor(p, level)
}

/// Closed integer box `[lo, hi]` in finest cells of a key.
fn bounds(k: MortonKey) -> ([i64; 3], [i64; 3]) {
    let a = k.anchor().map(|x| x as i64);
    let w = k.width_in_cells() as i64;
    (a, a.map(|x| x + w))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn anchor_round_trip(a in [0u32..FINEST_GRID, 0u32..FINEST_GRID, 0u32..FINEST_GRID], l in 0u32..=DEEPEST_LEVEL) {
        let k = MortonKey::from_anchor(a, l);
        let mask = !(k.width_in_cells() - 1);
        prop_assert_eq!(k.anchor(), a.map(|x| x & mask));
        prop_assert_eq!(k.level(), l);
        prop_assert_eq!(MortonKey::from_raw(k.raw()), Some(k));
        prop_assert_eq!(MortonKey::from_morton(k.morton(), l), k);
        // Bit layout: bit i of x at 3i, of y at 3i+1, of z at 3i+2.
        let mut m = 0u64;
        for bit in 0..DEEPEST_LEVEL {
            for (axis, &c) in k.anchor().iter().enumerate() {
                m |= (((c >> bit) & 1) as u64) << (3 * bit + axis as u32);
            }
        }
        prop_assert_eq!(k.morton(), m);
    }

    #[test]
    fn point_round_trip(p in [0.0f64..1.0, 0.0f64..1.0, 0.0f64..1.0], l in 0u32..=DEEPEST_LEVEL,
                        origin in [-1e6f64..1e6, -1e6f64..1e6, -1e6f64..1e6], width in 1e-3f64..1e3) {
        let d = Domain::new(origin, width).unwrap();
        let x: [f64; 3] = std::array::from_fn(|i| origin[i] + p[i] * width);
        let k = MortonKey::from_point(x, &d, l);
        let c = k.center(&d);
        let h = k.half_width(&d);
        for i in 0..3 {
            prop_assert!((x[i] - c[i]).abs() <= h * (1.0 + 1e-9) + 1e-9 * width.max(origin[i].abs()));
        }
        // The deeper key of the same point is a descendant.
        let fine = MortonKey::from_point(x, &d, DEEPEST_LEVEL);
        prop_assert!(k.contains(fine));
        prop_assert_eq!(fine.ancestor(l), k);
        // Re-encoding the centre gives the same box.
        prop_assert_eq!(MortonKey::from_point(c, &d, l), k);
    }

    #[test]
    fn family(k in key()) {
        let l = k.level();
        if l < DEEPEST_LEVEL {
            let ch = k.children();
            for (o, &c) in ch.iter().enumerate() {
                prop_assert_eq!(c.parent(), k);
                prop_assert_eq!(c.octant(), o);
                prop_assert_eq!(c.level(), l + 1);
                prop_assert!(k.is_ancestor_of(c) && k.contains(c) && !c.contains(k));
                prop_assert!(k < c && c <= k.finest_last_descendant());
                prop_assert_eq!(c.siblings(), ch);
                // Octant bits: x = 1, y = 2, z = 4.
                let half = c.width_in_cells();
                for axis in 0..3 {
                    let upper = c.anchor()[axis] - k.anchor()[axis] == half;
                    prop_assert_eq!(upper, o >> axis & 1 == 1);
                }
            }
            prop_assert!(ch.windows(2).all(|w| w[0] < w[1]));
        }
        if l > 0 {
            let p = k.parent();
            prop_assert!(p.children().contains(&k));
            prop_assert_eq!(k.siblings()[k.octant()], k);
        }
        let anc: Vec<_> = k.ancestors().collect();
        prop_assert_eq!(anc.len(), l as usize);
        for (i, a) in anc.iter().enumerate() {
            prop_assert_eq!(a.level(), l - 1 - i as u32);
            prop_assert!(a.is_ancestor_of(k));
        }
        prop_assert!(!k.is_ancestor_of(k) && k.contains(k));
        prop_assert_eq!(k.finest_first_descendant().anchor(), k.anchor());
        prop_assert_eq!(k.finest_last_descendant().anchor(), k.anchor().map(|a| a + k.width_in_cells() - 1));
        prop_assert_eq!(k.morton_range().end - k.morton_range().start,
                        k.finest_last_descendant().morton() - k.morton() + 1);
    }

    /// Sorting gives pre-order: a box precedes its descendants, and all of
    /// them precede any box after it that it does not contain.
    #[test]
    fn depth_first_order(a in key(), b in key()) {
        if a.contains(b) {
            prop_assert!(a <= b);
        } else if b.contains(a) {
            prop_assert!(b <= a);
        } else {
            prop_assert_eq!(a < b, a.morton() < b.morton());
            let (first, second) = if a < b { (a, b) } else { (b, a) };
            prop_assert!(first.finest_last_descendant() < second);
        }
    }

    #[test]
    fn colleagues_and_transfer_vectors(k in key()) {
        let col = k.colleagues();
        let n = 1i64 << k.level();
        let s = DEEPEST_LEVEL - k.level();
        let c = k.anchor().map(|a| (a >> s) as i64);
        let inside = |o: [i64; 3]| (0..3).all(|i| (0..n).contains(&(c[i] + o[i])));
        let mut expected = 0;
        for dz in -1..=1 { for dy in -1..=1 { for dx in -1..=1 {
            if (dx, dy, dz) != (0, 0, 0) && inside([dx, dy, dz]) { expected += 1; }
        }}}
        prop_assert_eq!(col.len(), expected);
        prop_assert!(col.len() <= 26);
        for &q in &col {
            prop_assert_eq!(q.level(), k.level());
            prop_assert!(k.is_adjacent(q) && q.is_adjacent(k));
            let t = k.transfer_vector(q);
            prop_assert!(t.iter().all(|x| x.abs() <= 1) && t != [0; 3]);
            prop_assert_eq!(k.neighbour(t), Some(q));
            prop_assert_eq!(q.transfer_vector(k), t.map(|x| -x));
        }
    }

    /// `is_adjacent` equals the geometric definition: closed boxes intersect,
    /// interiors do not.
    #[test]
    fn adjacency_matches_geometry(k in key(), l2 in 0u32..=DEEPEST_LEVEL,
                                  off in [-2i32..=2, -2i32..=2, -2i32..=2]) {
        let q = nearby(k, l2, off);
        let (alo, ahi) = bounds(k);
        let (blo, bhi) = bounds(q);
        let closed = (0..3).all(|i| alo[i] <= bhi[i] && blo[i] <= ahi[i]);
        let interiors = (0..3).all(|i| alo[i] < bhi[i] && blo[i] < ahi[i]);
        prop_assert_eq!(k.is_adjacent(q), closed && !interiors);
        prop_assert_eq!(k.is_adjacent(q), q.is_adjacent(k));
        // Octree boxes with overlapping interiors are nested.
        prop_assert_eq!(interiors, k.contains(q) || q.contains(k));
    }
}

#[test]
fn root_and_layout() {
    assert_eq!(MortonKey::ROOT.level(), 0);
    assert_eq!(MortonKey::ROOT.anchor(), [0; 3]);
    assert_eq!(MortonKey::ROOT.octant(), 0);
    assert_eq!(MortonKey::ROOT.ancestors().count(), 0);
    assert!(MortonKey::ROOT.colleagues().is_empty());
    let d = Domain::new([1.0, 2.0, 3.0], 4.0).unwrap();
    assert_eq!(MortonKey::ROOT.center(&d), [3.0, 4.0, 5.0]);
    assert_eq!(MortonKey::ROOT.half_width(&d), 2.0);
    let deepest = MortonKey::from_anchor([FINEST_GRID - 1; 3], DEEPEST_LEVEL);
    assert_eq!(deepest.octant(), 7);
    assert!(deepest.raw() < 1 << 63);
    assert_eq!(MortonKey::from_raw(3 << 5 | 1), None); // not aligned to level 1
    assert_eq!(MortonKey::from_raw(31), None); // level too deep
    // Points on the upper faces clamp into the last box.
    let k = MortonKey::from_point([5.0, 6.0, 7.0], &d, 3);
    assert_eq!(k.anchor(), [FINEST_GRID - (1 << (DEEPEST_LEVEL - 3)); 3]);
    // Interior colleague count.
    let mid = MortonKey::from_anchor([FINEST_GRID / 2; 3], 3);
    assert_eq!(mid.colleagues().len(), 26);
}

#[test]
#[should_panic(expected = "root has no parent")]
fn root_has_no_parent() {
    let _ = MortonKey::ROOT.parent();
}

#[test]
#[should_panic(expected = "across levels")]
fn transfer_vector_needs_same_level() {
    let c = MortonKey::ROOT.children();
    let _ = c[0].transfer_vector(c[1].children()[0]);
}
