"""A search graph node's neighbours as one compiled loop (numba).

Why: the lazy A* asks `JointGraph.successors` once per expansion (~30 times per planning
query), and finding the neighbour cells (27 offsets, the squeeze rule's six faces, the
exempt cells) and their nodes take ~15 numpy calls, ~40 us. The rules are those of
`JointGraph.neighbour_cells` and `nodes_of`, in the same order (offsets as
`itertools.product((-1, 0, 1), repeat=3)`, nodes ascending within a cell).

Serves (the user-felt figure): the search on every plan and re-plan: in the thesis run its
Python form costs 3.1 s. Until compiled (a first run), `search_numpy`'s array forms stand in.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.lazy import kernel
from assistant.roadmap.search_numpy import expand_numpy, successor_costs_numpy

Array = np.ndarray


@kernel(cache=True)
def neighbour_cells(cell: int, nx: int, ny: int, nz: int, searchable: Array,
                    squeeze_blocked: Array, exempt: Array) -> Array:
    """Searchable cells one step from `cell` (itself included), the squeeze rule applied: a
    step along two or three axes is refused when at least two of the face cells it passes
    (those of its axes, in its directions, inside the grid) are blocked, unless it leaves
    or enters a cell of `exempt` (sorted)."""
    out = np.empty(27, dtype=np.int64)
    n = neighbour_cells_into(cell, nx, ny, nz, searchable, squeeze_blocked, exempt, out)
    return out[:n].copy()


@kernel(cache=True)
def neighbour_cells_into(cell: int, nx: int, ny: int, nz: int, searchable: Array,
                         squeeze_blocked: Array, exempt: Array, out: Array) -> int:
    """`neighbour_cells` written into `out` (27 long); returns how many. The A* asks this
    once per expansion: no array of its own (the face flags are scalars)."""
    i, j, k = cell // (ny * nz), (cell // nz) % ny, cell % nz
    # the face neighbour along each axis, +1 then -1 side, blocked (False outside the grid)
    xp = i + 1 < nx and squeeze_blocked[((i + 1) * ny + j) * nz + k]
    xm = i >= 1 and squeeze_blocked[((i - 1) * ny + j) * nz + k]
    yp = j + 1 < ny and squeeze_blocked[(i * ny + j + 1) * nz + k]
    ym = j >= 1 and squeeze_blocked[(i * ny + j - 1) * nz + k]
    zp = k + 1 < nz and squeeze_blocked[(i * ny + j) * nz + k + 1]
    zm = k >= 1 and squeeze_blocked[(i * ny + j) * nz + k - 1]
    cell_exempt = _contains(exempt, cell)
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
                        n_blocked += xp if di > 0 else xm
                    if dj != 0:
                        n_blocked += yp if dj > 0 else ym
                    if dk != 0:
                        n_blocked += zp if dk > 0 else zm
                    if n_blocked >= 2 and not (cell_exempt or _contains(exempt, flat)):
                        continue
                if searchable[flat]:
                    out[n_out] = flat
                    n_out += 1
    return n_out


@kernel(cache=True)
def predecessor_cells_into(cell: int, nx: int, ny: int, nz: int, searchable: Array,
                           squeeze_blocked: Array, exempt: Array, out: Array) -> int:
    """The cells whose `neighbour_cells_into` holds `cell` (itself included), written into
    `out` (27 long); returns how many. A step's squeeze rule reads the face cells on the side
    of the cell it leaves, and a three-axis step passes other face cells one way than the
    other: so each candidate's own rule is applied, not `cell`'s. None if `cell` is not
    searchable (no step enters it)."""
    if not searchable[cell]:
        return 0
    i, j, k = cell // (ny * nz), (cell // nz) % ny, cell % nz
    cell_exempt = _contains(exempt, cell)
    n_out = 0
    for di in range(-1, 2):
        for dj in range(-1, 2):
            for dk in range(-1, 2):
                a, b, c = i - di, j - dj, k - dk  # the step (di, dj, dk) from here enters
                if not (0 <= a < nx and 0 <= b < ny and 0 <= c < nz):
                    continue
                flat = (a * ny + b) * nz + c
                if not searchable[flat]:
                    continue
                if (di != 0) + (dj != 0) + (dk != 0) >= 2:
                    # the face neighbours of (a, b, c) along the step's axes (inside the
                    # grid: each shares `cell`'s coordinate on its axis)
                    n_blocked = 0
                    if di != 0:
                        n_blocked += squeeze_blocked[(i * ny + b) * nz + c]
                    if dj != 0:
                        n_blocked += squeeze_blocked[(a * ny + j) * nz + c]
                    if dk != 0:
                        n_blocked += squeeze_blocked[(a * ny + b) * nz + k]
                    if n_blocked >= 2 and not (cell_exempt or _contains(exempt, flat)):
                        continue
                out[n_out] = flat
                n_out += 1
    return n_out


@kernel(cache=True)
def neighbour_nodes(u: int, cell: int, nx: int, ny: int, nz: int, searchable: Array,
                    squeeze_blocked: Array, exempt: Array, cell_start: Array,
                    extra_cell: Array) -> Array:
    """Node ids of `neighbour_cells` (cell by cell, ascending within a cell, a cell's
    extra nodes after its own), u left out."""
    cells = neighbour_cells(cell, nx, ny, nz, searchable, squeeze_blocked, exempt)
    n_base = cell_start[cell_start.shape[0] - 1]
    n = 0
    for c in cells:
        n += cell_start[c + 1] - cell_start[c]
        for e in range(extra_cell.shape[0]):
            n += extra_cell[e] == c
    out = np.empty(n, dtype=np.int64)
    n_out = 0
    for c in cells:
        hi = cell_start[c + 1]
        for t in range(cell_start[c], hi + extra_cell.shape[0]):
            v = node_of(t, c, hi, n_base, extra_cell)
            if v >= 0 and v != u:
                out[n_out] = v
                n_out += 1
    return out[:n_out]


@kernel(cache=True, inline="always")
def node_of(t: int, c: int, hi: int, n_base: int, extra_cell: Array) -> int:
    """The t-th node of cell c, counting from its first node (`cell_start[c]`) on through
    its own (up to hi = `cell_start[c + 1]`) and then over the graph's extra nodes (ids
    n_base + e, in cell extra_cell[e]): the node id, or -1 for an extra of another cell."""
    if t < hi:
        return t
    e = t - hi
    return n_base + e if extra_cell[e] == c else -1


@kernel(cache=True)
def _contains(sorted_ids: Array, x: int) -> bool:
    p = np.searchsorted(sorted_ids, x)
    return p < len(sorted_ids) and sorted_ids[p] == x


@kernel(cache=True, inline="always")
def weighted_distance(a: Array, b: Array, w: Array) -> float:
    """||W (b - a)||, the squares summed in two lanes (even and odd joints, then the two
    lanes): the order numpy's einsum takes on this kind of machine, fixed here so the
    graph's costs do not depend on which SIMD path numpy picks."""
    even, odd = 0.0, 0.0
    for j in range(a.shape[0]):
        d = (b[j] - a[j]) * w[j]
        if j % 2 == 0:
            even += d * d
        else:
            odd += d * d
    return np.sqrt(even + odd)


