"""`astar_kernel.search` (with its goal's flood; and `graph_kernel.expand`,
`successor_costs`) as heapq and array expressions: their fallbacks until compiled.

Why: on a first run (empty kernel cache) the compiled search is pending for most of the
run, and its own Python - one interpreted loop per neighbour node, ~2 ms an expansion -
cost ~4.5 s of the thesis run's plans and re-plans. Here each expansion is ~20 numpy calls
over its neighbour nodes at once (~60 us): the same rules (`graph_kernel.successors_into`:
the 27 neighbour cells, the squeeze rule, the cells' nodes and extra nodes, edge length,
the entered cell's penalty, closed / dead nodes, known-invalid edges) and the same queue
order (heapq on (f, g, node, parent) tuples), so the path is the compiled one's up to ties
that float rounding may break differently (the weighted distance is summed in the same two
lanes, in numpy's order).
"""

from __future__ import annotations

import collections
import heapq
import itertools

import numpy as np

Array = np.ndarray

FOUND, NO_PATH, BUDGET = 0, 1, 2  # as `astar_kernel`
FLOOD_ON, FLOOD_MET, FLOOD_DONE = 0, 1, 2

#: The 27 cell offsets in `itertools.product((-1, 0, 1), repeat=3)` order.
_OFFSETS = np.array(list(itertools.product((-1, 0, 1), repeat=3)), dtype=np.int64)
_AXES = (_OFFSETS != 0).sum(axis=1)


def weighted_distances(q: Array, Q: Array, w: Array) -> Array:
    """||W (Q_i - q)|| per row, the squares summed in two lanes (even and odd joints) as
    `graph_kernel.weighted_distance` sums them."""
    d = (Q - q) * w
    d *= d
    return np.sqrt(d[:, 0::2].sum(axis=1) + d[:, 1::2].sum(axis=1))


def neighbour_cells(cell: int, nx: int, ny: int, nz: int, searchable: Array,
                    squeeze_blocked: Array, exempt: Array) -> Array:
    """`graph_kernel.neighbour_cells` as array expressions."""
    i, j, k = cell // (ny * nz), (cell // nz) % ny, cell % nz
    ijk = np.array([i, j, k]) + _OFFSETS
    inside = ((ijk >= 0) & (ijk < np.array([nx, ny, nz]))).all(axis=1)
    # face neighbours blocked, +1 side then -1 side per axis (False outside the grid)
    faces = np.zeros((3, 2), dtype=bool)
    dims = (nx, ny, nz)
    for axis in range(3):
        for side, step in enumerate((1, -1)):
            f = [i, j, k]
            f[axis] += step
            if 0 <= f[axis] < dims[axis]:
                faces[axis, side] = squeeze_blocked[(f[0] * ny + f[1]) * nz + f[2]]
    off = _OFFSETS[inside]
    flat = (ijk[inside] * np.array([ny * nz, nz, 1])).sum(axis=1)
    blocked = np.zeros(len(off), dtype=np.int64)
    for axis in range(3):
        blocked += np.where(off[:, axis] > 0, faces[axis, 0],
                            np.where(off[:, axis] < 0, faces[axis, 1], False))
    keep = searchable[flat]
    squeeze = (_AXES[inside] >= 2) & (blocked >= 2)
    if squeeze.any() and not _contains(exempt, cell):
        keep &= ~(squeeze & ~np.isin(flat, exempt))
    return flat[keep]


