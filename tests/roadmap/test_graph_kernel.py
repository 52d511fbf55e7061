"""The compiled neighbourhood (roadmap/graph_kernel) against the numpy formulation it
replaced: the same cells in the same order, the same successor nodes, on random grids with
blocked cells, unsearchable cells and exempt cells, including the grid's faces and corners."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from assistant.roadmap.graph import JointGraph

OFFSETS27 = np.array(list(itertools.product((-1, 0, 1), repeat=3)), dtype=np.int64)
FACES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
FACE_OF_MOVE = np.zeros((27, 6), dtype=np.int64)
for _m, _o in enumerate(OFFSETS27):
    if np.count_nonzero(_o) >= 2:
        for _a in range(3):
            if _o[_a]:
                FACE_OF_MOVE[_m, 2 * _a + (0 if _o[_a] > 0 else 1)] = 1


def reference_cells(g: JointGraph, cell: int) -> np.ndarray:
    """`JointGraph.neighbour_cells` as numpy array expressions (the code before the kernel)."""
    nx_, ny, nz = g.shape
    i, j, k = cell // (ny * nz), (cell // nz) % ny, cell % nz
    ijk = np.array([i, j, k]) + OFFSETS27
    inside = np.all((ijk >= 0) & (ijk < np.array(g.shape)), axis=1)
    faces = np.array([i, j, k]) + FACES
    f_in = np.all((faces >= 0) & (faces < np.array(g.shape)), axis=1)
    f_flat = (faces[:, 0] * ny + faces[:, 1]) * nz + faces[:, 2]
    f_blocked = np.zeros(6, dtype=np.int64)
    f_blocked[f_in] = g.squeeze_blocked[f_flat[f_in]]
    squeezed = (FACE_OF_MOVE @ f_blocked) >= 2
    flat = (ijk[inside, 0] * ny + ijk[inside, 1]) * nz + ijk[inside, 2]
    keep = ~squeezed[inside]
    if len(g.squeeze_exempt):
        keep |= np.isin(cell, g.squeeze_exempt) | np.isin(flat, g.squeeze_exempt)
    flat = flat[keep]
    return flat[g.searchable[flat]]


def reference_nodes(g: JointGraph, u: int) -> np.ndarray:
    cells = reference_cells(g, int(g.node_cell[u]))
    vs = np.concatenate([np.arange(g.cell_start[c], g.cell_start[c + 1]) for c in cells] +
                        [np.zeros(0, dtype=np.int64)])
    return vs[vs != u]


def _random_graph(rng: np.random.Generator, shape: tuple[int, int, int]) -> JointGraph:
    n_cells = int(np.prod(shape))
    cells = np.sort(rng.choice(n_cells, size=n_cells // 2, replace=False))
    counts = rng.integers(1, 4, len(cells))
    offsets = np.r_[0, np.cumsum(counts)]
    Q = rng.uniform(-1.0, 1.0, (offsets[-1], 3))
    searchable = rng.random(n_cells) < 0.8
    blocked = rng.random(n_cells) < 0.35
    exempt = rng.choice(n_cells, size=3, replace=False)
    g, _ = JointGraph.build(shape, cells, offsets, Q, searchable, blocked,
                            np.zeros(n_cells), np.ones(3), squeeze_exempt=exempt)
    return g


def test_neighbourhood_matches_the_numpy_formulation():
    rng = np.random.default_rng(5)
    squeezed = exempted = 0
    for shape in [(4, 5, 3), (1, 6, 6), (6, 1, 2), (3, 3, 3)]:
        for _ in range(5):
            g = _random_graph(rng, shape)
            plain = JointGraph(g.shape, g.node_q, g.node_cell, g.cell_start, g.searchable,
                               g.squeeze_blocked, g.penalty, g.weights)
            for cell in range(int(np.prod(shape))):
                got = g.neighbour_cells(cell)
                assert got.tolist() == reference_cells(g, cell).tolist()
                without = plain.neighbour_cells(cell)
                assert without.tolist() == reference_cells(plain, cell).tolist()
                squeezed += len(without) < len(_all_searchable(plain).neighbour_cells(cell))
                exempted += len(got) > len(without)
            for u in range(g.n_nodes):
                vs, cost = g.successors(u)
                assert vs.tolist() == reference_nodes(g, u).tolist()
                # 1e-12 rad: a weighted joint distance (5 products, summed) compiled vs numpy
                np.testing.assert_allclose(cost, g.distance(g.node_q[u], g.node_q[vs]),
                                           rtol=0, atol=1e-12)
    # The rule and its exemption both changed answers, or the comparison proves little.
    assert squeezed > 0 and exempted > 0


def random_positions(rng: np.random.Generator, shape: tuple[int, int, int],
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cells, offsets, Q) of a world's positions: 3/4 of the cells, 1-3 postures of 5
    joints each (cell i's: Q[offsets[i]:offsets[i + 1]])."""
    n_cells = int(np.prod(shape))
    cells = np.sort(rng.choice(n_cells, size=n_cells * 3 // 4, replace=False))
    offsets = np.r_[0, np.cumsum(rng.integers(1, 4, len(cells)))]
    return cells, offsets, rng.uniform(-1.0, 1.0, (offsets[-1], 5))


def _all_searchable(g: JointGraph) -> JointGraph:
    """The same graph with the squeeze rule off: every in-grid neighbour."""
    return JointGraph(g.shape, g.node_q, g.node_cell, g.cell_start, g.searchable,
                      np.zeros_like(g.squeeze_blocked), g.penalty, g.weights)


def _reference_selection(shape, cells, offsets, Q, searchable, extra):
    """`JointGraph.build`'s node selection as numpy calls (the code before the kernel):
    positions of searchable cells, then the extras, stable-sorted by cell."""
    n_cells = int(np.prod(shape))
    counts = np.diff(offsets)
    keep = np.repeat(searchable[cells], counts)
    node_cell = np.repeat(cells, counts)[keep]
    node_q = np.asarray(Q)[keep]
    extra_cells = np.array([c for c, _ in extra], dtype=np.int64)
    node_cell = np.r_[node_cell, extra_cells]
    node_q = np.vstack([node_q, np.array([q for _, q in extra], dtype=float)])
    order = np.argsort(node_cell, kind="stable")
    where = np.empty(len(order), dtype=np.int64)
    where[order] = np.arange(len(order))
    ids = [int(where[len(order) - len(extra) + i]) for i in range(len(extra))]
    cell_start = np.zeros(n_cells + 1, dtype=np.int64)
    np.cumsum(np.bincount(node_cell[order], minlength=n_cells), out=cell_start[1:])
    return node_q[order], node_cell[order], cell_start, ids


def test_node_selection_matches_the_stable_sort_it_replaced():
    """Positions of searchable cells grouped by cell, extras after a cell's own positions
    (also in an unsearchable cell, and two extras in one cell), ids of the extras."""
    rng = np.random.default_rng(17)
    for trial in range(30):
        shape = (4, 5, 3)
        n_cells = int(np.prod(shape))
        cells = rng.choice(n_cells, size=n_cells // 2, replace=False)
        if trial % 2:
            cells = np.sort(cells)
        offsets = np.r_[0, np.cumsum(rng.integers(1, 4, len(cells)))]
        Q = rng.uniform(-1.0, 1.0, (offsets[-1], 5))
        searchable = rng.random(n_cells) < 0.6
        picks = rng.choice(n_cells, size=2, replace=trial % 3 == 0)
        extra = [(int(c), rng.uniform(-1.0, 1.0, 5)) for c in picks]
        g, ids = JointGraph.build(shape, cells, offsets, Q, searchable,
                                  np.zeros(n_cells, bool), np.zeros(n_cells), np.ones(5),
                                  extra=extra)
        ref_q, ref_cell, ref_start, ref_ids = _reference_selection(
            shape, cells, offsets, Q, searchable, extra)
        # selected rows are copies (no arithmetic): exact on any machine
        assert np.array_equal(g.node_q, ref_q) and np.array_equal(g.node_cell, ref_cell)
        assert np.array_equal(g.cell_start, ref_start) and ids == ref_ids
        assert g.searchable[picks].all() and np.array_equal(
            g.searchable[~np.isin(np.arange(n_cells), picks)],
            searchable[~np.isin(np.arange(n_cells), picks)])


def test_graph_over_a_base_searches_as_the_selected_graph():
    """`JointGraph.over` (every cell's positions, the extras after them all) against
    `build` (the searchable cells' positions, extras sorted in): node for node the same
    successors in the same order with the same costs, and the same A* paths (penalties,
    squeeze rule, exempt cells, two extras in one cell, a base reused by a second query);
    an extra in an unsearchable cell with positions gets `build`'s graph itself."""
    from assistant.roadmap.astar_kernel import FOUND, search
    from assistant.roadmap.graph import GraphBase

    rng = np.random.default_rng(23)
    shape = (5, 4, 4)
    n_cells = int(np.prod(shape))
    cells, offsets, Q = random_positions(rng, shape)
    base = GraphBase.of(shape, cells, offsets, Q)
    with pytest.raises(ValueError, match="ascending"):  # node ids must follow the cells
        GraphBase.of(shape, cells[::-1], offsets, Q)
    found = fast = 0
    for trial in range(24):
        searchable = rng.random(n_cells) < 0.6
        blocked = rng.random(n_cells) < 0.3
        penalty = rng.uniform(0.0, 0.2, n_cells)
        picks = rng.choice(n_cells, size=2, replace=trial % 4 == 0)
        extra = [(int(c), rng.uniform(-1.0, 1.0, 5)) for c in picks]
        exempt = [int(picks[0])] if trial % 2 else []
        args = (searchable, blocked, penalty, np.ones(5))
        kw = {"extra": extra, "max_edge": 1.2, "squeeze_exempt": exempt}
        sel, ids = JointGraph.build(shape, cells, offsets, Q, *args, **kw)
        over, over_ids = JointGraph.over(base, *args, **kw)
        fast += len(over.extra_cell) > 0
        # node ids of `over` for the selected graph's nodes, by position (unique rows)
        key = {tuple(q): i for i, q in enumerate(over.node_q)}
        to_over = np.array([key[tuple(q)] for q in sel.node_q])
        assert to_over[ids].tolist() == over_ids
        for u in range(sel.n_nodes):
            vs, cost = sel.successors(u)
            vs_o, cost_o = over.successors(to_over[u])
            # the same compiled kernel on the same rows in this process: exact
            assert to_over[vs].tolist() == vs_o.tolist() and np.array_equal(cost, cost_o)
        for g, (s, t) in ((sel, ids), (over, over_ids)):
            n = g.n_nodes
            res = search(s, t, *g.shape, g.searchable, g.squeeze_blocked, g.squeeze_exempt,
                         g.cell_start, g.node_q, g.node_cell, g.weights, g.max_edge,
                         g.penalty, np.zeros(n, bool), np.zeros(0, np.int64),
                         np.full(n, np.nan), 1.0, 10_000, g.extra_cell)
            if g is sel:
                status, path, cost, expansions = res
                ref = sel.node_q[path]
            else:
                assert res[0] == status and res[2] == cost and res[3] == expansions
                assert np.array_equal(over.node_q[res[1]], ref)
        found += status == FOUND
    assert 3 <= found < 24 and 3 <= fast < 24  # found or not; base graphs and `build`'s


def test_predecessor_cells_are_the_cells_whose_steps_enter():
    """`predecessor_cells_into` (the goal's flood, `astar_kernel`) and its numpy fallback
    give exactly the cells whose `neighbour_cells` hold the cell, on random grids with the
    squeeze rule (a three-axis step reads other face cells one way than the other) and
    exempt cells (cell ids: exact)."""
    from assistant.roadmap.graph_kernel import predecessor_cells_into
    from assistant.roadmap.search_numpy import predecessor_cells

    rng = np.random.default_rng(23)
    out = np.empty(27, dtype=np.int64)
    one_way = 0
    for shape in [(4, 5, 3), (1, 6, 6), (3, 3, 3)]:
        for _ in range(4):
            g = _random_graph(rng, shape)
            n_cells = int(np.prod(shape))
            into = {c: [] for c in range(n_cells)}
            for a in range(n_cells):
                if g.searchable[a]:
                    for b in g.neighbour_cells(a).tolist():
                        into[b].append(a)
            for c in range(n_cells):
                args = (c, *g.shape, g.searchable, g.squeeze_blocked, g.squeeze_exempt)
                got = out[:predecessor_cells_into(*args, out)].tolist()
                assert sorted(got) == sorted(into[c]), c
                assert sorted(predecessor_cells(*args).tolist()) == sorted(into[c]), c
                if g.searchable[c]:
                    one_way += len(set(into[c]) ^ set(g.neighbour_cells(c).tolist()))
    # the rule is not symmetric on these grids: the inverse was not the forward rule
    assert one_way > 0
