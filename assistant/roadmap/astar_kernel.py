"""A* over a `JointGraph` with no edge checks, as one compiled loop (numba).

Why: the path-first search (`path_first.lazy_path_search`) searches once per round, over the
graph less the edges found invalid so far, and checks only the path it gets. The search
itself then costs next to nothing: the queue, the successors (`graph_kernel.expand`, the same
expansion rule as `astar.lazy_astar`) and the path are all compiled, and the GIL is released
so the page stays responsive during a long search.

The queue is a binary heap of (f, g, node, parent) rows in one float array, ordered as
Python compares those tuples and kept by heapq's own algorithm (`_sift_down`, `_sift_up`),
so entries pop in the order `lazy_astar`'s heapq pops them: with no edge known to be invalid
both searches close the same nodes in the same order and return the same path. (One
float array, because numba's heapq on a list of tuples is ~15 % slower; the expansion
appends its successors to the heap array itself, `graph_kernel.successors_into`.)

A search that finds no path ends as soon as either side is known to be cut off: beside the
A* from the start, a breadth-first flood from the goal over the reversed edges takes one node
per expansion (`_flood_step`). When the flood runs out without meeting a node the A* has
reached, no node the A* could still reach leads to the goal: "no path" at once, instead of
after closing every node the start reaches. After a collision indication the goal's side is
often the small one - a goal whose cell's positions lost every edge is known after one step,
where the A* had closed 18 000-41 000 of the UR5 cell's 65 000 positions (0.1-0.4 s a
search, several searches a re-plan). The flood never changes a path found: it reads the
A*'s g and writes nothing the A* reads; once it meets a reached node (a path exists) it
stops. Its work is at most the A*'s, one node per expansion.

Serves (the user-felt figure): the A* of every plan and re-plan: 0.4 s in Python in the
thesis run. Until compiled (a first run), `search_numpy` stands in for it.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.lazy import kernel
from assistant.roadmap.graph_kernel import (
    _contains,
    node_of,
    predecessor_cells_into,
    successors_into,
    weighted_distance,
)
from assistant.roadmap.search_numpy import search_numpy

Array = np.ndarray

FOUND = 0
NO_PATH = 1
BUDGET = 2

#: `_flood_step`'s states: flooding on; met a node the A* reached (a path exists, the flood
#: stops); ran out (no path).
FLOOD_ON = 0
FLOOD_MET = 1
FLOOD_DONE = 2


@kernel(cache=True, nogil=True, fallback=search_numpy)
def search(start: int, goal: int, nx: int, ny: int, nz: int, searchable: Array,
           squeeze_blocked: Array, exempt: Array, cell_start: Array, node_q: Array,
           node_cell: Array, weights: Array, max_edge: float, penalty: Array, dead: Array,
           bad: Array, h: Array, h_weight: float, max_expansions: int, extra_cell: Array,
           ) -> tuple[int, Array, float, int]:
    """(status, path start..goal, its cost, expansions) of a weighted A* from start to goal
    that never enters a `dead` node nor takes an edge of `bad` (sorted keys u * n + v).

    `h` caches the weighted heuristic per node (NaN = not yet) across calls: it does not
    depend on which edges are known. Status FOUND, NO_PATH, or BUDGET when more than
    `max_expansions` nodes were expanded (counted as `lazy_astar` counts them; the goal's
    flood, module docstring, is not counted: it may end the search with NO_PATH earlier).
    `extra_cell`: `JointGraph.extra_cell`.
    """
    n = node_q.shape[0]
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    q_goal = node_q[goal]
    g[start] = 0.0
    heap = np.empty((1024, 4))  # rows (f, g, node, parent); node ids < 2**53 are exact
    heap[0, 0], heap[0, 1], heap[0, 2], heap[0, 3] = 0.0, 0.0, start, -1.0
    size = 1
    cells = np.empty(27, dtype=np.int64)
    expansions = 0
    # the goal's flood: a FIFO of the nodes known to reach the goal
    queue = np.empty(n, dtype=np.int64)
    seen = np.zeros(n, dtype=np.bool_)
    queue[0], seen[goal] = goal, True
    head, tail, flood = 0, 1, FLOOD_ON
    if dead[goal]:
        flood = FLOOD_DONE
    elif g[goal] < np.inf:  # start == goal
        flood = FLOOD_MET
    else:
        head, tail, flood = _flood_step(queue, seen, head, tail, nx, ny, nz, searchable,
                                        squeeze_blocked, exempt, cell_start, node_q,
                                        node_cell, weights, max_edge, dead, bad, g,
                                        extra_cell, cells)
    if flood == FLOOD_DONE:
        return NO_PATH, np.zeros(0, dtype=np.int64), np.inf, expansions
    while size > 0:
        gu, u, p = heap[0, 1], np.int64(heap[0, 2]), np.int64(heap[0, 3])
        size -= 1  # heappop: the last row replaces the root and sifts
        if size > 0:
            heap[0, 0], heap[0, 1] = heap[size, 0], heap[size, 1]
            heap[0, 2], heap[0, 3] = heap[size, 2], heap[size, 3]
            _sift_up(heap, size)
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
        first = size
        heap, size = successors_into(u, gu, nx, ny, nz, searchable, squeeze_blocked, exempt,
                                     cell_start, node_q, node_cell, weights, max_edge,
                                     penalty, closed, dead, g, parent, h, q_goal, h_weight,
                                     bad, extra_cell, cells, heap, size)
        for r in range(first, size):  # heappush of each, in order (the rows after r are
            _sift_down(heap, 0, r)    # not on r's path to the root)
        if flood == FLOOD_ON:
            head, tail, flood = _flood_step(queue, seen, head, tail, nx, ny, nz, searchable,
                                            squeeze_blocked, exempt, cell_start, node_q,
                                            node_cell, weights, max_edge, dead, bad, g,
                                            extra_cell, cells)
            if flood == FLOOD_DONE:
                break
    return NO_PATH, np.zeros(0, dtype=np.int64), np.inf, expansions


@kernel(cache=True)
def _flood_step(queue: Array, seen: Array, head: int, tail: int, nx: int, ny: int, nz: int,
                searchable: Array, squeeze_blocked: Array, exempt: Array,
                cell_start: Array, node_q: Array, node_cell: Array, weights: Array,
                max_edge: float, dead: Array, bad: Array, g: Array, extra_cell: Array,
                cells: Array) -> tuple[int, int, int]:
    """One step of the goal's flood (module docstring): the queue's next node v gets the
    nodes u whose edge u -> v the search would take (v among u's successors: the cells of
    `predecessor_cells_into`, u not dead, the edge within `max_edge` and not in `bad`)
    queued as `seen`. Returns (head, tail, state): FLOOD_MET when such a u has a finite g
    (the A* reached it: a path exists), FLOOD_DONE when the queue ran out, else FLOOD_ON.
    `cells` is scratch, 27 long."""
    v = queue[head]
    head += 1
    n_nodes = node_q.shape[0]
    n_base = cell_start[cell_start.shape[0] - 1]
    n_cells = predecessor_cells_into(node_cell[v], nx, ny, nz, searchable, squeeze_blocked,
                                     exempt, cells)
    for ci in range(n_cells):
        c = cells[ci]
        hi = cell_start[c + 1]
        for t in range(cell_start[c], hi + extra_cell.shape[0]):
            u = node_of(t, c, hi, n_base, extra_cell)
            if u < 0 or u == v or seen[u] or dead[u]:
                continue
            if not weighted_distance(node_q[u], node_q[v], weights) <= max_edge:
                continue
            if bad.shape[0] and _contains(bad, u * n_nodes + v):
                continue
            if g[u] < np.inf:
                return head, tail, FLOOD_MET
            seen[u] = True
            queue[tail] = u
            tail += 1
    return head, tail, FLOOD_DONE if head == tail else FLOOD_ON


@kernel(cache=True, inline="always")
def _before(f: float, g: float, v: float, p: float, heap: Array, b: int) -> bool:
    """(f, g, v, p) < row b as Python compares the tuples (f, g, node, parent)."""
    if f != heap[b, 0]:
        return f < heap[b, 0]
    if g != heap[b, 1]:
        return g < heap[b, 1]
    if v != heap[b, 2]:
        return v < heap[b, 2]
    return p < heap[b, 3]


@kernel(cache=True)
def _sift_down(heap: Array, start: int, pos: int) -> None:
    """heapq's `_siftdown`: the row at pos moves up towards `start` past larger parents."""
    f, g, v, p = heap[pos, 0], heap[pos, 1], heap[pos, 2], heap[pos, 3]
    while pos > start:
        up = (pos - 1) >> 1
        if _before(f, g, v, p, heap, up):
            heap[pos, 0], heap[pos, 1] = heap[up, 0], heap[up, 1]
            heap[pos, 2], heap[pos, 3] = heap[up, 2], heap[up, 3]
            pos = up
            continue
        break
    heap[pos, 0], heap[pos, 1], heap[pos, 2], heap[pos, 3] = f, g, v, p


@kernel(cache=True)
def _sift_up(heap: Array, end: int) -> None:
    """heapq's `_siftup` from the root over rows [0, end): the smaller child moves up to the
    leaves, then the root's row sifts down from there."""
    pos = 0
    f, g, v, p = heap[0, 0], heap[0, 1], heap[0, 2], heap[0, 3]
    child = 1
    while child < end:
        if child + 1 < end and not _before(heap[child, 0], heap[child, 1], heap[child, 2],
                                           heap[child, 3], heap, child + 1):
            child += 1
        heap[pos, 0], heap[pos, 1] = heap[child, 0], heap[child, 1]
        heap[pos, 2], heap[pos, 3] = heap[child, 2], heap[child, 3]
        pos = child
        child = 2 * pos + 1
    heap[pos, 0], heap[pos, 1], heap[pos, 2], heap[pos, 3] = f, g, v, p
    _sift_down(heap, 0, pos)
