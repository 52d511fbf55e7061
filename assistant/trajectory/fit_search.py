"""The primitive fitter's growth, look-ahead and junction refinement, compiled (numba).

Why: with the line and arc fits compiled (`fit_kernels`), the rest of a transfer's fit is
control flow around them, ~2.5 ms in Python: ~250 fits, gallops, look-ahead scores,
shifted ends and their primitives as objects, a dict of remembered reaches. Here the same
steps run in one compiled call and return the primitives as rows; `primitives` turns them
into `LinePrimitive`/`ArcPrimitive` objects. The rules are `primitives`' (its module
docstring), step for step and in the same order: the test fits recorded and synthetic node
lists with this kernel and with a Python formulation (`tests/trajectory/
fit_reference.py`) and asks for the same primitives to the bit.

A primitive is one row of `N_FIELDS` floats: kind (0 line, 1 arc), start, end, via, centre,
radius, normal, sweep, first node, last node (lines leave via..sweep at 0). A "reach" of
None is -1 (remembered per start point and tangent in arrays sized for the worst case,
`_new_memo`); look-ahead scores (reach, a line gets there, end node, is a line) compare as
tuples through `_score`.

Serves (the user-felt figure): the fitter's search: under 0.1 s of its own in Python in the
thesis run (the fits it calls are in fit_kernels); the largest compile (~30 s of one core),
the first candidate to drop.
"""

from __future__ import annotations

import math

import numpy as np

from assistant.kernels.lazy import kernel
from assistant.trajectory.fit_kernels import (
    _dot,
    _unit3,
    arc_deviation,
    fit_arc,
    fit_line,
    line_deviation,
    put_on_arc,
)

Array = np.ndarray

LINE, ARC = 0, 1
N_FIELDS = 20
_KIND, _START, _END, _VIA, _CENTRE, _RADIUS, _NORMAL, _SWEEP, _FIRST, _LAST = (
    0, 1, 4, 7, 10, 13, 14, 17, 18, 19)
_JIT = {"cache": True, "error_model": "numpy"}
#: Flags passed as numpy booleans, not literals: numba compiles a callee once per literal
#: argument value, and each copy re-optimises the fits it calls (~45 s of compiling).
_YES, _NO = np.bool_(True), np.bool_(False)
#: The fit and its gallop are inlined (numba IR) where they are asked: each level of calls
#: links and optimises the fits below it again (28 s to compile instead of 33 s).
_INLINE = {**_JIT, "inline": "always"}


@kernel(**_JIT)
def _line(O: Array, end: Array, s: int, e: int) -> Array:
    p = np.zeros(N_FIELDS)
    p[_KIND] = LINE
    p[_START:_START + 3] = O
    p[_END:_END + 3] = end
    p[_FIRST], p[_LAST] = s, e
    return p


@kernel(**_JIT)
def _arc(O: Array, r: Array, s: int, e: int) -> Array:
    """From `fit_arc`'s answer: centre r[0:3], normal r[3:6], via r[6:9], end r[9:12],
    radius r[12], sweep r[13]."""
    p = np.zeros(N_FIELDS)
    p[_KIND] = ARC
    p[_START:_START + 3] = O
    p[_VIA:_VIA + 3] = r[6:9]
    p[_END:_END + 3] = r[9:12]
    p[_CENTRE:_CENTRE + 3] = r[0:3]
    p[_RADIUS] = r[12]
    p[_NORMAL:_NORMAL + 3] = r[3:6]
    p[_SWEEP] = r[13]
    p[_FIRST], p[_LAST] = s, e
    return p


@kernel(**_JIT)
def _tangent_end(p: Array) -> Array:
    """Unit direction of the primitive at its end: as scalars into one array (the same
    operations as `d / max(|d|, 1e-15)` for a line, `_unit(normal x (end - centre))` for an
    arc, without an array per intermediate)."""
    t = np.empty(3)
    if p[_KIND] == LINE:
        d0, d1, d2 = p[_END] - p[_START], p[_END + 1] - p[_START + 1], p[_END + 2] - p[_START + 2]
        n = max(math.sqrt(d0 * d0 + d1 * d1 + d2 * d2), 1e-15)
        t[0], t[1], t[2] = d0 / n, d1 / n, d2 / n
        return t
    n0, n1, n2 = p[_NORMAL], p[_NORMAL + 1], p[_NORMAL + 2]
    v0, v1, v2 = (p[_END] - p[_CENTRE], p[_END + 1] - p[_CENTRE + 1],
                  p[_END + 2] - p[_CENTRE + 2])
    t[0], t[1], t[2] = _unit3(n1 * v2 - n2 * v1, n2 * v0 - n0 * v2, n0 * v1 - n1 * v0)
    return t


