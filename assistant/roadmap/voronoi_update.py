"""The rounds of `voronoi.update_voronoi`, compiled (numba).

Every planning query adds its start and goal as sources and updates the map around them.
As numpy calls the rounds' bookkeeping (dilations through scipy, bounding boxes, copies and
comparisons of the whole grid) cost more than the brushfire itself (~1.2 of 1.7 ms a
query); here each step touches only the bounding box of what it works on. The logic is
`update_voronoi`'s, step for step (its docstring); the tests compare with full rebuilds.

Serves (the user-felt figure): the roads' update around start and goal on every plan and re-
plan: 0.8 s in Python in the thesis run.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.lazy import kernel
from assistant.roadmap.brushfire import brushfire_region

Array = np.ndarray


@kernel(cache=True)
def _box(mask: Array, margin: int) -> tuple[int, int, int, int, int, int]:
    """Bounding box of the True cells grown by margin, clipped; lo > hi if none."""
    nx, ny, nz = mask.shape
    lo0, lo1, lo2, hi0, hi1, hi2 = nx, ny, nz, -1, -1, -1
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if mask[i, j, k]:
                    lo0, hi0 = min(lo0, i), max(hi0, i)
                    lo1, hi1 = min(lo1, j), max(hi1, j)
                    lo2, hi2 = min(lo2, k), max(hi2, k)
    if hi0 < 0:
        return 1, 1, 1, 0, 0, 0
    return (max(0, lo0 - margin), max(0, lo1 - margin), max(0, lo2 - margin),
            min(nx - 1, hi0 + margin), min(ny - 1, hi1 + margin), min(nz - 1, hi2 + margin))


@kernel(cache=True)
def _grow(box: tuple[int, int, int, int, int, int], r: int, shape: tuple[int, int, int],
          ) -> tuple[int, int, int, int, int, int]:
    a0, a1, a2, b0, b1, b2 = box
    return (max(0, a0 - r), max(0, a1 - r), max(0, a2 - r), min(shape[0] - 1, b0 + r),
            min(shape[1] - 1, b1 + r), min(shape[2] - 1, b2 + r))


@kernel(cache=True)
def _dilate(mask: Array, radius: int, box: tuple[int, int, int, int, int, int]) -> Array:
    """Cells within Chebyshev distance `radius` of a True cell (`grid_ops.dilate`), the
    True cells lying in `box` (inclusive): the cube is separable, three running maxima
    over the box grown by the radius."""
    out = np.zeros(mask.shape, dtype=np.bool_)
    if box[3] < box[0]:
        return out
    a0, a1, a2, b0, b1, b2 = _grow(box, radius, mask.shape)
    nx, ny, nz = b0 - a0 + 1, b1 - a1 + 1, b2 - a2 + 1
    A = np.zeros((nx, ny, nz), dtype=np.bool_)
    B = np.zeros((nx, ny, nz), dtype=np.bool_)
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                A[i, j, k] = mask[a0 + i, a1 + j, a2 + k]
    box_out = out[a0:b0 + 1, a1:b1 + 1, a2:b2 + 1]
    _max_along_last(A, B, radius)  # along k, then j, then i (transposed views)
    _max_along_last(B.transpose(0, 2, 1), A.transpose(0, 2, 1), radius)
    _max_along_last(A.transpose(1, 2, 0), box_out.transpose(1, 2, 0), radius)
    return out


@kernel(cache=True)
def _max_along_last(src: Array, dst: Array, radius: int) -> None:
    """dst = running maximum (any True) of src over +-radius along the last axis."""
    nx, ny, nz = src.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                v = False
                for c in range(max(0, k - radius), min(nz, k + radius + 1)):
                    if src[i, j, c]:
                        v = True
                        break
                dst[i, j, k] = v


@kernel(cache=True)
def update_rounds(D0: Array, T0: Array, L0: Array, S: Array, reach: Array, changed: Array,
                  d_min: int, max_rounds: int,
                  ) -> tuple[Array, Array, Array, Array, int, int, bool]:
    """(dist, tent, label, changed cells, region cells, rounds, done) of the update of the
    map (D0, T0, L0) to the sources S; `done` False: the region kept growing for
    `max_rounds` rounds and the caller rebuilds. `changed` flags the cells whose source
    label differs (at least one)."""
    shape = D0.shape
    box = _box(changed, 0)
    region = _dilate(changed, d_min, box)
    box = _grow(box, d_min, shape)  # region's cells lie in box
    D, T, L = D0.copy(), T0.copy(), L0.copy()
    diff = np.zeros(shape, dtype=np.bool_)
    ring_diff = np.zeros(shape, dtype=np.bool_)
    for rnd in range(1, max_rounds + 1):
        grown = _dilate(region, 1, box)  # region and its ring
        gbox = _grow(box, 1, shape)
        if rnd > 1:  # the first round starts from the fresh copies
            D[:], T[:], L[:] = D0, T0, L0
            diff[:] = False
            ring_diff[:] = False
        a0, a1, a2, b0, b1, b2 = _grow(gbox, 1, shape)
        Db = np.ascontiguousarray(D[a0:b0 + 1, a1:b1 + 1, a2:b2 + 1])
        Tb = np.ascontiguousarray(T[a0:b0 + 1, a1:b1 + 1, a2:b2 + 1])
        Lb = np.ascontiguousarray(L[a0:b0 + 1, a1:b1 + 1, a2:b2 + 1])
        brushfire_region(Db, Tb, Lb, np.ascontiguousarray(S[a0:b0 + 1, a1:b1 + 1, a2:b2 + 1]),
                         np.ascontiguousarray(reach[a0:b0 + 1, a1:b1 + 1, a2:b2 + 1]),
                         np.ascontiguousarray(grown[a0:b0 + 1, a1:b1 + 1, a2:b2 + 1]))
        any_ring = False
        cells = 0
        r0, r1, r2, s0, s1, s2 = shape[0], shape[1], shape[2], -1, -1, -1  # ring_diff's box
        for i in range(a0, b0 + 1):
            for j in range(a1, b1 + 1):
                for k in range(a2, b2 + 1):
                    if not grown[i, j, k]:
                        continue
                    cells += 1
                    x, y, z = i - a0, j - a1, k - a2
                    D[i, j, k], T[i, j, k], L[i, j, k] = Db[x, y, z], Tb[x, y, z], Lb[x, y, z]
                    if (D[i, j, k] != D0[i, j, k] or T[i, j, k] != T0[i, j, k]
                            or L[i, j, k] != L0[i, j, k]):
                        diff[i, j, k] = True
                        if not region[i, j, k]:
                            ring_diff[i, j, k] = True
                            any_ring = True
                            r0, r1, r2 = min(r0, i), min(r1, j), min(r2, k)
                            s0, s1, s2 = max(s0, i), max(s1, j), max(s2, k)
        if not any_ring:
            return D, T, L, diff, cells, rnd, True
        rbox = (r0, r1, r2, s0, s1, s2)
        more = _dilate(ring_diff, d_min, rbox)
        mbox = _grow(rbox, d_min, shape)
        c0, c1, c2 = min(gbox[0], mbox[0]), min(gbox[1], mbox[1]), min(gbox[2], mbox[2])
        e0, e1, e2 = max(gbox[3], mbox[3]), max(gbox[4], mbox[4]), max(gbox[5], mbox[5])
        for i in range(c0, e0 + 1):
            for j in range(c1, e1 + 1):
                for k in range(c2, e2 + 1):
                    region[i, j, k] = grown[i, j, k] or more[i, j, k]
        box = (c0, c1, c2, e0, e1, e2)
    return D, T, L, diff, 0, max_rounds, False


@kernel(cache=True)
def terminal_round(D0: Array, T0: Array, L0: Array, S0: Array, reach: Array, cells: Array,
                   labels: Array, d_min: int) -> tuple[Array, bool]:
    """The label grid of the map (D0, T0, L0) with sources `labels` put on the flat `cells`
    (a query's start and goal), by the first round of `update_rounds` alone, on the bounding
    box of its region only; False if that round's ring changed (the caller then runs the
    whole update).

    Why: the query needs only the labels, and only one round in twenty grows. Without the
    general update's whole-grid steps (scanning the changed flags for their box, full-grid
    masks, copies of the distance and tentative grids) the same round costs ~0.1 ms less.
    The region is `update_rounds`': the cells within `d_min` (Chebyshev) of a cell whose
    source changes, and its one-cell ring."""
    nx, ny, nz = D0.shape
    n = cells.shape[0]
    ci = np.empty((n, 3), dtype=np.int64)
    m = 0
    lo0, lo1, lo2, hi0, hi1, hi2 = nx, ny, nz, -1, -1, -1
    for c in range(n):
        i, j, k = cells[c] // (ny * nz), (cells[c] // nz) % ny, cells[c] % nz
        if S0[i, j, k] == labels[c]:
            continue
        ci[m, 0], ci[m, 1], ci[m, 2] = i, j, k
        m += 1
        lo0, lo1, lo2 = min(lo0, i), min(lo1, j), min(lo2, k)
        hi0, hi1, hi2 = max(hi0, i), max(hi1, j), max(hi2, k)
    L = L0.copy()
    if m == 0:
        return L, True
    # the brushfire's box: the region's, grown by the ring and by one more cell (the ring's
    # neighbours are read, held fixed)
    a0, a1, a2 = max(0, lo0 - d_min - 2), max(0, lo1 - d_min - 2), max(0, lo2 - d_min - 2)
    b0 = min(nx - 1, hi0 + d_min + 2)
    b1 = min(ny - 1, hi1 + d_min + 2)
    b2 = min(nz - 1, hi2 + d_min + 2)
    sx, sy, sz = b0 - a0 + 1, b1 - a1 + 1, b2 - a2 + 1
    Db = np.empty((sx, sy, sz), dtype=D0.dtype)
    Tb = np.empty((sx, sy, sz), dtype=T0.dtype)
    Lb = np.empty((sx, sy, sz), dtype=L0.dtype)
    Sb = np.empty((sx, sy, sz), dtype=S0.dtype)
    Rb = np.empty((sx, sy, sz), dtype=np.bool_)
    ring = np.zeros((sx, sy, sz), dtype=np.bool_)
    grown = np.zeros((sx, sy, sz), dtype=np.bool_)
    for x in range(sx):
        for y in range(sy):
            for z in range(sz):
                i, j, k = a0 + x, a1 + y, a2 + z
                Db[x, y, z], Tb[x, y, z], Lb[x, y, z] = D0[i, j, k], T0[i, j, k], L0[i, j, k]
                Sb[x, y, z], Rb[x, y, z] = S0[i, j, k], reach[i, j, k]
                near = nx + ny + nz  # Chebyshev distance to the nearest changed cell
                for c in range(m):
                    near = min(near, max(abs(i - ci[c, 0]), abs(j - ci[c, 1]),
                                         abs(k - ci[c, 2])))
                grown[x, y, z] = near <= d_min + 1
                ring[x, y, z] = near == d_min + 1
    for c in range(m):
        Sb[ci[c, 0] - a0, ci[c, 1] - a1, ci[c, 2] - a2] = labels[c]
    brushfire_region(Db, Tb, Lb, Sb, Rb, grown)
    for x in range(sx):
        for y in range(sy):
            for z in range(sz):
                if not grown[x, y, z]:
                    continue
                i, j, k = a0 + x, a1 + y, a2 + z
                if ring[x, y, z] and (Db[x, y, z] != D0[i, j, k] or Tb[x, y, z] != T0[i, j, k]
                                      or Lb[x, y, z] != L0[i, j, k]):
                    return L, False
                L[i, j, k] = Lb[x, y, z]
    return L, True
