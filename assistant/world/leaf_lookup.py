"""Per point, the leaf it lies in or that leaf's flag (compiled, numba).

The elastic net asks "is each proposed TCP point (and its edge midpoints) in a free leaf?"
once or twice per sweep, a few dozen points at a time; through `OctreeGrid.flat_of_points`
that is six numpy calls and ~40 us per question. The arithmetic is the grid's own:
leaf index floor((p - origin) / leaf) per axis, outside the cube (or NaN) -> False.

Serves (the user-felt figure): the octree lookups of the net and the world build: 0.3 s in
Python in the thesis run.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.lazy import kernel

Array = np.ndarray


@kernel(cache=True)
def leaf_flags(points: Array, origin: Array, leaf: float, n: int, flags: Array) -> Array:
    """flags[flat leaf of each point] for points (N, 3), False outside the grid.

    `flags` is a flat C-order (n, n, n) bool array, as `OctreeGrid.flat_of_ijk` indexes it.
    """
    out = np.zeros(len(points), dtype=np.bool_)
    for p in range(len(points)):
        out[p] = leaf_flag(points[p, 0], points[p, 1], points[p, 2], origin, leaf, n, flags)
    return out


@kernel(cache=True, inline="always")
def leaf_flag(x: float, y: float, z: float, origin: Array, leaf: float, n: int,
              flags: Array) -> bool:
    """`leaf_flags` of one point; also called per point by compiled planners
    (`trajectory.net_kernel`)."""
    fx = np.floor((x - origin[0]) / leaf)
    fy = np.floor((y - origin[1]) / leaf)
    fz = np.floor((z - origin[2]) / leaf)
    if not (fx >= 0.0 and fx < n and fy >= 0.0 and fy < n and fz >= 0.0 and fz < n):
        return False
    return flags[(int(fx) * n + int(fy)) * n + int(fz)]


@kernel(cache=True)
def leaf_indices(points: Array, origin: Array, leaf: float, n: int) -> Array:
    """Flat C-order leaf index of each point (N, 3), -1 outside the grid or not finite.

    `OctreeGrid.flat_of_points` in one pass: its five numpy calls cost ~12 us even for
    the two points (a query's start and goal TCP) a planning query asks about."""
    out = np.empty(len(points), dtype=np.int64)
    for p in range(len(points)):
        fx = np.floor((points[p, 0] - origin[0]) / leaf)
        fy = np.floor((points[p, 1] - origin[1]) / leaf)
        fz = np.floor((points[p, 2] - origin[2]) / leaf)
        if fx >= 0.0 and fx < n and fy >= 0.0 and fy < n and fz >= 0.0 and fz < n:
            out[p] = (int(fx) * n + int(fy)) * n + int(fz)
        else:
            out[p] = -1
    return out
