"""Lazy A* over joint positions: optimal on toy graphs (vs networkx), corner-squeeze rule, lazy
rejection with detour, and the no-path / budget endings."""

from __future__ import annotations

from itertools import pairwise

import networkx as nx
import numpy as np
import pytest

from assistant.roadmap.astar import REASON_BUDGET, REASON_NO_PATH, SearchBudget, lazy_astar
from assistant.roadmap.graph import JointGraph


class AlwaysValid:
    def __init__(self):
        self.calls = 0

    def first_invalid_fraction(self, q0, q1):
        self.calls += 1
        return None


class Wall:
    """Rejects every motion that crosses x = 0.5 below y = top (a wall in joint space)."""

    def __init__(self, top: float):
        self.top = top
        self.checked: list[tuple[tuple, tuple]] = []

    def blocks(self, q0, q1) -> bool:
        if (q0[0] - 0.5) * (q1[0] - 0.5) > 0:
            return False
        t = (0.5 - q0[0]) / (q1[0] - q0[0]) if q1[0] != q0[0] else 0.0
        return q0[1] + t * (q1[1] - q0[1]) < self.top

    def first_invalid_fraction(self, q0, q1):
        self.checked.append((tuple(q0), tuple(q1)))
        return 0.5 if self.blocks(q0, q1) else None


def toy_graph(rng, shape=(5, 4, 2), per_cell=3, blocked=(), penalty=True):
    n_cells = int(np.prod(shape))
    cells = np.arange(n_cells)
    ijk = np.stack(np.unravel_index(cells, shape), axis=1)
    counts = np.full(n_cells, per_cell)
    # joint positions near the cell's scaled index, 2 joints
    Q = (np.repeat(ijk[:, :2], per_cell, axis=0) + rng.uniform(0, 1, (n_cells * per_cell, 2))) \
        / np.array(shape[:2])
    offsets = np.r_[0, np.cumsum(counts)]
    searchable = np.ones(n_cells, bool)
    searchable[list(blocked)] = False
    squeeze = ~searchable
    pen = rng.uniform(0, 0.05, n_cells) if penalty else np.zeros(n_cells)
    start_q = np.array([0.01, 0.01])
    goal_q = np.array([0.99, 0.99])
    start_cell = 0
    goal_cell = int(np.ravel_multi_index((shape[0] - 1, shape[1] - 1, 0), shape))
    return JointGraph.build(shape, cells, offsets, Q, searchable, squeeze, pen,
                            np.array([1.0, 0.7]), extra=[(start_cell, start_q),
                                                         (goal_cell, goal_q)])


def to_networkx(graph: JointGraph, reject=None) -> nx.DiGraph:
    G = nx.DiGraph()
    for u in range(graph.n_nodes):
        vs, cs = graph.successors(u)
        for v, c in zip(vs.tolist(), cs.tolist(), strict=True):
            if reject is None or not reject(graph.node_q[u], graph.node_q[v]):
                G.add_edge(u, v, weight=c)
    return G


@pytest.mark.parametrize("seed", range(8))
def test_astar_is_optimal_on_a_toy_graph(seed):
    rng = np.random.default_rng(seed)
    graph, (s, g) = toy_graph(rng, blocked=rng.choice(40, 6, replace=False).tolist()[2:])
    res = lazy_astar(graph, s, g, AlwaysValid(), SearchBudget(edge_batch=1))
    want = nx.dijkstra_path_length(to_networkx(graph), s, g)
    assert res.found and res.reason == "found"
    assert res.cost == pytest.approx(want, rel=1e-9)
    # the returned node path really costs that much
    assert sum(graph.cost(a, b) for a, b in pairwise(res.nodes)) == \
        pytest.approx(res.cost)
    assert res.nodes[0] == s and res.nodes[-1] == g
    # batching the lazy checks does not change the answer
    res4 = lazy_astar(graph, s, g, AlwaysValid(), SearchBudget(edge_batch=4))
    assert res4.cost == pytest.approx(res.cost)
    # a weighted heuristic stays within its factor
    w = lazy_astar(graph, s, g, AlwaysValid(), heuristic_weight=1.5)
    assert res.cost <= w.cost <= 1.5 * res.cost + 1e-12


def test_lazy_check_rejects_a_blocked_edge_and_finds_the_detour():
    rng = np.random.default_rng(3)
    graph, (s, g) = toy_graph(rng, shape=(6, 6, 1), per_cell=2, penalty=False)
    wall = Wall(top=0.7)
    res = lazy_astar(graph, s, g, wall, SearchBudget(edge_batch=1))
    assert res.found and res.rejected_edges >= 1
    # the path goes over the wall, and costs exactly the shortest path without the
    # rejected motions
    path = graph.node_q[res.nodes]
    assert not any(wall.blocks(a, b) for a, b in pairwise(path))
    want = nx.dijkstra_path_length(to_networkx(graph, reject=wall.blocks), s, g)
    assert res.cost == pytest.approx(want)
    assert nx.dijkstra_path_length(to_networkx(graph), s, g) < want - 1e-6  # a real detour
    # lazy: far fewer checks than edges in the graph
    assert len(wall.checked) < to_networkx(graph).number_of_edges() / 5


