"""The labelled brushfire of `voronoi` over a box of cells, compiled (numba).

Every planning query adds its start and goal as sources and updates the map around them;
the numpy formulation swept four 26-neighbourhood reductions over the whole box per layer
(~5 ms of a query). This loop visits only each layer's front and the cells it reaches. The
rules are those of the `voronoi` module docstring, integer for integer (the test compares
both formulations on random grids and incremental updates).
"""

from __future__ import annotations

import numpy as np
from numba import njit

Array = np.ndarray

ROAD = -1
ROAD_UNREACHABLE = 0
UNREACHED = -2
INF = 2**30
_BIG = 2**30


@njit(cache=True)
def brushfire_region(D: Array, T: Array, L: Array, S: Array, reach: Array, R: Array) -> None:
    """Recompute dist D, tentative label T and label L (int32, in place) inside region R
    with the values outside held fixed. S: source labels (> 0), reach: reachable cells."""
    nx, ny, nz = D.shape
    todo = np.zeros(D.shape, dtype=np.bool_)
    n_todo = 0
    max_fixed = -1
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if R[i, j, k]:
                    if S[i, j, k] > 0:
                        D[i, j, k], T[i, j, k], L[i, j, k] = 0, S[i, j, k], S[i, j, k]
                    else:
                        D[i, j, k], T[i, j, k], L[i, j, k] = INF, UNREACHED, UNREACHED
                        todo[i, j, k] = True
                        n_todo += 1
                elif D[i, j, k] < INF:
                    max_fixed = max(max_fixed, D[i, j, k])
    stamp = np.zeros(D.shape, dtype=np.int32)  # the layer a cell was last put on the front
    cap = nx * ny * nz
    hx = np.empty(cap, dtype=np.int64)
    hy = np.empty(cap, dtype=np.int64)
    hz = np.empty(cap, dtype=np.int64)
    buf = np.empty(cap, dtype=np.int32)
    d = 1
    while n_todo > 0:
        # cells of the layer below with an unreached neighbour: the new layer
        n_prev = 0
        n_has = 0
        for i in range(nx):
            for j in range(ny):
                for k in range(nz):
                    if D[i, j, k] != d - 1:
                        continue
                    n_prev += 1
                    for a in range(max(i - 1, 0), min(i + 2, nx)):
                        for b in range(max(j - 1, 0), min(j + 2, ny)):
                            for c in range(max(k - 1, 0), min(k + 2, nz)):
                                if todo[a, b, c] and stamp[a, b, c] != d:
                                    stamp[a, b, c] = d
                                    hx[n_has], hy[n_has], hz[n_has] = a, b, c
                                    n_has += 1
        if n_prev == 0 and d - 1 > max_fixed:
            break  # no front left that could reach the remaining cells
        # tentative label: the one label the layer below carries here, else ROAD
        for h in range(n_has):
            i, j, k = hx[h], hy[h], hz[h]
            lo, hi = _BIG, -1
            for a in range(max(i - 1, 0), min(i + 2, nx)):
                for b in range(max(j - 1, 0), min(j + 2, ny)):
                    for c in range(max(k - 1, 0), min(k + 2, nz)):
                        if D[a, b, c] == d - 1 and L[a, b, c] >= 1:
                            lo = min(lo, L[a, b, c])
                            hi = max(hi, L[a, b, c])
            buf[h] = ROAD if (lo == _BIG or lo != hi) else lo
        for h in range(n_has):
            D[hx[h], hy[h], hz[h]] = d
            T[hx[h], hy[h], hz[h]] = buf[h]
        # even gaps: a neighbour on the same layer with a larger tentative label wins
        for h in range(n_has):
            i, j, k = hx[h], hy[h], hz[h]
            tent = buf[h]
            above = -1
            for a in range(max(i - 1, 0), min(i + 2, nx)):
                for b in range(max(j - 1, 0), min(j + 2, ny)):
                    for c in range(max(k - 1, 0), min(k + 2, nz)):
                        if (a != i or b != j or c != k) and D[a, b, c] == d \
                                and T[a, b, c] >= 1:
                            above = max(above, T[a, b, c])
            if tent < 1 or above > tent:
                buf[h] = ROAD if reach[i, j, k] else ROAD_UNREACHABLE
        for h in range(n_has):
            L[hx[h], hy[h], hz[h]] = buf[h]
            todo[hx[h], hy[h], hz[h]] = False
        n_todo -= n_has
        d += 1