@kernel(**_JIT)
def _max_distance(p: Array, pts: Array) -> float:
    """Largest distance of the points to the primitive; NaN if any is (as numpy's max)."""
    if p[_KIND] == LINE:
        return line_deviation(p[_START:_START + 3], p[_END:_END + 3], pts)
    return arc_deviation(p[_START:_START + 3], p[_END:_END + 3], p[_CENTRE:_CENTRE + 3],
                         p[_RADIUS], p[_NORMAL:_NORMAL + 3], p[_SWEEP], pts)


@kernel(**_JIT)
def _shift_end(p: Array, delta: float) -> tuple[bool, Array]:
    """The same primitive with its end moved `delta` metres along it (False if degenerate)."""
    start = p[_START:_START + 3]
    if p[_KIND] == LINE:
        d = p[_END:_END + 3] - start
        norm = math.sqrt(_dot(d, d))
        length = norm + delta
        if length <= 1e-9:
            return False, p
        return True, _line(start.copy(), start + length * (d / max(norm, 1e-15)),
                           int(p[_FIRST]), int(p[_LAST]))
    sweep = p[_SWEEP] + delta / p[_RADIUS]
    if sweep <= 1e-9:
        return False, p
    centre, normal = p[_CENTRE:_CENTRE + 3], p[_NORMAL:_NORMAL + 3]
    r0 = start - centre
    q = p.copy()
    put_on_arc(centre, r0, normal, sweep / 2, q, _VIA)
    put_on_arc(centre, r0, normal, sweep, q, _END)
    q[_SWEEP] = sweep
    return True, q


@kernel(**_JIT)
def _min_nodes(kind: int) -> int:
    return 1 if kind == LINE else 2


@kernel(**_JIT)
def _score(reach: int, line_gets_there: bool, e: int, is_line: bool, n: int) -> int:
    """The tuple (reach, line_gets_there, e, is_line) as one integer of the same order
    (reach <= n, e < n + 1)."""
    return ((reach * 2 + int(line_gets_there)) * (n + 1) + e) * 2 + int(is_line)


@kernel(**_INLINE)
def _fit(kind: int, O: Array, has_t0: bool, t0: Array, s: int, e: int, first_feasible: bool,
         nodes: Array, par: Array) -> tuple[bool, Array]:
    """The primitive from O covering nodes s+1..e within tolerance (`_Fitter.fit`)."""
    pts = nodes[s + 1 : e + 1]
    if kind == LINE:
        ok, end = fit_line(O, t0, has_t0, pts, par[0], par[4])
        return ok, _line(O.copy(), end, s, e)
    ok, r = fit_arc(O, t0, has_t0, pts, par[0], par[4], par[1], par[2], par[3],
                    first_feasible)
    return ok, _arc(O.copy(), r, s, e)


@kernel(**_INLINE)
def _gallop(kind: int, O: Array, has_t0: bool, t0: Array, s: int, nodes: Array,
            par: Array) -> int:
    n = nodes.shape[0]
    first = s + _min_nodes(kind)
    if first > n - 1 or not _fit(kind, O, has_t0, t0, s, first, _YES, nodes, par)[0]:
        return -1
    good, step = first, 1
    bad = -1
    while True:
        e = min(good + step, n - 1)
        if e == good:
            return good
        if not _fit(kind, O, has_t0, t0, s, e, _YES, nodes, par)[0]:
            bad = e
            break
        good, step = e, step * 2
    while bad - good > 1:
        mid = (good + bad) // 2
        if not _fit(kind, O, has_t0, t0, s, mid, _YES, nodes, par)[0]:
            bad = mid
        else:
            good = mid
    return good


