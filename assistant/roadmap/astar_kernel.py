"""A* over a `JointGraph` with no edge checks, as one compiled loop (numba).

Why: the path-first search (`path_first.lazy_path_search`) searches once per round, over the
graph less the edges found invalid so far, and checks only the path it gets. The search
itself then costs next to nothing: the queue, the successors (`graph_kernel.expand`, the same
expansion rule as `astar.lazy_astar`) and the path are all compiled, and the GIL is released
so the page stays responsive during a long search.

The queue holds (f, g, node, parent) tuples in numba's port of Python's heapq, so entries
pop in the order `lazy_astar`'s queue pops them: with no edge known to be invalid both
searches close the same nodes in the same order and return the same path.
"""

from __future__ import annotations

import heapq

import numpy as np
from numba import njit

from assistant.roadmap.graph_kernel import expand

Array = np.ndarray

FOUND = 0
NO_PATH = 1
BUDGET = 2


@njit(cache=True, nogil=True)
def search(start: int, goal: int, nx: int, ny: int, nz: int, searchable: Array,
           squeeze_blocked: Array, exempt: Array, cell_start: Array, node_q: Array,
           node_cell: Array, weights: Array, max_edge: float, penalty: Array, dead: Array,
           bad: Array, h: Array, h_weight: float, max_expansions: int,
           ) -> tuple[int, Array, float, int]:
    """(status, path start..goal, its cost, expansions) of a weighted A* from start to goal
    that never enters a `dead` node nor takes an edge of `bad` (sorted keys u * n + v).

    `h` caches the weighted heuristic per node (NaN = not yet) across calls: it does not
    depend on which edges are known. Status FOUND, NO_PATH, or BUDGET when more than
    `max_expansions` nodes were expanded (counted as `lazy_astar` counts them).
    """
    n = node_q.shape[0]
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    q_goal = node_q[goal]
    g[start] = 0.0
    heap = [(0.0, 0.0, np.int64(start), np.int64(-1))]
    expansions = 0
    while len(heap):
        _, gu, u, p = heapq.heappop(heap)
        if closed[u] or dead[u] or abs(gu - g[u]) > 1e-12 or p != parent[u]:
            continue  # stale entry
        closed[u] = True
        if u == goal:
            m = 1
            v = goal
            while parent[v] >= 0:
                v = parent[v]
                m += 1
            path = np.empty(m, dtype=np.int64)
            v = goal
            for i in range(m - 1, -1, -1):
                path[i] = v
                v = parent[v]
            return FOUND, path, g[goal], expansions
        expansions += 1
        if expansions > max_expansions:
            return BUDGET, np.zeros(0, dtype=np.int64), np.inf, expansions
        f, gn, vs = expand(u, gu, nx, ny, nz, searchable, squeeze_blocked, exempt, cell_start,
                           node_q, node_cell, weights, max_edge, penalty, closed, dead, g,
                           parent, h, q_goal, h_weight, bad)
        for i in range(vs.shape[0]):
            heapq.heappush(heap, (f[i], gn[i], vs[i], u))
    return NO_PATH, np.zeros(0, dtype=np.int64), np.inf, expansions
