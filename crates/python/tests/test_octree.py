"""The octree's invariants, checked from its NumPy arrays."""

import numpy as np
import pytest

import ferrofmm
from conftest import cube, sphere, two_clusters


def adjacent(tree, a, b):
    """Boxes touch (share a face, edge or corner) and neither contains the other."""
    wa = 1 << (ferrofmm.DEEPEST_LEVEL - int(tree.levels[a]))
    wb = 1 << (ferrofmm.DEEPEST_LEVEL - int(tree.levels[b]))
    lo_a, lo_b = tree.anchors[a].astype(np.int64), tree.anchors[b].astype(np.int64)
    hi_a, hi_b = lo_a + wa, lo_b + wb
    touch = np.all(lo_a <= hi_b) and np.all(lo_b <= hi_a)
    overlap = np.all(lo_a < hi_b) and np.all(lo_b < hi_a)
    return bool(touch and not overlap)


@pytest.mark.parametrize("geometry", [cube, sphere, two_clusters])
def test_structure(rng, geometry):
    x = geometry(rng, 5000)
    leaf = 40
    tree = ferrofmm.Octree(x, leaf_size=leaf)
    n = tree.n_boxes
    assert tree.balanced
    # Keys in (level, Morton) order; the level is in the key.
    order = np.lexsort((tree.morton, tree.levels))
    np.testing.assert_array_equal(order, np.arange(n))
    assert tree.levels.max() == tree.depth
    assert tree.parents[0] == -1
    assert np.all(tree.levels[tree.parents[1:]] == tree.levels[1:] - 1)
    # The permutation is one, and each leaf's range covers its points.
    perm = tree.permutation
    np.testing.assert_array_equal(np.sort(perm), np.arange(len(x)))
    ranges = tree.source_ranges
    leaves = tree.leaves
    covered = np.zeros(len(x), dtype=int)
    for b in leaves:
        s, e = ranges[b]
        covered[s:e] += 1
        assert e - s <= leaf or tree.levels[b] == ferrofmm.DEEPEST_LEVEL
        pts = x[perm[s:e]]
        c, h = tree.centers[b], tree.half_widths[b]
        assert np.all(np.abs(pts - c) <= h * (1 + 1e-12) + 1e-15)
    assert np.all(covered == 1), "every point in exactly one leaf"
    # Ranges nest: a parent's range is the union of its children's.
    for b in range(1, n):
        p = tree.parents[b]
        assert ranges[p][0] <= ranges[b][0] and ranges[b][1] <= ranges[p][1]
    # 2:1 balance: adjacent leaves differ by at most one level.
    for i, a in enumerate(leaves[:200]):
        for b in leaves:
            if a != b and adjacent(tree, a, b):
                assert abs(int(tree.levels[a]) - int(tree.levels[b])) <= 1


def test_lists(rng):
    x = cube(rng, 4000)
    tree = ferrofmm.Octree(x, leaf_size=30)
    offsets, indices = tree.lists("u")
    assert len(offsets) == tree.n_boxes + 1 and offsets[-1] == len(indices)
    for b in tree.leaves[:100]:
        u = tree.u_list(b)
        assert b in u
        assert all(adjacent(tree, b, a) for a in u if a != b)
    some_v = 0
    for b in range(tree.n_boxes):
        for a in tree.v_list(b):
            some_v += 1
            assert tree.levels[a] == tree.levels[b]
            assert not adjacent(tree, a, b)
            assert adjacent(tree, tree.parents[a], tree.parents[b]) or tree.parents[a] == tree.parents[b]
        assert len(tree.v_list(b)) <= 189
    assert some_v > 0
    for b in range(tree.n_boxes):
        for a in tree.w_list(b):
            assert tree.levels[a] > tree.levels[b] and not adjacent(tree, a, b)
        for a in tree.x_list(b):
            assert tree.levels[a] < tree.levels[b] and not adjacent(tree, a, b)
    with pytest.raises(ValueError, match="unknown interaction list"):
        tree.lists("z")
    with pytest.raises(IndexError):
        tree.u_list(tree.n_boxes)


def test_unbalanced_tree(rng):
    sparse = cube(rng, 300)
    tight = 0.01 + 1e-4 * cube(rng, 3000)
    x = np.concatenate([sparse, tight])
    plain = ferrofmm.Octree(x, leaf_size=8, balance=False)
    balanced = ferrofmm.Octree(x, leaf_size=8)
    assert not plain.balanced and balanced.balanced
    assert balanced.n_boxes > plain.n_boxes
    assert set(plain.keys.tolist()) <= set(balanced.keys.tolist())
    with pytest.raises(ValueError, match="balance"):
        plain.u_list(0)


def test_separate_targets_and_float32(rng):
    x = cube(rng, 2000).astype(np.float32)
    y = sphere(rng, 500)
    tree = ferrofmm.Octree(x, leaf_size=20, targets=y)
    np.testing.assert_array_equal(np.sort(tree.target_permutation), np.arange(500))
    assert tree.target_ranges[0][1] == 500 and tree.source_ranges[0][1] == 2000
