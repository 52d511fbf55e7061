"""Linear octree: Morton codes, conversions, parent = max of children, nearest-ancestor queries."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.world.octree import LinearOctree, OctreeGrid, morton_decode, morton_encode


def test_depth_follows_the_requested_leaf_size():
    g = OctreeGrid.for_leaf(2.0, 0.0625)
    assert (g.depth, g.n, g.leaf) == (5, 32, 0.0625)
    fine = OctreeGrid.for_leaf(2.0, 0.03125)
    assert (fine.depth, fine.leaf) == (6, 0.03125)
    # a leaf that does not divide the cube is rounded down, never up
    odd = OctreeGrid.for_leaf(2.0, 0.05)
    assert odd.leaf <= 0.05 and odd.depth == 6


@pytest.mark.parametrize("depth", [1, 5, 10, 21])
def test_morton_round_trip(depth, rng):
    ijk = rng.integers(0, 2**depth, size=(500, 3))
    assert np.array_equal(morton_decode(morton_encode(ijk)), ijk)


def test_octal_digits_name_the_path_from_the_root():
    g = OctreeGrid(2.0, 1)
    # digit = x + 2 y + 4 z
    assert [g.octal(int(morton_encode(np.array([c]))[0]), 1)
            for c in ([1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1])] == ["1", "2", "4", "7"]
    g5 = OctreeGrid(2.0, 5)
    ijk = np.array([[13, 7, 30]])
    child = int(g5.codes_of_ijk(ijk, 5)[0])
    parent = int(g5.codes_of_ijk(ijk, 4)[0])
    assert child >> 3 == parent
    assert g5.octal(child, 5) == g5.octal(parent, 4) + str(child & 7)


def test_points_cells_and_codes_convert_both_ways(rng):
    g = OctreeGrid.for_leaf(2.0, 0.0625, centre=(0.1, -0.2, 0.3))  # world -> octree: a shift
    ijk = rng.integers(0, g.n, size=(300, 3))
    c = g.centres_of_ijk(ijk)
    assert np.array_equal(g.ijk_of_points(c), ijk)
    flat = g.flat_of_ijk(ijk)
    assert np.array_equal(g.ijk_of_flat(flat), ijk)
    assert np.array_equal(g.flat_of_codes(g.codes_of_flat(flat)), flat)
    assert np.array_equal(g.flat_of_points(c), flat)
    # the cube's corner cell and a point outside
    corner = np.array([[0.1 - 0.999, -1.2 + 1e-6, -0.7 + 1e-6]])
    assert g.ijk_of_points(corner)[0].tolist() == [0, 0, 0]
    assert g.flat_of_points(np.array([[5.0, 0.0, 0.0]]))[0] == -1


def _max_pool(dense: np.ndarray, times: int) -> np.ndarray:
    for _ in range(times):
        m = dense.shape[0] // 2
        dense = dense.reshape(m, 2, m, 2, m, 2).max(axis=(1, 3, 5))
    return dense


def test_parents_hold_the_max_of_their_children(rng):
    g = OctreeGrid(2.0, 4)
    tree = LinearOctree(g)
    ijk = rng.integers(0, g.n, size=(60, 3))
    vals = rng.uniform(0.05, 1.0, size=60)
    tree.set_leaves(g.codes_of_ijk(ijk), vals)
    dense = tree.to_dense()
    for level in range(g.depth + 1):
        want = _max_pool(dense, g.depth - level)
        assert np.allclose(tree.to_dense(level), want)
        # only occupied cells are stored
        assert len(tree.stored(level)) == int((want > 0).sum())
    # lowering a leaf lowers its ancestors to the max of what remains
    top = int(np.argmax(vals))
    tree.set_leaves(g.codes_of_ijk(ijk[top:top + 1]), [0.01])
    dense2 = tree.to_dense()
    assert np.allclose(tree.to_dense(0), dense2.max())
    assert dense2.max() < vals[top]


def test_missing_cell_takes_its_nearest_terminal_ancestors_value():
    g = OctreeGrid(2.0, 3)
    tree = LinearOctree(g)
    coarse = g.codes_of_ijk(np.array([[4, 4, 4]]), 1)  # the +x+y+z octant, level 1
    tree.set(coarse, [0.7], level=1)
    leaf_in = g.codes_of_ijk(np.array([[6, 5, 7]]))
    leaf_out = g.codes_of_ijk(np.array([[1, 1, 1]]))
    assert tree.value(leaf_in)[0] == pytest.approx(0.7)  # inherited from level 1
    assert tree.value(leaf_out)[0] == 0.0
    assert len(tree.stored()) == 0  # nothing stored at leaf level yet
    # a finer observation inside splits the coarse cell; the rest keeps 0.7
    tree.set_leaves(leaf_in, [0.2])
    assert tree.value(leaf_in)[0] == pytest.approx(0.2)
    sibling = g.codes_of_ijk(np.array([[7, 5, 7]]))
    assert tree.value(sibling)[0] == pytest.approx(0.7)
    assert tree.value(coarse, 1)[0] == pytest.approx(0.7)  # max of children
    # below an internal node (children stored explicitly) a missing cell is empty
    t2 = LinearOctree(g)
    t2.set_leaves(g.codes_of_ijk(np.array([[0, 0, 0]])), [0.9])
    assert t2.value(g.codes_of_ijk(np.array([[1, 0, 0]])))[0] == 0.0
    assert t2.value(g.codes_of_ijk(np.array([[0, 0, 0]]), 1), 1)[0] == pytest.approx(0.9)


def test_compaction_merges_full_parents_without_changing_queries():
    g = OctreeGrid(2.0, 3)
    tree = LinearOctree(g)
    block = np.array([[2 + a, 4 + b, 6 + c] for a in (0, 1) for b in (0, 1) for c in (0, 1)])
    tree.set_leaves(g.codes_of_ijk(block), 1.0)
    tree.set_leaves(g.codes_of_ijk(np.array([[0, 0, 0]])), 0.4)
    before = tree.to_dense()
    n_before = tree.n_stored()
    assert tree.compact() == 8
    assert tree.n_stored() == n_before - 8
    assert np.array_equal(tree.to_dense(), before)
    assert tree.value(g.codes_of_ijk(block[:1]))[0] == 1.0


def test_dense_view_is_shared_until_the_tree_changes():
    g = OctreeGrid(2.0, 3)
    tree = LinearOctree(g)
    tree.set_leaves(g.codes_of_ijk(np.array([[1, 2, 3]])), 0.5)
    a = tree.to_dense()
    assert tree.to_dense() is a  # cached: planners read it several times per query
    with pytest.raises(ValueError):
        a[0, 0, 0] = 1.0  # read-only, so nobody can spoil the shared copy
    tree.set_leaves(g.codes_of_ijk(np.array([[0, 0, 0]])), 0.9)
    b = tree.to_dense()
    assert b is not a and b[0, 0, 0] == pytest.approx(0.9) and a[0, 0, 0] == 0.0
    assert tree.to_dense(1) is tree.to_dense(1)
    tree.compact()
    assert tree.to_dense() is not b and np.array_equal(tree.to_dense(), b)