def predecessor_cells(cell: int, nx: int, ny: int, nz: int, searchable: Array,
                      squeeze_blocked: Array, exempt: Array) -> Array:
    """`graph_kernel.predecessor_cells_into` as array expressions: the cells whose steps
    enter `cell`, each candidate's squeeze rule read on its own side."""
    if not searchable[cell]:
        return np.zeros(0, dtype=np.int64)
    here = np.array([cell // (ny * nz), (cell // nz) % ny, cell % nz])
    src = here - _OFFSETS  # the step _OFFSETS[m] from src[m] enters the cell
    inside = ((src >= 0) & (src < np.array([nx, ny, nz]))).all(axis=1)
    off, src = _OFFSETS[inside], src[inside]
    scale = np.array([ny * nz, nz, 1])
    blocked = np.zeros(len(off), dtype=np.int64)
    for axis in range(3):
        face = src.copy()
        face[:, axis] = here[axis]  # src's face neighbour along the step's axis
        blocked += (off[:, axis] != 0) & squeeze_blocked[face @ scale]
    flat = src @ scale
    keep = searchable[flat]
    squeeze = (_AXES[inside] >= 2) & (blocked >= 2)
    if squeeze.any() and not _contains(exempt, cell):
        keep &= ~(squeeze & ~np.isin(flat, exempt))
    return flat[keep]


def neighbour_nodes(u: int, cells: Array, cell_start: Array, extra_cell: Array) -> Array:
    """Node ids of `cells` in `graph_kernel.neighbour_nodes`' order (cell by cell, a cell's
    own nodes ascending, then the graph's extra nodes in it), u left out."""
    lo, hi = cell_start[cells], cell_start[cells + 1]
    counts = hi - lo
    total = int(counts.sum())
    own = (np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
           + np.repeat(lo, counts))
    if extra_cell.shape[0]:
        rank = np.full(len(cell_start), -1)  # each cell's place in `cells`
        rank[cells] = np.arange(len(cells))
        e = np.flatnonzero(rank[extra_cell] >= 0)
        if len(e):
            key = np.concatenate([2 * np.repeat(np.arange(len(cells)), counts),
                                  2 * rank[extra_cell[e]] + 1])
            own = np.concatenate([own, e + cell_start[-1]])[np.argsort(key, kind="stable")]
    return own[own != u]


def successors(u: int, gu: float, nx: int, ny: int, nz: int, searchable: Array,
               squeeze_blocked: Array, exempt: Array, cell_start: Array, node_q: Array,
               node_cell: Array, weights: Array, max_edge: float, penalty: Array,
               extra_cell: Array) -> tuple[Array, Array]:
    """u's neighbour nodes within `max_edge` and the edge costs (weighted joint distance +
    the entered cell's penalty): `graph_kernel.successor_costs`."""
    cells = neighbour_cells(int(node_cell[u]), nx, ny, nz, searchable, squeeze_blocked, exempt)
    vs = neighbour_nodes(u, cells, cell_start, extra_cell)
    d = weighted_distances(node_q[u], node_q[vs], weights)
    ok = d <= max_edge
    vs = vs[ok]
    return vs, d[ok] + penalty[node_cell[vs]]


def successor_costs_numpy(u: int, nx: int, ny: int, nz: int, searchable: Array,
                          squeeze_blocked: Array, exempt: Array, cell_start: Array,
                          node_q: Array, node_cell: Array, weights: Array, max_edge: float,
                          penalty: Array, extra_cell: Array) -> tuple[Array, Array]:
    """`graph_kernel.successor_costs` (its fallback until compiled)."""
    return successors(u, 0.0, nx, ny, nz, searchable, squeeze_blocked, exempt, cell_start,
                      node_q, node_cell, weights, max_edge, penalty, extra_cell)


def expand_numpy(u: int, gu: float, nx: int, ny: int, nz: int, searchable: Array,
                 squeeze_blocked: Array, exempt: Array, cell_start: Array, node_q: Array,
                 node_cell: Array, weights: Array, max_edge: float, penalty: Array,
                 closed: Array, dead: Array, g: Array, parent: Array, h: Array, q_goal: Array,
                 h_weight: float, bad: Array, extra_cell: Array) -> tuple[Array, Array, Array]:
    """`graph_kernel.expand` (its fallback until compiled): the successors u reaches cheaper,
    not closed or dead nor over an edge of `bad`, get g, parent and h in place; returns
    their (f, g, node) in successor order."""
    vs, cost = successors(u, gu, nx, ny, nz, searchable, squeeze_blocked, exempt, cell_start,
                          node_q, node_cell, weights, max_edge, penalty, extra_cell)
    gv = gu + cost
    ok = ~closed[vs] & ~dead[vs] & (gv < g[vs] - 1e-12)
    if bad.shape[0]:
        ok &= ~np.isin(u * node_q.shape[0] + vs, bad)
    vs, gv = vs[ok], gv[ok]
    g[vs] = gv
    parent[vs] = u
    miss = vs[np.isnan(h[vs])]
    if len(miss):
        h[miss] = h_weight * weighted_distances(q_goal, node_q[miss], weights)
    return gv + h[vs], gv, vs


def search_numpy(start: int, goal: int, nx: int, ny: int, nz: int, searchable: Array,
                 squeeze_blocked: Array, exempt: Array, cell_start: Array, node_q: Array,
                 node_cell: Array, weights: Array, max_edge: float, penalty: Array,
                 dead: Array, bad: Array, h: Array, h_weight: float, max_expansions: int,
                 extra_cell: Array) -> tuple[int, Array, float, int]:
    """`astar_kernel.search` (same arguments, same results; h filled in place)."""
    n = node_q.shape[0]
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=bool)
    q_goal = node_q[goal]
    g[start] = 0.0
    heap: list[tuple[float, float, int, int]] = [(0.0, 0.0, int(start), -1)]
    expansions = 0
    grid = (nx, ny, nz, searchable, squeeze_blocked, exempt, cell_start, node_q, node_cell,
            weights, max_edge, dead, bad, g, extra_cell)
    seen = np.zeros(n, dtype=bool)
    seen[goal] = True
    queue = collections.deque([int(goal)])  # the goal's flood (`astar_kernel`)
    if dead[goal]:
        flood = FLOOD_DONE
    elif g[goal] < np.inf:
        flood = FLOOD_MET
    else:
        flood = _flood_step(queue, seen, *grid)
    if flood == FLOOD_DONE:
        return NO_PATH, np.zeros(0, dtype=np.int64), np.inf, expansions
    while heap:
        _, gu, u, p = heapq.heappop(heap)
        if closed[u] or dead[u] or abs(gu - g[u]) > 1e-12 or p != parent[u]:
            continue  # stale entry
        closed[u] = True
        if u == goal:
            path = [goal]
            while parent[path[-1]] >= 0:
                path.append(int(parent[path[-1]]))
            return FOUND, np.array(path[::-1], dtype=np.int64), float(g[goal]), expansions
        expansions += 1
        if expansions > max_expansions:
            return BUDGET, np.zeros(0, dtype=np.int64), np.inf, expansions
        f, gv, vs = expand_numpy(u, gu, nx, ny, nz, searchable, squeeze_blocked, exempt,
                                 cell_start, node_q, node_cell, weights, max_edge, penalty,
                                 closed, dead, g, parent, h, q_goal, h_weight, bad, extra_cell)
        for fv, gg, v in zip(f.tolist(), gv.tolist(), vs.tolist(), strict=True):
            heapq.heappush(heap, (fv, gg, v, u))
        if flood == FLOOD_ON:
            flood = _flood_step(queue, seen, *grid)
            if flood == FLOOD_DONE:
                break
    return NO_PATH, np.zeros(0, dtype=np.int64), np.inf, expansions


def _flood_step(queue: collections.deque, seen: Array, nx: int, ny: int, nz: int,
                searchable: Array, squeeze_blocked: Array, exempt: Array, cell_start: Array,
                node_q: Array, node_cell: Array, weights: Array, max_edge: float,
                dead: Array, bad: Array, g: Array, extra_cell: Array) -> int:
    """`astar_kernel._flood_step` (the queue a deque, consumed from the left)."""
    v = queue.popleft()
    cells = predecessor_cells(int(node_cell[v]), nx, ny, nz, searchable, squeeze_blocked,
                              exempt)
    us = neighbour_nodes(v, cells, cell_start, extra_cell)
    us = us[~seen[us] & ~dead[us]]
    us = us[weighted_distances(node_q[v], node_q[us], weights) <= max_edge]
    if bad.shape[0]:
        us = us[~np.isin(us * node_q.shape[0] + v, bad)]
    if (g[us] < np.inf).any():
        return FLOOD_MET
    seen[us] = True
    queue.extend(us.tolist())
    return FLOOD_ON if queue else FLOOD_DONE


def _contains(sorted_ids: Array, x: int) -> bool:
    p = int(np.searchsorted(sorted_ids, x))
    return p < len(sorted_ids) and sorted_ids[p] == x
