"""The compiled brushfire against the numpy formulation it replaced, cell for cell.

The reference below is `voronoi._recompute`'s former numpy code (kept here only as the
reference): four 26-neighbourhood reductions over the box per layer. On random grids, for
full builds and for regions recomputed with the values outside held fixed, both must give
the same distances, tentative labels and labels.
"""

from __future__ import annotations

import numpy as np
import pytest

from assistant.roadmap.brushfire import brushfire_region
from assistant.roadmap.grid_ops import neighbour_any, neighbour_max, neighbour_min
from assistant.roadmap.voronoi import INF, ROAD, ROAD_UNREACHABLE, UNREACHED, build_voronoi

_BIG = np.int32(2**30)


def _reference(D, T, L, S, reach, R):
    src = S > 0
    D[R], T[R], L[R] = INF, UNREACHED, UNREACHED
    rs = R & src
    D[rs], T[rs], L[rs] = 0, S[rs], S[rs]
    todo = R & ~src
    fixed = ~R & (D < INF)
    max_fixed = int(D[fixed].max()) if fixed.any() else -1
    d = 1
    while todo.any():
        prev = D == d - 1
        if not prev.any() and d - 1 > max_fixed:
            break
        has = todo & neighbour_any(prev)
        if has.any():
            D[has] = d
            carrier = prev & (L >= 1)
            lo = neighbour_min(np.where(carrier, L, _BIG), _BIG)[has]
            hi = neighbour_max(np.where(carrier, L, -1), -1)[has]
            tent = np.where((lo == _BIG) | (lo != hi), ROAD, lo).astype(np.int32)
            T[has] = tent
            same = (D == d) & (T >= 1)
            above = neighbour_max(np.where(same, T, -1), -1)[has]
            road = (tent < 1) | (above > tent)
            L[has] = np.where(road, np.where(reach[has], ROAD, ROAD_UNREACHABLE), tent)
            todo &= ~has
        d += 1


def _assert_same_as_reference(base, src, reach, region) -> None:
    """The compiled brushfire and the numpy reference recompute `region` of `base` alike."""
    ref = [base.dist.copy(), base.tent.copy(), base.label.copy()]
    out = [base.dist.copy(), base.tent.copy(), base.label.copy()]
    _reference(*ref, src, reach, region)
    brushfire_region(*out, src, reach, region)
    for a, b in zip(out, ref, strict=True):
        assert np.array_equal(a, b)


def _grid(rng, density: tuple[float, float] = (0.01, 0.2)):
    shape = tuple(int(v) for v in rng.integers(1, 14, 3))
    n_labels = int(rng.integers(1, 6))
    src = np.where(rng.random(shape) < rng.uniform(*density),
                   rng.integers(1, n_labels + 1, shape), 0).astype(np.int32)
    reach = rng.random(shape) < rng.uniform(0.5, 1.0)
    return src, reach


@pytest.mark.parametrize("seed", range(60))
def test_brushfire_equals_numpy_reference(seed: int) -> None:
    """Sparse sources (seeds < 40: the first layers are found from the layer below) and
    dense ones like the planner's, nine cells in ten (the first layer is found from the
    few cells left to reach)."""
    rng = np.random.default_rng(seed)
    src, reach = _grid(rng, (0.01, 0.2) if seed < 40 else (0.6, 0.95))
    # the values outside the region come from the map of other sources (an update)
    other = np.where(rng.random(src.shape) < 0.1, rng.integers(1, 4, src.shape), src)
    base = build_voronoi(other.astype(np.int32), reach)
    for region in (np.ones(src.shape, bool), rng.random(src.shape) < rng.uniform(0.2, 0.9)):
        _assert_same_as_reference(base, src, reach, region)


def test_even_gap_and_unreachable_roads_are_exercised() -> None:
    """The cases above meet both road rules (not only the plain label spread)."""
    kinds = set()
    for seed in range(40):
        rng = np.random.default_rng(seed)
        src, reach = _grid(rng)
        L = build_voronoi(src, reach).label
        kinds |= {int(v) for v in np.unique(L)} & {ROAD, ROAD_UNREACHABLE, UNREACHED}
    assert kinds == {ROAD, ROAD_UNREACHABLE, UNREACHED}


def test_distances_past_the_counted_range_equal_the_reference() -> None:
    """Layers beyond the per-distance counts (64) are found through the distance buckets:
    a long corridor with a source at each end, recomputed whole and in its far part."""
    shape = (150, 2, 1)
    src = np.zeros(shape, np.int32)
    src[0], src[-1, 0] = 1, 2
    reach = np.ones(shape, bool)
    base = build_voronoi(np.where(np.arange(150)[:, None, None] < 140, src, 0).astype(np.int32),
                         reach)
    assert base.dist.max() > 70
    for region in (np.ones(shape, bool), np.arange(150)[:, None, None] > np.full(shape, 90)):
        _assert_same_as_reference(base, src, reach, region)
