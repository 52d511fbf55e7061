"""Path-first lazy search: the compiled search pops like the pop-checking A*, the checked
path avoids what the checker refuses at the optimal cost, it checks far fewer edges, and it
hands over to the pop-checking A* (still complete) when rounds run out."""

from __future__ import annotations

import time
from itertools import pairwise

import networkx as nx
import numpy as np
import pytest
from test_roadmap_astar import AlwaysValid, Wall, to_networkx, toy_graph

from assistant.roadmap.astar import (
    REASON_BUDGET,
    REASON_NO_PATH,
    REASON_SAFETY,
    SearchBudget,
    lazy_astar,
)
from assistant.roadmap.astar_kernel import FOUND, NO_PATH, search
from assistant.roadmap.path_first import lazy_path_search


class Batched(Wall):
    """The wall, with the batched call the planner's edge checker offers; counts calls."""

    def __init__(self, top: float):
        super().__init__(top)
        self.calls = 0

    def first_invalid_fractions(self, Q0, Q1):
        self.calls += 1
        return [self.first_invalid_fraction(a, b) for a, b in zip(Q0, Q1, strict=True)]


class DeadNode(AlwaysValid):
    """Refuses every motion ending in one posture (fraction 1: the posture itself)."""

    def __init__(self, q):
        super().__init__()
        self.q = np.asarray(q)

    def first_invalid_fraction(self, q0, q1):
        super().first_invalid_fraction(q0, q1)
        return 1.0 if np.array_equal(q1, self.q) else None


def _search(graph, s, g, dead=None, bad=(), weight=1.0, max_expansions=60_000):
    n = graph.n_nodes
    return search(s, g, *graph.shape, graph.searchable, graph.squeeze_blocked,
                  graph.squeeze_exempt, graph.cell_start, graph.node_q, graph.node_cell,
                  graph.weights, float(graph.max_edge), graph.penalty,
                  np.zeros(n, bool) if dead is None else dead,
                  np.array(sorted(bad), dtype=np.int64), np.full(n, np.nan), weight,
                  max_expansions, graph.extra_cell)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("weight", [1.0, 1.5])
def test_compiled_search_closes_nodes_as_the_pop_checking_astar(seed, weight):
    rng = np.random.default_rng(seed)
    graph, (s, g) = toy_graph(rng, blocked=rng.choice(40, 6, replace=False).tolist()[2:])
    ref = lazy_astar(graph, s, g, AlwaysValid(), heuristic_weight=weight)
    status, path, cost, expansions = _search(graph, s, g, weight=weight)
    assert status == FOUND and path.tolist() == ref.nodes
    # the same edge weights summed along the same path by compiled and Python code (the
    # order or an FMA may differ): a few ulp per edge over a few dozen edges
    assert cost == pytest.approx(ref.cost, rel=1e-12) and expansions == ref.expansions
    if weight == 1.0:
        assert cost == pytest.approx(nx.dijkstra_path_length(to_networkx(graph), s, g))


def test_compiled_search_leaves_out_bad_edges_and_dead_nodes():
    rng = np.random.default_rng(1)
    graph, (s, g) = toy_graph(rng, shape=(6, 6, 1), per_cell=2, penalty=False)
    G = to_networkx(graph)
    n = graph.n_nodes
    _, path, _, _ = _search(graph, s, g)
    u, v = path.tolist()[1:3]
    status, detour, cost, _ = _search(graph, s, g, bad=[u * n + v])
    G.remove_edge(u, v)
    assert status == FOUND and (u, v) not in set(pairwise(detour.tolist()))
    assert cost == pytest.approx(nx.dijkstra_path_length(G, s, g))
    dead = np.zeros(n, bool)
    dead[v] = True
    status, around, cost, _ = _search(graph, s, g, dead=dead)
    G.remove_node(v)
    assert status == FOUND and v not in around.tolist()
    assert cost == pytest.approx(nx.dijkstra_path_length(G, s, g))
    cut = np.zeros(n, bool)
    cut[[w for w in G.predecessors(g)] + [w for w in graph.successors(g)[0].tolist()]] = True
    assert _search(graph, s, g, dead=cut)[0] != FOUND
    assert _search(graph, s, g, max_expansions=2)[0] != FOUND


