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


def _flat_numpy(grid: OctreeGrid, P: np.ndarray) -> np.ndarray:
    """`flat_of_points` as the grid's numpy steps (the compiled pass must match it)."""
    with np.errstate(invalid="ignore"):  # NaN/inf rows: the cast warns, inside() says no
        ijk = grid.ijk_of_points(P)
    out = grid.flat_of_ijk(np.clip(ijk, 0, grid.n - 1))
    out[~grid.inside(ijk)] = -1
    return out


def test_flat_of_points_equals_numpy_indexing() -> None:
    rng = np.random.default_rng(4)
    grids = (OctreeGrid.for_leaf(2.0, 0.0625), OctreeGrid.for_leaf(1.0, 0.03, (0.2, -0.1, 0.3)))
    for grid in grids:
        P = rng.uniform(-1.3, 1.3, (5000, 3)) + grid.origin + grid.size / 2
        P[:200] = grid.origin + rng.integers(0, grid.n + 1, (200, 3)) * grid.leaf
        P[200:210] = np.nan
        P[210:215, 1] = np.inf
        P[215:220, 2] = -np.inf
        P[220:225] = 1e30  # beyond int64 once divided by the leaf
        P[225:230] = grid.origin - 1e-12  # just below the cube
        got = grid.flat_of_points(P)
        ref = _flat_numpy(grid, P)
        assert got.dtype == np.int64 and np.array_equal(got, ref)
        assert (got[200:230] == -1).all()
        assert 0 < (got >= 0).sum() < len(P)
        one = grid.flat_of_points(P[300])  # a single point as (3,)
        assert one.shape == (1,) and one[0] == ref[300]
