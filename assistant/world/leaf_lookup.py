"""Per point, a flag of the leaf it lies in (compiled, numba).

The elastic net asks "is each proposed TCP point (and its edge midpoints) in a free leaf?"
once or twice per sweep, a few dozen points at a time; through `OctreeGrid.flat_of_points`
that was six numpy calls and ~40 us per question. The arithmetic is the grid's own:
leaf index floor((p - origin) / leaf) per axis, outside the cube (or NaN) -> False.
"""

from __future__ import annotations

import numpy as np
from numba import njit

Array = np.ndarray


@njit(cache=True)
def leaf_flags(points: Array, origin: Array, leaf: float, n: int, flags: Array) -> Array:
    """flags[flat leaf of each point] for points (N, 3), False outside the grid.

    `flags` is a flat C-order (n, n, n) bool array, as `OctreeGrid.flat_of_ijk` indexes it.
    """
    out = np.zeros(len(points), dtype=np.bool_)
    for p in range(len(points)):
        flat = 0
        inside = True
        for a in range(3):
            f = np.floor((points[p, a] - origin[a]) / leaf)
            if not (f >= 0.0 and f < n):
                inside = False
                break
            flat = flat * n + int(f)
        if inside:
            out[p] = flags[flat]
    return out