def test_path_first_checks_only_the_path_in_one_call_when_nothing_is_refused():
    rng = np.random.default_rng(3)
    graph, (s, g) = toy_graph(rng, shape=(6, 6, 1), per_cell=2, penalty=False)
    free = Batched(top=-1.0)  # a wall of no height: refuses nothing
    res = lazy_path_search(graph, s, g, free)
    pop = lazy_astar(graph, s, g, AlwaysValid())
    assert res.found and res.nodes == pop.nodes
    # the compiled search's cost and the Python A*'s: the same edge weights summed by
    # compiled and interpreted code (order, FMA): a few ulp per edge over a short path
    assert res.cost == pytest.approx(pop.cost, rel=1e-12)
    assert free.calls == 1 and res.edge_checks == len(res.nodes) - 1 < pop.edge_checks


def test_path_first_finds_the_optimal_detour_past_refused_edges():
    """A wall across the whole toy graph is Lazy PRM's hard case (each round finds one more
    edge across it); it still ends at the optimum, checking no edge twice."""
    rng = np.random.default_rng(3)
    graph, (s, g) = toy_graph(rng, shape=(6, 6, 1), per_cell=2, penalty=False)
    want = nx.dijkstra_path_length(to_networkx(graph, reject=Wall(0.7).blocks), s, g)
    for rounds in (SearchBudget().path_rounds, 1000):
        wall = Batched(top=0.7)
        res = lazy_path_search(graph, s, g, wall, SearchBudget(path_rounds=rounds))
        path = graph.node_q[res.nodes]
        assert res.found and res.rejected_edges >= 1
        assert not any(wall.blocks(a, b) for a, b in pairwise(path))
        assert res.cost == pytest.approx(want)
        assert res.edge_checks == len(wall.checked) == len(set(wall.checked))


def test_path_first_marks_an_invalid_posture_dead():
    rng = np.random.default_rng(2)
    graph, (s, g) = toy_graph(rng, shape=(6, 6, 1), per_cell=2, penalty=False)
    first = lazy_path_search(graph, s, g, AlwaysValid())
    v = first.nodes[2]
    res = lazy_path_search(graph, s, g, DeadNode(graph.node_q[v]))
    assert res.found and v not in res.nodes and res.rejected_edges >= 1


def test_path_first_hands_over_to_pop_checking_when_rounds_run_out():
    rng = np.random.default_rng(3)
    graph, (s, g) = toy_graph(rng, shape=(6, 6, 1), per_cell=2, penalty=False)
    want = nx.dijkstra_path_length(to_networkx(graph, reject=Wall(0.7).blocks), s, g)
    for rounds in (0, 1):
        wall = Batched(top=0.7)
        res = lazy_path_search(graph, s, g, wall, SearchBudget(path_rounds=rounds))
        assert res.found and res.cost == pytest.approx(want)
        assert res.edge_checks == len(wall.checked)
    # what the rounds checked is not checked again
    assert len(set(wall.checked)) == len(wall.checked)


def test_path_first_no_path_and_budgets_end_with_a_reason():
    rng = np.random.default_rng(4)
    graph, (s, g) = toy_graph(rng, shape=(6, 6, 1), per_cell=2, penalty=False)
    res = lazy_path_search(graph, s, g, Batched(top=2.0))
    assert not res.found and res.reason == REASON_NO_PATH and res.rejected_edges > 0
    tight = lazy_path_search(graph, s, g, AlwaysValid(), SearchBudget(max_expansions=3))
    assert not tight.found and tight.reason == REASON_BUDGET
    few = lazy_path_search(graph, s, g, AlwaysValid(), SearchBudget(max_edge_checks=2))
    assert not few.found and few.reason == REASON_BUDGET and few.edge_checks <= 2


