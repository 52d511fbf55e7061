"""The compiled leaf lookup of the elastic net's `allowed` against the grid's own indexing."""

from __future__ import annotations

import numpy as np

from assistant.world.leaf_lookup import leaf_flags
from assistant.world.octree import OctreeGrid


def test_leaf_flags_equal_grid_indexing() -> None:
    rng = np.random.default_rng(3)
    grids = (OctreeGrid.for_leaf(2.0, 0.0625), OctreeGrid.for_leaf(1.0, 0.03, (0.2, -0.1, 0.3)))
    for grid in grids:
        flags = rng.random(grid.n_cells) < 0.5
        P = rng.uniform(-1.3, 1.3, (5000, 3)) + grid.origin + grid.size / 2
        # points exactly on leaf faces and on the cube's faces, and NaN
        P[:200] = grid.origin + rng.integers(0, grid.n + 1, (200, 3)) * grid.leaf
        P[200:210] = np.nan
        with np.errstate(invalid="ignore"):  # NaN rows: the cast warns, inside() says no
            flat = grid.flat_of_points(P)
        ref = np.where(flat >= 0, flags[np.maximum(flat, 0)], False)
        ref[200:210] = False
        got = leaf_flags(np.ascontiguousarray(P), grid.origin, grid.leaf, grid.n, flags)
        assert np.array_equal(got, ref)
        assert 0 < got.sum() < (flat >= 0).sum()  # inside and outside, free and not
