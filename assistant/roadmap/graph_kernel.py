"""A search graph node's neighbours as one compiled loop (numba).

Why: the lazy A* asks `JointGraph.successors` once per expansion (~30 times per planning
query), and finding the neighbour cells (27 offsets, the squeeze rule's six faces, the
exempt cells) and their nodes took ~15 numpy calls, ~40 us. The rules are those of
`JointGraph.neighbour_cells` and `nodes_of`, in the same order (offsets as
`itertools.product((-1, 0, 1), repeat=3)`, nodes ascending within a cell).
"""

from __future__ import annotations

import numpy as np
from numba import njit

Array = np.ndarray


@njit(cache=True)
def neighbour_cells(cell: int, nx: int, ny: int, nz: int, searchable: Array,
                    squeeze_blocked: Array, exempt: Array) -> Array:
    """Searchable cells one step from `cell` (itself included), the squeeze rule applied: a
    step along two or three axes is refused when at least two of the face cells it passes
    (those of its axes, in its directions, inside the grid) are blocked, unless it leaves
    or enters a cell of `exempt` (sorted)."""
    i, j, k = cell // (ny * nz), (cell // nz) % ny, cell % nz
    # blocked[2a + (0 if +1 else 1)]: the face neighbour along axis a
    blocked = np.zeros(6, dtype=np.bool_)
    ijk = (i, j, k)
    dims = (nx, ny, nz)
    for a in range(3):
        for side in range(2):
            c = [i, j, k]
            c[a] = ijk[a] + (1 if side == 0 else -1)
            if 0 <= c[a] < dims[a]:
                blocked[2 * a + side] = squeeze_blocked[(c[0] * ny + c[1]) * nz + c[2]]
    cell_exempt = _contains(exempt, cell)
    out = np.empty(27, dtype=np.int64)
    n_out = 0
    for di in range(-1, 2):
        for dj in range(-1, 2):
            for dk in range(-1, 2):
                a, b, c = i + di, j + dj, k + dk
                if not (0 <= a < nx and 0 <= b < ny and 0 <= c < nz):
                    continue
                flat = (a * ny + b) * nz + c
                if (di != 0) + (dj != 0) + (dk != 0) >= 2:
                    n_blocked = 0
                    if di != 0:
                        n_blocked += blocked[0 if di > 0 else 1]
                    if dj != 0:
                        n_blocked += blocked[2 if dj > 0 else 3]
                    if dk != 0:
                        n_blocked += blocked[4 if dk > 0 else 5]
                    if n_blocked >= 2 and not (cell_exempt or _contains(exempt, flat)):
                        continue
                if searchable[flat]:
                    out[n_out] = flat
                    n_out += 1
    return out[:n_out].copy()


@njit(cache=True)
def neighbour_nodes(u: int, cell: int, nx: int, ny: int, nz: int, searchable: Array,
                    squeeze_blocked: Array, exempt: Array, cell_start: Array) -> Array:
    """Node ids of `neighbour_cells` (cell by cell, ascending within a cell), u left out."""
    cells = neighbour_cells(cell, nx, ny, nz, searchable, squeeze_blocked, exempt)
    n = 0
    for c in cells:
        n += cell_start[c + 1] - cell_start[c]
    out = np.empty(n, dtype=np.int64)
    n_out = 0
    for c in cells:
        for v in range(cell_start[c], cell_start[c + 1]):
            if v != u:
                out[n_out] = v
                n_out += 1
    return out[:n_out]


@njit(cache=True)
def _contains(sorted_ids: Array, x: int) -> bool:
    p = np.searchsorted(sorted_ids, x)
    return p < len(sorted_ids) and sorted_ids[p] == x