def test_path_first_looks_at_the_clock_between_rounds(monkeypatch):
    """The wall-time safety net: a round that refuses edges is followed by a look at the
    clock, and a search the machine cannot finish in time fails with that reason."""
    rng = np.random.default_rng(3)
    graph, (s, g) = toy_graph(rng, shape=(6, 6, 1), per_cell=2, penalty=False)
    real = time.monotonic
    t0 = real()
    monkeypatch.setattr(time, "monotonic", lambda: t0 + 1e7 * (real() - t0))
    res = lazy_path_search(graph, s, g, Batched(top=0.7))
    assert not res.found and res.reason == REASON_SAFETY and res.rejected_edges >= 1


def _args(graph, s, g, dead=None, bad=(), weight=1.0, max_expansions=60_000):
    n = graph.n_nodes
    return (s, g, *graph.shape, graph.searchable, graph.squeeze_blocked,
            graph.squeeze_exempt, graph.cell_start, graph.node_q, graph.node_cell,
            graph.weights, float(graph.max_edge), graph.penalty,
            np.zeros(n, bool) if dead is None else dead, np.array(sorted(bad), dtype=np.int64),
            np.full(n, np.nan), weight, max_expansions, graph.extra_cell)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("weight", [1.0, 1.5])
def test_the_search_fallback_finds_the_compiled_searchs_path(seed, weight):
    """`search_numpy` (the search until compiled, on a first run) pops as the compiled
    search: the same path, cost and expansions, also with bad edges and dead nodes. The
    cost within 1e-9 (the same sums, compiled or numpy); the path exactly, as no two paths
    of these random graphs tie within that."""
    from assistant.roadmap.search_numpy import search_numpy

    rng = np.random.default_rng(seed)
    graph, (s, g) = toy_graph(rng, blocked=rng.choice(40, 6, replace=False).tolist()[2:])
    n = graph.n_nodes
    _, path, _, _ = _search(graph, s, g)
    u, v = path.tolist()[1:3]
    dead = np.zeros(n, bool)
    dead[path.tolist()[-2]] = True
    for kw in ({}, {"bad": [u * n + v]}, {"dead": dead}, {"max_expansions": 3}):
        want = _search(graph, s, g, weight=weight, **kw)
        got = search_numpy(*_args(graph, s, g, weight=weight, **kw))
        assert got[0] == want[0] and got[3] == want[3], kw
        assert got[1].tolist() == want[1].tolist(), kw
        assert abs(got[2] - want[2]) <= 1e-9 or got[2] == want[2] == np.inf, kw


def test_the_search_fallback_keeps_the_squeeze_rule_and_its_exemptions():
    """The fallback's neighbour cells are the kernel's on random grids with blocked,
    unsearchable and exempt cells (cell ids: exact)."""
    from test_graph_kernel import _random_graph

    from assistant.roadmap.search_numpy import neighbour_cells

    rng = np.random.default_rng(11)
    for shape in [(4, 5, 3), (1, 6, 6), (3, 3, 3)]:
        g = _random_graph(rng, shape)
        for cell in range(int(np.prod(shape))):
            got = neighbour_cells(cell, *g.shape, g.searchable, g.squeeze_blocked,
                                  g.squeeze_exempt)
            assert sorted(got.tolist()) == sorted(g.neighbour_cells(cell).tolist()), cell


