"""Path-first lazy search (Lazy PRM, Bohlin & Kavraki 2000) over a `JointGraph`.

Why: the pop-checking lazy A* (`astar.lazy_astar`) checks the edge into every node it pops,
and on the benchmark's queries it pops ~29 nodes to find a path of ~11 edges: two checks
in three are of edges the path never uses, each ~0.1 ms of exact continuous check. Here a
round searches the graph less the edges found invalid so far with every other edge assumed
valid (`astar_kernel.search`, compiled, no checks), then checks only the unknown edges of the
path it found, all in one batched call. A path whose edges all pass is the answer; else the
invalid edges (and nodes whose posture itself is invalid) leave the graph and the next
round searches again. A search that finds no path in a round has none at all: only edges
known to be invalid were left out.

A query among many obstacles can need many rounds; after `SearchBudget.path_rounds` of them
the search hands over to `lazy_astar`, with everything checked so far, so it is never less
complete than checking at every pop. Counted budgets (expansions over all rounds, edge
checks) decide the answer; the wall-time safety net is checked between rounds.
"""

from __future__ import annotations

import time

import numpy as np

from assistant.progress import Progress
from assistant.roadmap.astar import (
    REASON_BUDGET,
    REASON_FOUND,
    REASON_NO_PATH,
    REASON_SAFETY,
    EdgeChecker,
    SearchBudget,
    SearchResult,
    check_edges,
    lazy_astar,
)
from assistant.roadmap.astar_kernel import BUDGET, FOUND, search
from assistant.roadmap.graph import JointGraph

Array = np.ndarray


def lazy_path_search(graph: JointGraph, start: int, goal: int, checker: EdgeChecker,
                     budget: SearchBudget | None = None, progress: Progress | None = None, *,
                     heuristic_weight: float = 1.0, dead: Array | None = None,
                     ) -> SearchResult:
    """A path start -> goal whose edges all pass `checker` (see module docstring).

    `dead` marks nodes whose posture is known to be invalid before the search (e.g. next
    to a recorded collision): they are never entered, and no edge into them is checked.

    With `heuristic_weight` 1 the path is the cheapest over the edges that pass, as
    `lazy_astar`'s; above 1 it is weighted A*'s, within that factor of the optimum.
    """
    budget = budget or SearchBudget()
    t0 = time.monotonic()
    n = graph.n_nodes
    dead = np.zeros(n, dtype=bool) if dead is None else np.array(dead, dtype=bool)
    h = np.full(n, np.nan)
    bad: list[int] = []
    known: dict[tuple[int, int], float | None] = {}
    expansions = checks = rejected = 0

    def ended(found: bool, reason: str, nodes: list[int] | None = None,
              cost: float = float("inf"), detail: str = "") -> SearchResult:
        return SearchResult(found, reason, nodes or [], cost, expansions, checks, rejected,
                            time.monotonic() - t0, detail)

    for rnd in range(budget.path_rounds):
        status, path, cost, used = search(
            start, goal, *graph.shape, graph.searchable, graph.squeeze_blocked,
            graph.squeeze_exempt, graph.cell_start, graph.node_q, graph.node_cell,
            graph.weights, float(graph.max_edge), graph.penalty, dead,
            np.array(sorted(bad), dtype=np.int64), h, float(heuristic_weight),
            budget.max_expansions - expansions, graph.extra_cell)
        expansions += used
        if status == BUDGET:
            return ended(False, REASON_BUDGET, detail=f"{budget.max_expansions} expansions")
        if status != FOUND:
            return ended(False, REASON_NO_PATH)
        nodes = path.tolist()
        todo = [e for e in zip(nodes[:-1], nodes[1:], strict=True) if e not in known]
        if checks + len(todo) > budget.max_edge_checks:
            return ended(False, REASON_BUDGET, detail=f"{checks} edge checks")
        if todo:
            a, b = np.array(todo).T
            known.update(zip(todo, check_edges(checker, graph.node_q[a], graph.node_q[b]),
                             strict=True))
            checks += len(todo)
        failed = [(u, v) for u, v in todo if known[(u, v)] is not None]
        if not failed:
            return ended(True, REASON_FOUND, nodes, float(cost))
        rejected += len(failed)
        for u, v in failed:
            bad.append(u * n + v)
            if known[(u, v)] >= 1.0 - 1e-12:  # the posture v itself is invalid
                dead[v] = True
        if time.monotonic() - t0 > budget.max_seconds:
            return ended(False, REASON_SAFETY, detail=f"{budget.max_seconds:g} s of wall time "
                         "- is the machine overloaded?")
        if progress is not None:
            progress.update(min(0.99, (rnd + 1) / (budget.path_rounds + 1)),
                            f"searching roads ({rejected} edges refused)")
    rest = SearchBudget(max_expansions=budget.max_expansions - expansions,
                        max_edge_checks=budget.max_edge_checks - checks,
                        max_seconds=budget.max_seconds - (time.monotonic() - t0),
                        edge_batch=budget.edge_batch)
    res = lazy_astar(graph, start, goal, checker, rest, progress,
                     heuristic_weight=heuristic_weight, known=known, dead=dead)
    return SearchResult(res.found, res.reason, res.nodes, res.cost,
                        expansions + res.expansions, checks + res.edge_checks,
                        rejected + res.rejected_edges, time.monotonic() - t0,
                        res.budget_detail)