@kernel(**_JIT)
def _new_memo(n: int, lookahead: int) -> tuple[Array, Array, Array, Array, Array]:
    """Room for every reach a fit of n nodes can remember: (head (2, n + 1): each (kind,
    start node)'s latest entry or -1, and in head[0, n] the entries used; next entry of the
    same bucket; start points; tangents (has, t); reaches).

    A choice at one node remembers at most 2 reaches from its start, 2 per look-ahead
    candidate (2 kinds x lookahead + 1 ends) and 2 per junction shift (at most 24): a
    cache evicting entries could change answers (`_may_reach` asks the cache first)."""
    head = np.full((2, n + 1), -1, dtype=np.int64)
    head[0, n] = 0
    cap = (2 + 4 * (lookahead + 1) + 48) * n
    return (head, np.empty(cap, dtype=np.int64), np.empty((cap, 3)), np.empty((cap, 4)),
            np.empty(cap, dtype=np.int64))


@kernel(**_JIT)
def _find(memo, kind: int, s: int, O: Array, has_t0: bool, t0: Array) -> int:
    """Index of the reach remembered for (kind, s, O, t0), or -1: the exact start point and
    tangent, as the Python fitter's dict keyed by their bytes."""
    head, nxt, pts, tan, _ = memo
    i = head[kind, s]
    while i >= 0:
        if (pts[i, 0] == O[0] and pts[i, 1] == O[1] and pts[i, 2] == O[2]
                and (tan[i, 0] != 0.0) == has_t0 and tan[i, 1] == t0[0]
                and tan[i, 2] == t0[1] and tan[i, 3] == t0[2]):
            return i
        i = nxt[i]
    return -1


@kernel(**_JIT)
def _remember(memo, kind: int, s: int, O: Array, has_t0: bool, t0: Array,
              value: int) -> None:
    head, nxt, pts, tan, val = memo
    n = head.shape[1] - 1
    i = head[0, n]
    head[0, n] = i + 1
    nxt[i] = head[kind, s]
    head[kind, s] = i
    pts[i] = O
    tan[i, 0] = 1.0 if has_t0 else 0.0
    tan[i, 1:] = t0
    val[i] = value


@kernel(**_INLINE)
def _reach(kind: int, O: Array, has_t0: bool, t0: Array, s: int, nodes: Array, par: Array,
           memo) -> int:
    """Largest end node a primitive from O covers nodes s+1.. to (-1: none), remembered."""
    i = _find(memo, kind, s, O, has_t0, t0)
    if i >= 0:
        return memo[4][i]
    v = _gallop(kind, O, has_t0, t0, s, nodes, par)
    _remember(memo, kind, s, O, has_t0, t0, v)
    return v


@kernel(**_JIT)
def _constraint(prev: int, kind: int) -> bool:
    """Whether a primitive of `kind` after one of `prev` (-1: none) must start tangent."""
    return not (prev < 0 or (prev == LINE and kind == LINE))


@kernel(**_JIT)
def _next_reach(p: Array, nodes: Array, par: Array, memo) -> tuple[int, bool]:
    n = nodes.shape[0]
    e = int(p[_LAST])
    if e == n - 1:
        return n, True
    end, t = p[_END:_END + 3].copy(), _tangent_end(p)
    zero = np.zeros(3)
    kind = int(p[_KIND])
    r = np.empty(2, dtype=np.int64)
    for k2 in (LINE, ARC):
        has = _constraint(kind, k2)
        v = _reach(k2, end, has, t if has else zero, e, nodes, par, memo)
        r[k2] = v if v > 0 else e
    best = max(r[0], r[1])
    return best, r[LINE] == best


@kernel(**_JIT)
def _may_reach(p: Array, line_to: int, arc_to: int, nodes: Array, par: Array, memo) -> bool:
    """Whether the line after p may reach `line_to`, or the arc `arc_to` (`_Fitter`)."""
    n = nodes.shape[0]
    e = int(p[_LAST])
    if e == n - 1:
        return True
    end, t = p[_END:_END + 3].copy(), _tangent_end(p)
    zero = np.zeros(3)
    kind = int(p[_KIND])
    for k2 in (LINE, ARC):
        target = line_to if k2 == LINE else arc_to
        if target <= e:
            return True
        target = max(target, e + _min_nodes(k2))
        if target > n - 1:
            continue
        has = _constraint(kind, k2)
        t0 = t if has else zero
        i = _find(memo, k2, e, end, has, t0)
        if i >= 0:
            v = memo[4][i]
            if (v if v > 0 else e) >= target:
                return True
        elif _fit(k2, end, has, t0, e, target, _YES, nodes, par)[0]:
            return True
    return False


