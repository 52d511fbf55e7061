"""The search graph: joint positions stored in cells, edges between neighbouring cells.

Nodes are joint positions (the valid positions a leaf offers, plus the start and goal
postures); the A* never searches cell centres (thesis §8.5.6: joint positions give exact
distances, decoupled from the cell size). Every node of a cell connects to every node of the
cell itself and of its 26 neighbours, except across a *corner squeeze*: a diagonal step whose
face neighbours along two (or three) of its axes include at least two blocked cells passes
between them, which the arm's volume forbids (thesis Fig. 23). Steps out of or into cells
named `squeeze_exempt` (the planner names the start's or goal's) are exempt: a point taught
next to a table or a part sits in a cell whose face neighbours are the part, and the rule can
cut it off although a plain move up and away is free (every edge is still checked exactly by
the lazy search). The planner exempts a terminal only when the rule leaves it no edge, or as
a last try: elsewhere the rule keeps paths from squeezing past what was just hit.

Cost of an edge u -> v: the arm-radius-weighted Euclidean joint distance ||W (q_v - q_u)||
(W = arm radii, so it approximates how far the arm travels, metres) plus the occupancy penalty
of v's cell. Edges longer than `max_edge` (joint part) are left out. The heuristic ||W (q -
q_goal)|| is consistent because the penalty is >= 0.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from assistant.roadmap.graph_kernel import (
    base_nodes,
    neighbour_cells,
    select_nodes,
    successor_costs,
    weighted_distances,
)

Array = np.ndarray

@dataclass
class JointGraph:
    """Nodes grouped by cell (CSR over flat cell ids) and the cell masks of the search.

    The nodes of cell c are cell_start[c]:cell_start[c + 1] and then those of the extra
    nodes (ids cell_start[-1] + e, after all the others) with extra_cell[e] == c. `build`
    selects the searchable cells' positions and sorts the extras in (no extra_cell);
    `over` puts the extras after the positions of every cell, which a `GraphBase` holds
    once, so a planning query copies nothing."""

    shape: tuple[int, int, int]
    node_q: Array  # (n, dof)
    node_cell: Array  # (n,) flat cell of each node, ascending up to cell_start[-1]
    cell_start: Array  # (n_cells + 1,) nodes of cell c: cell_start[c]:cell_start[c + 1]
    searchable: Array  # (n_cells,) bool
    squeeze_blocked: Array  # (n_cells,) bool: cells a diagonal step may not squeeze between
    penalty: Array  # (n_cells,) float: cost added when entering the cell
    weights: Array  # (dof,)
    max_edge: float = np.inf
    #: Cells (sorted) whose steps in or out the squeeze rule spares: start or goal cells.
    squeeze_exempt: Array = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    #: Cells of the extra nodes kept after the cells' own (see the class docstring).
    extra_cell: Array = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @staticmethod
    def over(base: GraphBase, searchable: Array, squeeze_blocked: Array, penalty: Array,
             weights: Array, extra: list[tuple[int, Array]], max_edge: float = np.inf,
             squeeze_exempt: Sequence[int] = ()) -> tuple[JointGraph, list[int]]:
        """`build`'s graph over the positions of `base`, which the searchable mask limits
        (the search never enters another cell), with the `extra` (cell, q) nodes written
        into the base's spare rows: the graph is valid until the next `over` the same base
        (a planning query's searches share their start and goal). The same searches as
        over `build`'s graph, node for node (other ids; `build`'s graph itself when an
        extra sits in an unsearchable cell with positions, or more extras than spare rows
        come); the copy of the searchable cells' positions `build` makes costs ~0.1 ms a
        query."""
        k = len(extra)
        n_base = int(base.cell_start[-1])
        searchable = np.asarray(searchable, bool).reshape(-1).copy()
        start = base.cell_start
        if k > base.n_extra or any(not searchable[c] and start[c + 1] > start[c]
                                   for c, _ in extra):
            # `build` leaves out the positions of an extra's cell that was not searchable,
            # which a base cannot (a planner's terminal cells are searchable or hold no
            # position): then `build`'s graph itself
            return JointGraph.build(base.shape, base.cells, base.offsets,
                                    base.node_q[:n_base], searchable, squeeze_blocked,
                                    penalty, weights, extra, max_edge, squeeze_exempt)
        extra_cell = np.array([c for c, _ in extra], dtype=np.int64)
        for e, (c, q) in enumerate(extra):
            base.node_q[n_base + e] = q
            base.node_cell[n_base + e] = c
        searchable[extra_cell] = True
        n = n_base + k
        g = JointGraph(base.shape, base.node_q[:n], base.node_cell[:n], base.cell_start,
                       searchable, np.asarray(squeeze_blocked, bool).reshape(-1),
                       np.asarray(penalty, float).reshape(-1), np.asarray(weights, float),
                       float(max_edge), np.array(sorted(set(squeeze_exempt)), dtype=np.int64),
                       extra_cell)
        return g, list(range(n_base, n))

    @staticmethod
    def build(shape: tuple[int, int, int], cells: Array, offsets: Array, Q: Array,
              searchable: Array, squeeze_blocked: Array, penalty: Array, weights: Array,
              extra: list[tuple[int, Array]] = (), max_edge: float = np.inf,
              squeeze_exempt: Sequence[int] = ()) -> tuple[JointGraph, list[int]]:
        """Graph over the positions of the searchable cells, plus `extra` (cell, q) nodes
        (start, goal); the squeeze rule does not apply to steps into or out of the cells
        `squeeze_exempt`. Returns the graph and the node ids of the extras."""
        n_cells = int(np.prod(shape))
        searchable = np.asarray(searchable, bool).reshape(-1).copy()
        extra_cells = np.array([c for c, _ in extra], dtype=np.int64)
        extra_q = (np.array([q for _, q in extra], dtype=float).reshape(len(extra), -1)
                   if len(extra) else np.zeros((0, np.shape(Q)[1])))
        node_q, node_cell, cell_start, ids = select_nodes(
            np.asarray(cells, dtype=np.int64), np.asarray(offsets, dtype=np.int64),
            np.ascontiguousarray(Q, dtype=float), searchable, extra_cells, extra_q, n_cells)
        searchable[extra_cells] = True
        extra_ids = ids.tolist()
        g = JointGraph(tuple(shape), node_q, node_cell, cell_start, searchable,
                       np.asarray(squeeze_blocked, bool).reshape(-1),
                       np.asarray(penalty, float).reshape(-1), np.asarray(weights, float),
                       float(max_edge), np.unique(np.asarray(squeeze_exempt, dtype=np.int64)))
        return g, extra_ids

    @property
    def n_nodes(self) -> int:
        return len(self.node_cell)

    def neighbour_cells(self, cell: int) -> Array:
        """Searchable cells one step from `cell` (itself included), squeeze rule applied."""
        return neighbour_cells(int(cell), *self.shape, self.searchable, self.squeeze_blocked,
                               self.squeeze_exempt)

    def distance(self, q: Array, Q: Array) -> Array:
        """Weighted joint distance from q to each row of Q (metres of arm travel)."""
        return weighted_distances(np.asarray(q, dtype=float),
                                  np.ascontiguousarray(Q, dtype=float), self.weights)

    def successors(self, u: int) -> tuple[Array, Array]:
        """(node ids, edge costs u -> v) of u's neighbours."""
        return successor_costs(int(u), *self.shape, self.searchable, self.squeeze_blocked,
                               self.squeeze_exempt, self.cell_start, self.node_q,
                               self.node_cell, self.weights, float(self.max_edge),
                               self.penalty, self.extra_cell)

    def cost(self, u: int, v: int) -> float:
        d = float(self.distance(self.node_q[u], self.node_q[v][None])[0])
        return d + float(self.penalty[self.node_cell[v]])