def test_no_path_and_budget_end_with_a_reason():
    rng = np.random.default_rng(4)
    graph, (s, g) = toy_graph(rng, shape=(6, 6, 1), per_cell=2, penalty=False)
    res = lazy_astar(graph, s, g, Wall(top=2.0), SearchBudget(edge_batch=1))
    assert not res.found and res.reason == REASON_NO_PATH and res.rejected_edges > 0
    tight = lazy_astar(graph, s, g, AlwaysValid(), SearchBudget(max_expansions=3))
    assert not tight.found and tight.reason == REASON_BUDGET and "expansions" in \
        tight.budget_detail
    few_checks = lazy_astar(graph, s, g, AlwaysValid(),
                            SearchBudget(max_edge_checks=2, edge_batch=1))
    assert few_checks.reason == REASON_BUDGET and few_checks.edge_checks == 2


def test_corner_squeeze_is_forbidden_only_between_two_blocked_faces():
    shape = (3, 3, 3)
    n = 27
    cells = np.arange(n)
    offsets = np.arange(n + 1)
    Q = np.zeros((n, 1))

    def neighbours(blocked):
        squeeze = np.zeros(n, bool)
        squeeze[[int(np.ravel_multi_index(b, shape)) for b in blocked]] = True
        out = []
        # An extra node (start/goal) elsewhere does not change the rule for other cells.
        for extra in ([], [(int(np.ravel_multi_index((2, 2, 2), shape)), np.zeros(1))]):
            g, _ = JointGraph.build(shape, cells, offsets, Q, np.ones(n, bool), squeeze,
                                    np.zeros(n), np.ones(1), extra=extra,
                                    squeeze_exempt=[c for c, _ in extra])
            out.append(set(g.neighbour_cells(int(np.ravel_multi_index((0, 0, 0),
                                                                      shape))).tolist()))
        assert out[0] == out[1]
        return out[0]

    diag_xy = int(np.ravel_multi_index((1, 1, 0), shape))
    corner = int(np.ravel_multi_index((1, 1, 1), shape))
    assert diag_xy in neighbours([(1, 0, 0)])  # one blocked face: may pass
    assert diag_xy not in neighbours([(1, 0, 0), (0, 1, 0)])  # squeezed between two
    assert diag_xy in neighbours([(1, 0, 0), (0, 0, 1)])  # the z face is not on its way
    assert corner not in neighbours([(1, 0, 0), (0, 0, 1)])  # any two of a corner's faces
    assert corner in neighbours([(0, 0, 1)])
    assert len(neighbours([])) == 8  # the cell itself and its 7 neighbours in the corner


def test_start_and_goal_cells_are_exempt_from_the_squeeze_rule():
    """A taught point next to a table: the start cell's face neighbours are the table, so
    every diagonal step up and away is a "squeeze". With the start's and goal's cells exempt
    the search leaves (and enters the goal) that way; the exact edge check decides."""
    shape = (3, 3, 3)
    n = 27

    def idx(*c: int) -> int:
        return int(np.ravel_multi_index(c, shape))

    table = [idx(i, j, 0) for i in range(3) for j in range(3)]
    start, goal = idx(0, 0, 0), idx(2, 2, 0)
    blocked = np.zeros(n, bool)
    blocked[table] = True
    # Cells above the table hold one position each; the table cells none (occupied).
    cells = np.array([c for c in range(n) if not blocked[c]])
    offsets = np.arange(len(cells) + 1)
    Q = np.array([[float(c)] for c in cells]) * 0.01
    blocked[[idx(0, 0, 1), idx(2, 2, 1)]] = True  # straight up is blocked too
    searchable = ~blocked

    extra = [(start, np.array([0.0])), (goal, np.array([0.26]))]
    g, (s, t) = JointGraph.build(shape, cells, offsets, Q, searchable, blocked, np.zeros(n),
                                 np.ones(1), extra=extra, squeeze_exempt=(start, goal))
    assert idx(1, 1, 1) in g.neighbour_cells(start).tolist()  # up and away, diagonally
    assert goal in g.neighbour_cells(idx(1, 1, 1)).tolist()  # and into the goal's cell
    res = lazy_astar(g, s, t, AlwaysValid())
    assert res.found and res.nodes[0] == s and res.nodes[-1] == t
    # Without the exemption the start cell is cut off.
    g, (s, t) = JointGraph.build(shape, cells, offsets, Q, searchable, blocked, np.zeros(n),
                                 np.ones(1), extra=extra)
    assert g.neighbour_cells(start).tolist() == [start]
    assert not lazy_astar(g, s, t, AlwaysValid()).found