@kernel(cache=True)
def weighted_distances(q: Array, Q: Array, w: Array) -> Array:
    """`weighted_distance` from q to each row of Q."""
    out = np.empty(Q.shape[0])
    for i in range(Q.shape[0]):
        out[i] = weighted_distance(q, Q[i], w)
    return out


@kernel(cache=True, fallback=successor_costs_numpy)
def successor_costs(u: int, nx: int, ny: int, nz: int, searchable: Array,
                    squeeze_blocked: Array, exempt: Array, cell_start: Array, node_q: Array,
                    node_cell: Array, weights: Array, max_edge: float, penalty: Array,
                    extra_cell: Array) -> tuple[Array, Array]:
    """`JointGraph.successors`: u's neighbour nodes within `max_edge` and the edge costs
    (weighted joint distance + the entered cell's penalty)."""
    vs = neighbour_nodes(u, node_cell[u], nx, ny, nz, searchable, squeeze_blocked, exempt,
                         cell_start, extra_cell)
    out = np.empty(vs.shape[0], dtype=np.int64)
    cost = np.empty(vs.shape[0])
    n = 0
    for v in vs:
        d = weighted_distance(node_q[u], node_q[v], weights)
        if d <= max_edge:
            out[n] = v
            cost[n] = d + penalty[node_cell[v]]
            n += 1
    return out[:n], cost[:n]


@kernel(cache=True, fallback=expand_numpy)
def expand(u: int, gu: float, nx: int, ny: int, nz: int, searchable: Array,
           squeeze_blocked: Array, exempt: Array, cell_start: Array, node_q: Array,
           node_cell: Array, weights: Array, max_edge: float, penalty: Array, closed: Array,
           dead: Array, g: Array, parent: Array, h: Array, q_goal: Array,
           h_weight: float, bad: Array, extra_cell: Array) -> tuple[Array, Array, Array]:
    """One A* expansion of node u at cost gu (`astar.lazy_astar`): `successors_into` as
    (f, g, node) arrays, in successor order."""
    rows = np.empty((64, 4))
    cells = np.empty(27, dtype=np.int64)
    rows, n = successors_into(u, gu, nx, ny, nz, searchable, squeeze_blocked, exempt,
                              cell_start, node_q, node_cell, weights, max_edge, penalty,
                              closed, dead, g, parent, h, q_goal, h_weight, bad, extra_cell,
                              cells, rows, 0)
    return rows[:n, 0].copy(), rows[:n, 1].copy(), rows[:n, 2].astype(np.int64)


