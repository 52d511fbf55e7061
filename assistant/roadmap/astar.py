"""Lazy A* over a `JointGraph`: edges are checked exactly only when the search pops them.

Checking every generated edge with the continuous collision check would cost more than the
search; most edges are never needed. So successors are queued with their optimistic cost and
the edge (parent -> node) is checked when the node is popped (as in Lazy Weighted A*). A
rejected edge is remembered and the node is *repaired*: its best parent among the already
closed neighbours over edges not known to be invalid is recomputed and re-queued, so the
search stays complete and, the heuristic being consistent, optimal for the edges that pass.

Every search ends with a clear reason: the goal was reached, the queue ran empty ("no path"),
or a counted budget (expansions, edge checks) ran out ("budget exhausted"); a wall-time
safety net ("safety limit") only stops a search the machine cannot finish in time.
"""

from __future__ import annotations

import heapq
import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from assistant.progress import Progress
from assistant.roadmap.graph import JointGraph
from assistant.roadmap.graph_kernel import expand

Array = np.ndarray

REASON_FOUND = "found"
REASON_NO_PATH = "no path"
REASON_BUDGET = "budget exhausted"
#: The wall-time safety net tripped (not a counted budget: the caller must not treat the
#: query as answered, e.g. as "no path", since the answer would depend on the machine).
REASON_SAFETY = "safety limit"
_UNKNOWN = object()
_NO_EDGES = np.zeros(0, dtype=np.int64)


class EdgeChecker(Protocol):
    def first_invalid_fraction(self, q0: Array, q1: Array) -> float | None:
        """None if the straight joint motion q0 -> q1 is valid, else where it first fails."""


def check_edges(checker: EdgeChecker, Q0: Array, Q1: Array) -> list[float | None]:
    """`first_invalid_fraction` for several edges; one batched call if the checker offers
    `first_invalid_fractions` (the planner's does), else one call per edge."""
    many = getattr(checker, "first_invalid_fractions", None)
    if many is not None:
        return list(many(Q0, Q1))
    return [checker.first_invalid_fraction(a, b) for a, b in zip(Q0, Q1, strict=True)]


@dataclass(frozen=True)
class SearchBudget:
    """What a search may spend. Expansions and edge checks decide the result (the same
    query gives the same answer on any machine); `max_seconds` is a wall-time safety net
    only, far above what the counted budgets take, and reaching it fails the search with
    that reason rather than returning another path."""

    max_expansions: int = 60_000
    max_edge_checks: int = 20_000
    max_seconds: float = 60.0
    #: Edges checked together when one must be checked: the popped one plus the next entries
    #: of the queue (the likeliest to be popped next), in one batched validity call. Saves
    #: per-call overhead when the search pops many nodes, wastes checks when it pops few; on
    #: the thesis cell it is a wash, so the default checks strictly one edge per pop.
    edge_batch: int = 1
    #: Rounds of the path-first search (`path_first.lazy_path_search`: search with unchecked
    #: edges assumed valid, check the path's edges) before it hands over to checking at
    #: every pop; 0 checks at every pop from the start.
    path_rounds: int = 8


@dataclass(frozen=True)
class SearchResult:
    found: bool
    reason: str
    nodes: list[int] = field(default_factory=list)
    cost: float = float("inf")
    expansions: int = 0
    edge_checks: int = 0
    rejected_edges: int = 0
    seconds: float = 0.0
    budget_detail: str = ""