@kernel(**_JIT)
def _refine_end(p: Array, reach: int, line_gets_there: bool, nodes: Array, par: Array,
                memo) -> Array:
    """Slide the junction point along the primitive (`_Fitter.refine_end`)."""
    n = nodes.shape[0]
    e = int(p[_LAST])
    pts = nodes[int(p[_FIRST]) + 1 : e + 1]
    d = nodes[min(e + 1, n - 1)] - nodes[e]
    spacing = math.sqrt(_dot(d, d))
    best = p
    b_r, b_l = reach, line_gets_there
    bound = n if e == n - 1 else n - 1
    step = spacing / 4.0
    if p[_KIND] == ARC:
        step = min(step, p[_RADIUS] * par[4])
    k_max = min(12, max(1, int(math.ceil(spacing / max(step, 1e-9)))))
    for i in range(2 * k_max):
        k = (i // 2 + 1) * (-1 if i % 2 == 0 else 1)  # -1, 1, -2, 2, ...
        if b_r * 2 + int(b_l) >= bound * 2 + 1:  # no shift can do better
            break
        ok, cand = _shift_end(p, k * step)
        if not ok or _max_distance(cand, pts) > par[0]:
            continue
        if not _may_reach(cand, b_r + int(b_l), b_r + 1, nodes, par, memo):
            continue
        r, lg = _next_reach(cand, nodes, par, memo)
        if r * 2 + int(lg) > b_r * 2 + int(b_l):
            best, b_r, b_l = cand, r, lg
    return best


@kernel(**_JIT)
def _choose(s: int, O: Array, t_in: Array, prev: int, nodes: Array, par: Array,
            lookahead: int, memo) -> tuple[bool, Array]:
    """The primitive from O at node s whose successor reaches farthest (`_Fitter.choose`)."""
    n = nodes.shape[0]
    zero = np.zeros(3)
    best = np.zeros(N_FIELDS)
    found = False
    best_score = -1
    b_r, b_l = np.int64(0), np.bool_(False)
    for kind in (LINE, ARC):
        has = _constraint(prev, kind)
        t0 = t_in if has else zero
        e_max = _reach(kind, O, has, t0, s, nodes, par, memo)
        if e_max < 0:
            continue
        lo = max(s + _min_nodes(kind), e_max - lookahead)
        for e in range(e_max, lo - 1, -1):
            bound = n if e == n - 1 else n - 1
            if found and best_score >= _score(bound, np.bool_(True), e, kind == LINE, n):
                break
            ok, prim = _fit(kind, O, has, t0, s, e, _NO, nodes, par)
            if not ok:
                continue
            if found and not _may_reach(prim, b_r, b_r, nodes, par, memo):
                continue
            r, lg = _next_reach(prim, nodes, par, memo)
            score = _score(r, lg, e, kind == LINE, n)
            if not found or score > best_score:
                best, best_score, b_r, b_l, found = prim, score, r, lg, True
    if not found or int(best[_LAST]) == n - 1:
        return found, best
    return True, _refine_end(best, b_r, b_l, nodes, par, memo)


@kernel(**_JIT)
def fit_rows(nodes: Array, par: Array, lookahead: int) -> tuple[Array, int]:
    """Primitives (m, N_FIELDS) through the nodes (n >= 2, C-contiguous (n, 3)) and the
    number of corners made where nothing tangent fitted. par = (tolerance, r_min, r_max,
    max_sweep, tangent_slack). The last primitive ends at its fitted end, not yet on the
    last node (`primitives.fit_primitives` snaps it)."""
    n = nodes.shape[0]
    memo = _new_memo(n, lookahead)
    out = np.empty((n, N_FIELDS))
    m = 0
    breaks = 0
    s, O, t_in, prev = np.int64(0), nodes[0].copy(), np.zeros(3), np.int64(-1)
    while s < n - 1:
        ok, best = _choose(s, O, t_in, prev, nodes, par, lookahead, memo)
        if not ok:  # nothing tangent fits: make a corner to the next node
            best = _line(O.copy(), nodes[s + 1].copy(), s, s + 1)
            breaks += 1 if prev >= 0 else 0
        out[m] = best
        m += 1
        s, O, t_in, prev = (int(best[_LAST]), best[_END:_END + 3].copy(), _tangent_end(best),
                            int(best[_KIND]))
    return out[:m].copy(), breaks