@kernel(cache=True)
def successors_into(u: int, gu: float, nx: int, ny: int, nz: int, searchable: Array,
                    squeeze_blocked: Array, exempt: Array, cell_start: Array, node_q: Array,
                    node_cell: Array, weights: Array, max_edge: float, penalty: Array,
                    closed: Array, dead: Array, g: Array, parent: Array, h: Array,
                    q_goal: Array, h_weight: float, bad: Array, extra_cell: Array,
                    cells: Array, rows: Array, size: int) -> tuple[Array, int]:
    """One A* expansion of node u at cost gu (`astar.lazy_astar`, `astar_kernel.search`):
    the successors (`successor_costs`' nodes and costs) not closed or dead, and not over an
    edge of `bad` (sorted keys u * n + v, edges known to be invalid), that u reaches cheaper
    get g and parent (in place) and are appended as rows (f, g, node, u) to `rows` from row
    `size` on, in successor order (`rows` grows by doubling; `cells` is scratch, 27 long);
    their heuristic (weight x distance to the goal) is computed once per node into h (NaN =
    not yet). Returns `rows` and its new size. Appending to the search's own queue array
    spares the three arrays per expansion (and the successor arrays behind them) that
    returning the successors would take."""
    n_nodes = node_q.shape[0]
    n_base = cell_start[cell_start.shape[0] - 1]
    n_cells = neighbour_cells_into(node_cell[u], nx, ny, nz, searchable, squeeze_blocked,
                                   exempt, cells)
    for ci in range(n_cells):
        c = cells[ci]
        hi = cell_start[c + 1]
        for t in range(cell_start[c], hi + extra_cell.shape[0]):
            v = node_of(t, c, hi, n_base, extra_cell)
            if v < 0 or v == u:
                continue
            d = weighted_distance(node_q[u], node_q[v], weights)
            if not d <= max_edge:
                continue
            gv = gu + (d + penalty[c])  # v is in cell c
            if closed[v] or dead[v] or not gv < g[v] - 1e-12:
                continue
            if bad.shape[0] and _contains(bad, u * n_nodes + v):
                continue
            g[v] = gv
            parent[v] = u
            if np.isnan(h[v]):
                h[v] = h_weight * weighted_distance(q_goal, node_q[v], weights)
            if size == rows.shape[0]:
                more = np.empty((2 * size, 4))
                more[:size] = rows
                rows = more
            rows[size, 0], rows[size, 1], rows[size, 2], rows[size, 3] = gv + h[v], gv, v, u
            size += 1
    return rows, size


@kernel(cache=True)
def select_nodes(cells: Array, offsets: Array, Q: Array, searchable: Array,
                 extra_cells: Array, extra_q: Array, n_cells: int,
                 ) -> tuple[Array, Array, Array, Array]:
    """(node_q, node_cell, cell_start, extra ids) of `JointGraph.build`: the positions of
    the searchable cells (positions of cell i: Q[offsets[i]:offsets[i + 1]]) and then the
    extra nodes, grouped by cell in a counting sort - within a cell the positions in their
    order, then the extras in theirs, as a stable sort by cell gives them (~0.3 ms a
    query as numpy calls)."""
    count = np.zeros(n_cells, dtype=np.int64)
    for i in range(cells.shape[0]):
        if searchable[cells[i]]:
            count[cells[i]] += offsets[i + 1] - offsets[i]
    for e in range(extra_cells.shape[0]):
        count[extra_cells[e]] += 1
    cell_start = np.zeros(n_cells + 1, dtype=np.int64)
    for c in range(n_cells):
        cell_start[c + 1] = cell_start[c] + count[c]
    n = cell_start[n_cells]
    node_q = np.empty((n, Q.shape[1]))
    node_cell = np.empty(n, dtype=np.int64)
    fill = cell_start[:n_cells].copy()
    for i in range(cells.shape[0]):
        c = cells[i]
        if not searchable[c]:
            continue
        for r in range(offsets[i], offsets[i + 1]):
            node_q[fill[c]] = Q[r]
            node_cell[fill[c]] = c
            fill[c] += 1
    ids = np.empty(extra_cells.shape[0], dtype=np.int64)
    for e in range(extra_cells.shape[0]):
        c = extra_cells[e]
        node_q[fill[c]] = extra_q[e]
        node_cell[fill[c]] = c
        ids[e] = fill[c]
        fill[c] += 1
    return node_q, node_cell, cell_start, ids


@kernel(cache=True)
def base_nodes(cells: Array, offsets: Array, Q: Array, n_cells: int, n_extra: int,
               ) -> tuple[Array, Array, Array]:
    """(node_q, node_cell, cell_start) of every cell's positions (`JointGraph.over`'s base):
    node r is Q[r] (positions of cell i: Q[offsets[i]:offsets[i + 1]], the cells
    ascending), and `n_extra` rows follow for a query's extra nodes."""
    n = Q.shape[0]
    cell_start = np.zeros(n_cells + 1, dtype=np.int64)
    for i in range(cells.shape[0]):
        cell_start[cells[i] + 1] = offsets[i + 1] - offsets[i]
    for c in range(n_cells):
        cell_start[c + 1] += cell_start[c]
    node_q = np.zeros((n + n_extra, Q.shape[1]))
    node_q[:n] = Q
    node_cell = np.full(n + n_extra, -1, dtype=np.int64)
    for i in range(cells.shape[0]):
        for r in range(offsets[i], offsets[i + 1]):
            node_cell[r] = cells[i]
    return node_q, node_cell, cell_start