def test_the_expansion_fallbacks_give_the_kernels_successors():
    """`successor_costs_numpy` and `expand_numpy` (the pop-checking A*'s expansion until
    compiled) give the kernels' nodes in the kernels' order (exact: ids), on graphs with
    extra nodes; costs within 1e-12 (the same five products summed compiled or in numpy)."""
    from test_graph_kernel import _random_graph, random_positions

    from assistant.roadmap.graph import GraphBase, JointGraph
    from assistant.roadmap.graph_kernel import expand, successor_costs
    from assistant.roadmap.search_numpy import expand_numpy, successor_costs_numpy

    rng = np.random.default_rng(3)
    shape = (5, 4, 4)
    n_cells = int(np.prod(shape))
    cells, offsets, Q = random_positions(rng, shape)
    picks = rng.choice(n_cells, size=3)
    picks[1] = picks[0]  # two extras in one cell
    searchable = rng.random(n_cells) < 0.7
    searchable[picks] = True  # (an extra in an unsearchable cell: `build`'s graph instead)
    over, _ = JointGraph.over(GraphBase.of(shape, cells, offsets, Q), searchable,
                              rng.random(n_cells) < 0.3, rng.uniform(0.0, 0.2, n_cells),
                              np.ones(5),
                              extra=[(int(c), rng.uniform(-1, 1, 5)) for c in picks[:2]],
                              max_edge=1.2, squeeze_exempt=[int(picks[2])])
    graph, _ = toy_graph(rng, blocked=[5, 6, 13])
    for gr in (over, graph, _random_graph(rng, (4, 5, 3))):
        args = (*gr.shape, gr.searchable, gr.squeeze_blocked, gr.squeeze_exempt,
                gr.cell_start, gr.node_q, gr.node_cell, gr.weights, float(gr.max_edge),
                gr.penalty)
        n = gr.n_nodes
        for u in range(n):
            vs, cost = successor_costs(u, *args, gr.extra_cell)
            vs_np, cost_np = successor_costs_numpy(u, *args, gr.extra_cell)
            assert vs_np.tolist() == vs.tolist(), u
            np.testing.assert_allclose(cost_np, cost, rtol=0, atol=1e-12)
        state = [np.zeros(n, bool), np.zeros(n, bool), np.full(n, np.inf),
                 np.full(n, -1, dtype=np.int64), np.full(n, np.nan)]
        state[0][::5] = True  # some closed
        state_np = [a.copy() for a in state]
        q_goal = gr.node_q[-1]
        for u in range(0, n, 3):
            want = expand(u, 0.1, *args, *state, q_goal, 1.2, np.zeros(0, np.int64),
                          gr.extra_cell)
            got = expand_numpy(u, 0.1, *args, *state_np, q_goal, 1.2,
                               np.zeros(0, np.int64), gr.extra_cell)
            assert got[2].tolist() == want[2].tolist(), u
            np.testing.assert_allclose(got[1], want[1], rtol=0, atol=1e-12)
            np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-12)
        np.testing.assert_array_equal(state_np[3], state[3])  # parents: exact
    assert len(over.extra_cell) == 2  # the query's extra nodes, both in one cell