def lazy_astar(graph: JointGraph, start: int, goal: int, checker: EdgeChecker,
               budget: SearchBudget | None = None, progress: Progress | None = None, *,
               heuristic_weight: float = 1.0,
               known: dict[tuple[int, int], float | None] | None = None,
               dead: Array | None = None) -> SearchResult:
    """Cheapest path start -> goal whose edges all pass `checker` (see module docstring).

    `heuristic_weight` > 1 turns it into weighted A*: far fewer expansions (and edge checks),
    cost at most that factor above the optimum. `known` holds edges (u, v) already checked
    (their first invalid fraction, None = valid), e.g. by a path-first search handing over;
    it is updated with the edges this search checks. `dead` marks nodes whose posture is
    known to be invalid (never entered).
    """
    budget = budget or SearchBudget()
    t0 = time.monotonic()
    n = graph.n_nodes
    q_goal = graph.node_q[goal]
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=bool)
    # the posture itself is invalid
    dead = np.zeros(n, dtype=bool) if dead is None else np.array(dead, dtype=bool)
    h = np.full(n, np.nan)
    invalid: set[tuple[int, int]] = set()
    known = {} if known is None else known
    g[start] = 0.0
    heap: list[tuple[float, float, int, int]] = [(0.0, 0.0, start, -1)]
    expansions = checks = rejected = 0

    def heur(ids: Array) -> Array:
        miss = np.isnan(h[ids])
        if miss.any():
            h[ids[miss]] = heuristic_weight * graph.distance(q_goal, graph.node_q[ids[miss]])
        return h[ids]

    def result(found: bool, reason: str, detail: str = "") -> SearchResult:
        nodes: list[int] = []
        if found:
            v = goal
            while v >= 0:
                nodes.append(int(v))
                v = int(parent[v])
            nodes.reverse()
        return SearchResult(found, reason, nodes, float(g[goal]) if found else float("inf"),
                            expansions, checks, rejected, time.monotonic() - t0, detail)

    def repair(v: int) -> None:
        """Best closed parent of v over edges not known to be invalid; re-queue v."""
        cand, _ = graph.successors(v)  # the neighbourhood is symmetric
        cand = cand[closed[cand]]
        best, best_g = -1, np.inf
        if len(cand):
            cost = graph.distance(graph.node_q[v], graph.node_q[cand]) + \
                graph.penalty[graph.node_cell[v]]
            tot = g[cand] + cost
            for i in np.argsort(tot).tolist():
                m = int(cand[i])
                if (m, v) not in invalid:
                    best, best_g = m, float(tot[i])
                    break
        g[v], parent[v] = best_g, best
        if best >= 0:
            heapq.heappush(heap, (best_g + float(heur(np.array([v]))[0]), best_g, v, best))

    while heap:
        _, gu, u, p = heapq.heappop(heap)
        if closed[u] or dead[u] or abs(gu - g[u]) > 1e-12 or p != parent[u]:
            continue  # stale entry
        if p >= 0:
            frac = known.get((p, u), _UNKNOWN)
            if frac is _UNKNOWN:
                if checks >= budget.max_edge_checks:
                    return result(False, REASON_BUDGET, f"{checks} edge checks")
                edges = [(p, u)]
                held: list[tuple[float, float, int, int]] = []
                while heap and len(edges) < budget.edge_batch:
                    e = heapq.heappop(heap)
                    held.append(e)
                    _, gv, v, pv = e
                    if (pv >= 0 and not closed[v] and not dead[v] and abs(gv - g[v]) <= 1e-12
                            and pv == parent[v] and (pv, v) not in known):
                        edges.append((pv, v))
                for e in held:
                    heapq.heappush(heap, e)
                a = np.array([x for x, _ in edges])
                b = np.array([y for _, y in edges])
                fr = check_edges(checker, graph.node_q[a], graph.node_q[b])
                checks += len(edges)
                known.update(zip(edges, fr, strict=True))
                frac = known[(p, u)]
            if frac is not None:
                rejected += 1
                invalid.add((p, u))
                if frac >= 1.0 - 1e-12:
                    dead[u] = True
                    g[u], parent[u] = np.inf, -1
                else:
                    repair(u)
                continue
        closed[u] = True
        if u == goal:
            return result(True, REASON_FOUND)
        expansions += 1
        if expansions > budget.max_expansions:
            return result(False, REASON_BUDGET, f"{budget.max_expansions} expansions")
        if time.monotonic() - t0 > budget.max_seconds:
            return result(False, REASON_SAFETY, f"{budget.max_seconds:g} s of wall time - is "
                          "the machine overloaded?")
        if progress is not None and expansions % 256 == 0:
            progress.update(min(0.99, expansions / budget.max_expansions), "searching roads")
        # successors reached cheaper: g, parent and heuristic set in one compiled pass
        f, gn, vs = expand(u, gu, *graph.shape, graph.searchable, graph.squeeze_blocked,
                           graph.squeeze_exempt, graph.cell_start, graph.node_q,
                           graph.node_cell, graph.weights, float(graph.max_edge), graph.penalty,
                           closed, dead, g, parent, h, q_goal, float(heuristic_weight),
                           _NO_EDGES, graph.extra_cell)
        for fv, gv, v in zip(f.tolist(), gn.tolist(), vs.tolist(), strict=True):
            heapq.heappush(heap, (fv, gv, v, u))
    return result(False, REASON_NO_PATH)
