"""Mission ordering: which application path next, and which way round (SPEC §6).

A mission is start -> N application paths -> goal; only the transfers between paths depend
on the order, so this is a travelling-salesman *path* problem with fixed ends, where a
reversible path may be entered from either end. Exact for up to `exact_limit` paths
(Held-Karp dynamic programming over (visited set, last path, its direction), vectorised per
set), nearest neighbour + 2-opt + Or-opt beyond; for any fixed sequence the best directions
come from a small DP along it, so the local search only moves paths around.

Costs: first estimated (TCP straight-line distance, or a weighted joint distance when
configurations are known), then measured: `measure(a, b)` gives the planned transfer cost.
Measuring every pair means planning 4 N^2 transfers, so measuring is lazy - solve, measure
the transfers the solution uses, re-solve with those replaced, repeat until the solution uses
only measured transfers. When the estimate never exceeds the measured cost (a straight line
is never longer than a planned path) and the solver is exact, the final order is optimal for
the measured costs while measuring only a few transfers.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from assistant.mission.model import ResolvedMission

Array = np.ndarray


@dataclass(frozen=True)
class Endpoint:
    """Where a transfer starts or ends: a TCP position (and the arm's joints if known)."""

    position: Array
    q: Array | None = None
    label: str = ""


CostFn = Callable[[Endpoint, Endpoint], float]


def tcp_distance(a: Endpoint, b: Endpoint) -> float:
    """Straight-line TCP distance: a lower bound on any transfer's TCP path length."""
    return float(np.linalg.norm(np.asarray(a.position) - np.asarray(b.position)))


@dataclass(frozen=True)
class JointDistance:
    """Weighted joint-space distance (e.g. weights = arm radii: metres of arm travel)."""

    weights: Array

    def __call__(self, a: Endpoint, b: Endpoint) -> float:
        if a.q is None or b.q is None:
            return tcp_distance(a, b)
        return float(np.sum(np.asarray(self.weights) * np.abs(np.asarray(a.q) - b.q)))


@dataclass(frozen=True)
class PathEnds:
    """An application path as the ordering sees it: its two ends and whether it may reverse."""

    start: Endpoint
    end: Endpoint
    reversible: bool = False


@dataclass(frozen=True)
class Ordering:
    order: list[int]  # indices into the paths
    reversed: list[bool]  # per position in `order`
    cost: float  # sum of transfer costs (start -> ... -> goal)
    exact: bool  # solved exactly for the cost matrix it used
    method: str
    #: Measurement rounds (0 = estimates only) and how many transfers were measured.
    rounds: int = 0
    measured: int = 0
    #: True when every transfer of the result is a measured one.
    all_measured: bool = False
    transfer_costs: list[float] = field(default_factory=list)


@dataclass(frozen=True)
class OrderingParams:
    exact_limit: int = 8
    #: Local search budget (passes over the 2-opt and Or-opt neighbourhoods).
    max_passes: int = 50
    #: Heuristic: nearest-neighbour tours started from this many different first paths.
    restarts: int = 4
    #: Lazy measuring budget (solve-measure rounds).
    max_rounds: int = 20


def order_paths(
    paths: Sequence[PathEnds],
    start: Endpoint | None,
    goal: Endpoint | None,
    *,
    estimate: CostFn = tcp_distance,
    measure: CostFn | None = None,
    params: OrderingParams | None = None,
) -> Ordering:
    """Order (and orient) the paths between start and goal.

    Without a start the tour begins at the first path chosen; without a goal it ends at the
    last. `measure` returns a planned transfer cost (np.inf if there is no transfer).
    """
    params = params or OrderingParams()
    n = len(paths)
    if n == 0:
        c = 0.0 if start is None or goal is None else _cost(estimate, measure, start, goal)
        return Ordering([], [], c, True, "empty", 0, 0, True, [c] if start and goal else [])
    model = _CostModel(paths, start, goal, estimate)
    solve = _held_karp if n <= params.exact_limit else _heuristic
    result = solve(model.matrix(), n, params)
    rounds = measured = 0
    if measure is not None:
        while rounds < params.max_rounds:
            todo = [e for e in model.edges(result) if e not in model.measured]
            if not todo:
                break
            rounds += 1
            for e in todo:
                model.measure(e, measure)
                measured += 1
            result = solve(model.matrix(), n, params)
    order, rev, cost = result
    edges = model.edges(result)
    transfer = [float(model.matrix()[e]) for e in edges]
    return Ordering(order, rev, float(cost), n <= params.exact_limit,
                    "held-karp" if n <= params.exact_limit else "nn+2opt+oropt", rounds,
                    measured, measure is not None and all(e in model.measured for e in edges),
                    transfer)


def order_mission(mission: ResolvedMission, *, estimate: CostFn = tcp_distance,
                  measure: CostFn | None = None, params: OrderingParams | None = None,
                  ) -> Ordering:
    """Order a mission's paths between its start and goal locations (world frame)."""
    ends = [PathEnds(Endpoint(p.start, label=f"{p.name} start"),
                     Endpoint(p.end, label=f"{p.name} end"), p.reversible)
            for p in mission.paths]
    start = Endpoint(mission.start.position, mission.start.q_hint, mission.start.name) \
        if mission.start else None
    goal = Endpoint(mission.goal.position, mission.goal.q_hint, mission.goal.name) \
        if mission.goal else None
    return order_paths(ends, start, goal, estimate=estimate, measure=measure, params=params)


def _cost(estimate: CostFn, measure: CostFn | None, a: Endpoint, b: Endpoint) -> float:
    return float(measure(a, b) if measure is not None else estimate(a, b))


# ------------------------------------------------------------------------- cost model
#
# Node numbering of the cost matrix: 0 = start, 1 = goal, then 2 + 2 i = start of path i,
# 3 + 2 i = end of path i. A path in direction d (0 forward, 1 reversed) is entered at
# node 2 + 2 i + d and left at node 3 + 2 i - d.


class _CostModel:
    def __init__(self, paths: Sequence[PathEnds], start: Endpoint | None,
                 goal: Endpoint | None, estimate: CostFn):
        self.paths = paths
        self.nodes: list[Endpoint | None] = [start, goal]
        for p in paths:
            self.nodes += [p.start, p.end]
        m = len(self.nodes)
        C = np.full((m, m), np.inf)
        for a in range(m):
            for b in range(m):
                if a != b and self.nodes[a] is not None and self.nodes[b] is not None:
                    C[a, b] = estimate(self.nodes[a], self.nodes[b])
        if start is None:
            C[0, :] = 0.0
        if goal is None:
            C[:, 1] = 0.0
        for i, p in enumerate(paths):  # forbid entering a one-way path at its end
            if not p.reversible:
                C[:, 3 + 2 * i] = np.where(np.arange(m) == 2 + 2 * i, C[:, 3 + 2 * i], np.inf)
        self.C = C
        self.measured: set[tuple[int, int]] = set()

    def matrix(self) -> Array:
        return self.C

    def measure(self, e: tuple[int, int], fn: CostFn) -> None:
        a, b = e
        if self.nodes[a] is None or self.nodes[b] is None:
            self.measured.add(e)  # free start/goal: nothing to plan
            return
        self.C[e] = float(fn(self.nodes[a], self.nodes[b]))
        self.measured.add(e)

    @staticmethod
    def edges(result: tuple[list[int], list[bool], float]) -> list[tuple[int, int]]:
        order, rev, _ = result
        out, here = [], 0
        for i, r in zip(order, rev, strict=True):
            out.append((here, _entry(i, r)))
            here = _exit(i, r)
        out.append((here, 1))
        return out


def _entry(i: int, rev: bool) -> int:
    return 2 + 2 * i + int(rev)


def _exit(i: int, rev: bool) -> int:
    return 3 + 2 * i - int(rev)


# ------------------------------------------------------------------------- exact


def _held_karp(C: Array, n: int, params: OrderingParams) -> tuple[list[int], list[bool], float]:
    """Exact: dp[mask][2 i + d] = cheapest start -> ... -> path i in direction d, over mask."""
    S = 2 * n
    entry = np.array([_entry(k // 2, bool(k % 2)) for k in range(S)])
    exit_ = np.array([_exit(k // 2, bool(k % 2)) for k in range(S)])
    T = C[np.ix_(exit_, entry)]  # state k (left at exit) -> state l (entered)
    first = C[0, entry]
    last = C[exit_, 1]
    full = (1 << n) - 1
    dp = np.full((1 << n, S), np.inf)
    parent = np.full((1 << n, S), -1, dtype=np.int64)
    for k in range(S):
        dp[1 << (k // 2), k] = first[k]
    path_of = np.arange(S) // 2
    for mask in range(1, full + 1):
        row = dp[mask]
        if not np.isfinite(row).any():
            continue
        inside = ((mask >> path_of) & 1).astype(bool)
        cand = row[:, None] + T  # (from state, to state)
        cand[~inside, :] = np.inf
        best_from = np.argmin(cand, axis=0)
        best = cand[best_from, np.arange(S)]
        for l_state in np.nonzero(~inside & np.isfinite(best))[0]:
            nm = mask | (1 << int(path_of[l_state]))
            if best[l_state] < dp[nm, l_state]:
                dp[nm, l_state] = best[l_state]
                parent[nm, l_state] = best_from[l_state]
    total = dp[full] + last
    k = int(np.argmin(total))
    cost = float(total[k])
    states, mask = [], full
    while k >= 0:
        states.append(k)
        pk = int(parent[mask, k])
        mask &= ~(1 << (k // 2))
        k = pk
    states.reverse()
    return [s // 2 for s in states], [bool(s % 2) for s in states], cost


# ------------------------------------------------------------------------- heuristic


def _directions(C: Array, seq: Sequence[int]) -> tuple[list[bool], float]:
    """Best direction of each path for a fixed sequence (DP over two states per path)."""
    c0 = C[0, _entry(seq[0], False)]
    c1 = C[0, _entry(seq[0], True)]
    back: list[tuple[int, int]] = []
    for a, b in zip(seq[:-1], seq[1:], strict=True):
        xa0, xa1 = _exit(a, False), _exit(a, True)
        eb0, eb1 = _entry(b, False), _entry(b, True)
        f0, f1 = c0 + C[xa0, eb0], c1 + C[xa1, eb0]
        g0, g1 = c0 + C[xa0, eb1], c1 + C[xa1, eb1]
        back.append((0 if f0 <= f1 else 1, 0 if g0 <= g1 else 1))
        c0, c1 = min(f0, f1), min(g0, g1)
    c0 += C[_exit(seq[-1], False), 1]
    c1 += C[_exit(seq[-1], True), 1]
    d = 0 if c0 <= c1 else 1
    total = float(min(c0, c1))
    dirs = [d]
    for arg in reversed(back):
        d = arg[d]
        dirs.append(d)
    dirs.reverse()
    return [bool(x) for x in dirs], total


def _heuristic(C: Array, n: int, params: OrderingParams) -> tuple[list[int], list[bool], float]:
    """Nearest neighbour from a few first paths, each improved by 2-opt and Or-opt."""
    firsts = sorted(range(n), key=lambda i: min(C[0, _entry(i, False)], C[0, _entry(i, True)]))
    best_seq, best = None, np.inf
    for first in firsts[: params.restarts]:
        seq, c = _local_search(C, _nearest_neighbour(C, n, first), params)
        if c < best:
            best_seq, best = seq, c
    assert best_seq is not None
    dirs, best = _directions(C, best_seq)
    return best_seq, dirs, best


def _nearest_neighbour(C: Array, n: int, first: int) -> list[int]:
    left = set(range(n)) - {first}
    seq = [first]
    here = _exit(first, bool(C[0, _entry(first, True)] < C[0, _entry(first, False)]))
    while left:
        i, r = min(((i, r) for i in left for r in (False, True)),
                   key=lambda ir: C[here, _entry(*ir)])
        seq.append(i)
        left.remove(i)
        here = _exit(i, r)
    return seq


def _local_search(C: Array, seq: list[int], params: OrderingParams) -> tuple[list[int], float]:
    """2-opt (reverse a stretch) and Or-opt (move a block of 1-3, either way round)."""
    n = len(seq)
    _, best = _directions(C, seq)
    for _ in range(params.max_passes):
        improved = False
        for i, j in itertools.combinations(range(n), 2):
            cand = seq[:i] + seq[i : j + 1][::-1] + seq[j + 1 :]
            _, c = _directions(C, cand)
            if c < best - 1e-12:
                seq, best, improved = cand, c, True
        for size in (1, 2, 3):
            for i in range(n - size + 1):
                block, rest = seq[i : i + size], seq[:i] + seq[i + size :]
                done = False
                for k in range(len(rest) + 1):
                    for blk in ((block, block[::-1]) if size > 1 else (block,)):
                        cand = rest[:k] + blk + rest[k:]
                        if cand == seq:
                            continue
                        _, c = _directions(C, cand)
                        if c < best - 1e-12:
                            seq, best, improved, done = cand, c, True, True
                            break
                    if done:
                        break
        if not improved:
            break
    return seq, best