def _cut_graph(rng, shape, max_edge):
    """A random 3-D graph (3 joints) with unsearchable, squeeze-blocked and exempt cells and
    edges only up to `max_edge`: many of its node pairs are not connected."""
    from assistant.roadmap.graph import JointGraph

    n_cells = int(np.prod(shape))
    cells = np.sort(rng.choice(n_cells, size=n_cells * 3 // 4, replace=False))
    offsets = np.r_[0, np.cumsum(rng.integers(1, 4, len(cells)))]
    Q = rng.uniform(-1.0, 1.0, (offsets[-1], 3))
    graph, _ = JointGraph.build(shape, cells, offsets, Q, rng.random(n_cells) < 0.8,
                                rng.random(n_cells) < 0.35, rng.uniform(0, 0.05, n_cells),
                                np.ones(3), max_edge=max_edge,
                                squeeze_exempt=rng.choice(n_cells, 3, replace=False))
    return graph


@pytest.mark.parametrize("seed", range(4))
def test_the_goals_flood_ends_only_searches_that_find_no_path(seed):
    """Over random start-goal pairs of cut graphs, the compiled search (with the goal's
    flood) finds a path exactly when the pop-checking A* (no flood) does, the same path at
    the same cost after the same expansions; where there is none it says so after at most
    as many expansions; and the fallback agrees with it (exact: ids and counts)."""
    from assistant.roadmap.search_numpy import search_numpy

    rng = np.random.default_rng(seed)
    graph = _cut_graph(rng, (5, 5, 4), max_edge=0.7)
    n = graph.n_nodes
    found = shorter = 0
    for _ in range(25):
        s, g = (int(x) for x in rng.choice(n, 2, replace=False))
        ref = lazy_astar(graph, s, g, AlwaysValid(), heuristic_weight=1.5)
        status, path, cost, expansions = _search(graph, s, g, weight=1.5)
        assert (status == FOUND) == ref.found, (s, g)
        if ref.found:
            found += 1
            assert path.tolist() == ref.nodes
            assert cost == pytest.approx(ref.cost, rel=1e-12)  # as in the test above
            assert expansions == ref.expansions
        else:
            assert status == NO_PATH and expansions <= ref.expansions
            shorter += expansions < ref.expansions
        got = search_numpy(*_args(graph, s, g, weight=1.5))
        assert (got[0], got[1].tolist(), got[3]) == (status, path.tolist(), expansions)
    # both kinds of pair came up, and the flood ended some searches early
    assert found > 0 and shorter > 0


def test_a_goal_cut_off_from_the_start_side_is_known_after_its_own_pocket():
    """A wall of unsearchable cells fences the goal's corner off: the search says "no path"
    after no more expansions than the pocket holds nodes, where the A* alone closes every
    node the start reaches; a goal posture with no edge at all, after none."""
    rng = np.random.default_rng(7)
    shape = (8, 8, 1)
    fence = [int(np.ravel_multi_index(ij + (0,), shape)) for ij in
             [(5, 5), (5, 6), (5, 7), (6, 5), (7, 5)]]
    graph, (s, g) = toy_graph(rng, shape=shape, per_cell=2, blocked=fence, penalty=False)
    pocket = 4 * 2 + 1  # cells (6, 6), (6, 7), (7, 6), (7, 7): 2 positions each, the goal
    ref = lazy_astar(graph, s, g, AlwaysValid())
    status, _, _, expansions = _search(graph, s, g)
    assert not ref.found and ref.expansions > 40
    assert status == NO_PATH and expansions <= pocket
    # the goal posture far from every position of its neighbourhood: no edge enters it
    graph.node_q[g] = [5.0, 5.0]
    graph.max_edge = 1.0
    status, _, _, expansions = _search(graph, s, g)
    assert status == NO_PATH and expansions == 0
    assert lazy_astar(graph, s, g, AlwaysValid()).expansions > 40


class Recording(AlwaysValid):
    """Every motion valid; remembers each motion's end posture."""

    def __init__(self):
        super().__init__()
        self.ends: list[np.ndarray] = []

    def first_invalid_fraction(self, q0, q1):
        self.ends.append(np.asarray(q1))
        return super().first_invalid_fraction(q0, q1)


@pytest.mark.parametrize("rounds", [8, 0])
def test_nodes_known_dead_are_never_entered_nor_checked(rounds):
    """`dead` (postures known invalid, e.g. next to a recorded collision) leaves nodes out
    before the search: the path avoids them and no edge into them is checked, in the
    path-first rounds and in the pop-checking A* they hand over to."""
    rng = np.random.default_rng(3)
    graph, (s, g) = toy_graph(rng, shape=(6, 6, 1), per_cell=2, penalty=False)
    free = lazy_path_search(graph, s, g, AlwaysValid())
    inner = free.nodes[1:-1]
    assert inner, "the toy query must pass some node"
    dead = np.zeros(graph.n_nodes, dtype=bool)
    dead[inner[len(inner) // 2]] = True
    checker = Recording()
    res = lazy_path_search(graph, s, g, checker, SearchBudget(path_rounds=rounds), dead=dead)
    assert res.found and not dead[res.nodes].any()
    q_dead = graph.node_q[dead]
    assert not any(np.array_equal(e, qd) for e in checker.ends for qd in q_dead)
    assert dead.sum() == 1  # the caller's array is left as it was