@dataclass
class GraphBase:
    """Every cell's positions as graph nodes, with spare rows for a query's extra nodes
    (`JointGraph.over`): made once per selection of the world's positions."""

    shape: tuple[int, int, int]
    node_q: Array  # (n + n_extra, dof)
    node_cell: Array
    cell_start: Array  # (n_cells + 1,) over the n positions
    n_extra: int
    cells: Array  # the positions' CSR, as given (`JointGraph.over` may need `build`)
    offsets: Array

    @staticmethod
    def of(shape: tuple[int, int, int], cells: Array, offsets: Array, Q: Array,
           n_extra: int = 2) -> GraphBase:
        """The base over the positions of cell cells[i] (ascending) Q[offsets[i]:offsets[i + 1]]."""
        n_cells = shape[0] * shape[1] * shape[2]
        if len(cells) > 1 and np.any(np.diff(cells) <= 0):
            raise ValueError("a graph base needs its cells in ascending order")
        node_q, node_cell, cell_start = base_nodes(
            np.asarray(cells, dtype=np.int64), np.asarray(offsets, dtype=np.int64),
            np.ascontiguousarray(Q, dtype=float), n_cells, n_extra)
        return GraphBase(tuple(shape), node_q, node_cell, cell_start, n_extra,
                         np.asarray(cells, dtype=np.int64), np.asarray(offsets, dtype=np.int64))
