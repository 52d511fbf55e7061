"""The primitive fitter's growth, look-ahead and junction refinement (the rules:
`primitives`' module docstring), in Python around the compiled line and arc fits
(`fit_kernels`).

Why Python: the control flow costs ~5 ms a transfer here (the fits it calls are compiled),
well under 0.1 s for a whole mission, while a compiled form of it was the largest compile
of all (~30 s of one core on a first run) for no saving an operator could feel.
"""

from __future__ import annotations

import numpy as np

from assistant.trajectory.fit_kernels import fit_arc, fit_line
from assistant.trajectory.primitives import (
    ArcPrimitive,
    FitParams,
    LinePrimitive,
    Primitive,
    PrimitiveFit,
    PrimitiveKind,
    _norm,
    _rotate_radius,
    _rows,
    _vec,
    finished_fit,
)

Array = np.ndarray
_NO_TANGENT = np.zeros(3)


def _tangent(t0: Array | None) -> Array:
    return _NO_TANGENT if t0 is None else _vec(t0)


def fit_primitives(nodes: Array, params: FitParams | None = None) -> PrimitiveFit:
    """Lines and arcs through ordered nodes (N, 3) within `params.tolerance`."""
    params = params or FitParams()
    nodes = np.ascontiguousarray(nodes, dtype=np.float64)
    n = len(nodes)
    if n < 2:
        raise ValueError("primitive fitting needs at least two nodes")
    fitter = _Fitter(nodes, params)
    prims: list[Primitive] = []
    breaks = 0
    s, O, t_in, prev = 0, nodes[0].copy(), None, None
    while s < n - 1:
        best = fitter.choose(s, O, t_in, prev)
        if best is None:  # nothing tangent fits: make a corner to the next node
            best = LinePrimitive(O, nodes[s + 1].copy(), s, s + 1)
            breaks += 1 if prev is not None else 0
        prims.append(best)
        s, O, t_in, prev = best.last_node, best.end, best.tangent_end, best.kind
    return finished_fit(prims, nodes, breaks)


class _Fitter:
    """Growth and look-ahead over one node list."""

    def __init__(self, nodes: Array, params: FitParams):
        self.nodes = nodes
        self.p = params
        self.n = len(nodes)
        self._reach: dict[tuple, int | None] = {}

    # ------------------------------------------------------------ choice with look-ahead
    def choose(self, s: int, O: Array, t_in: Array | None, prev: PrimitiveKind | None,
               ) -> Primitive | None:
        best, best_score = None, None
        for kind in (PrimitiveKind.LINE, PrimitiveKind.ARC):
            t0 = _constraint(prev, kind, t_in)
            e_max = self.reach(kind, O, t0, s)
            if e_max is None:
                continue
            lo = max(s + _min_nodes(kind), e_max - self.p.lookahead)
            for e in range(e_max, lo - 1, -1):
                # The best score an end node e could get; later (smaller) e get no more.
                if best_score is not None and best_score >= (
                        *self._reach_bound(e), e, kind == PrimitiveKind.LINE):
                    break
                prim = self.fit(kind, O, t0, s, e)
                if prim is None:
                    continue
                # A score below best_score's reach cannot win: skip the full look-ahead.
                if best_score is not None and not self._may_reach(
                        prim, best_score[0], best_score[0]):
                    continue
                score = (*self.next_reach(prim), e, kind == PrimitiveKind.LINE)
                if best_score is None or score > best_score:
                    best, best_score = prim, score
        if best is None or best.last_node == self.n - 1:
            return best
        return self.refine_end(best, best_score[:2])

    def _reach_bound(self, e: int) -> tuple[int, bool]:
        """The most `next_reach` can say for a primitive ending at node e."""
        return (self.n, True) if e == self.n - 1 else (self.n - 1, True)

    def next_reach(self, prim: Primitive) -> tuple[int, bool]:
        """How far the best following primitive gets (n if `prim` ends the path), and
        whether a line gets that far (a line reads better than a flat arc)."""
        e = prim.last_node
        if e == self.n - 1:
            return self.n, True
        r = {k2: (self.reach(k2, prim.end, _constraint(prim.kind, k2, prim.tangent_end), e)
                  or e) for k2 in PrimitiveKind}
        best = max(r.values())
        return best, r[PrimitiveKind.LINE] == best

    def _may_reach(self, prim: Primitive, line_to: int, arc_to: int) -> bool:
        """Whether the line after `prim` may reach node `line_to`, or the arc `arc_to`.

        One fit per type at exactly that end (or the gallop's answer if it is already known)
        instead of a full gallop: the look-ahead asks this of many candidates that cannot
        beat the best one found. Growth is monotone but for rare nodes that fit again after
        one that does not, where the gallop may still land beyond; there, a candidate is
        passed over that the full look-ahead might have preferred.
        """
        e = prim.last_node
        if e == self.n - 1:
            return True
        for kind, target in ((PrimitiveKind.LINE, line_to), (PrimitiveKind.ARC, arc_to)):
            if target <= e:  # any reach counts as e (see `next_reach`)
                return True
            target = max(target, e + _min_nodes(kind))
            if target > self.n - 1:
                continue
            t0 = _constraint(prim.kind, kind, prim.tangent_end)
            key = _reach_key(kind, e, prim.end, t0)
            if key in self._reach:
                if (self._reach[key] or e) >= target:
                    return True
            elif self.fit(kind, prim.end, t0, e, target, True) is not None:
                return True
        return False

    def refine_end(self, prim: Primitive, reach: tuple[int, bool]) -> Primitive:
        """Slide the junction point along the primitive (the thesis' junction calculation).

        The end of a fitted primitive is the projection of its last node; the point where it
        should hand over to the next one (and with it the next one's start tangent) may lie
        a little before or after. Shifts of up to one node spacing are tried (for arcs in
        steps that turn the end tangent by at most the tangent slack), keeping the
        primitive's own nodes within tolerance; the one that lets the next reach farthest
        wins (ties: the smallest shift).
        """
        e = prim.last_node
        pts = self.nodes[prim.first_node + 1 : e + 1]
        spacing = _norm(self.nodes[min(e + 1, self.n - 1)] - self.nodes[e])
        best, best_reach = prim, reach
        step = spacing / 4.0
        if prim.kind == PrimitiveKind.ARC:  # the end tangent turns by step / radius
            step = min(step, prim.radius * self.p.tangent_slack)
        k_max = min(12, max(1, int(np.ceil(spacing / max(step, 1e-9)))))
        for k in sorted(range(-k_max, k_max + 1), key=abs)[1:]:
            if best_reach >= self._reach_bound(e):  # no shift can do better
                break
            cand = _shift_end(prim, k * step)
            if cand is None or cand.distance(pts).max() > self.p.tolerance:
                continue
            # Only a farther reach (or as far, by a line where the best was an arc) wins.
            if not self._may_reach(cand, best_reach[0] + best_reach[1], best_reach[0] + 1):
                continue
            r = self.next_reach(cand)
            if r > best_reach:
                best, best_reach = cand, r
        return best

    def reach(self, kind: PrimitiveKind, O: Array, t0: Array | None, s: int) -> int | None:
        """Largest end node e for which a primitive from O covers nodes s+1..e (galloping).

        Remembered per arguments: the look-ahead of the chosen primitive asks exactly what
        the next `choose` asks first.
        """
        key = _reach_key(kind, s, O, t0)
        if key not in self._reach:
            self._reach[key] = self._gallop(kind, O, t0, s)
        return self._reach[key]

    def _gallop(self, kind: PrimitiveKind, O: Array, t0: Array | None, s: int) -> int | None:
        first = s + _min_nodes(kind)
        if first > self.n - 1 or self.fit(kind, O, t0, s, first, True) is None:
            return None
        good, step = first, 1
        bad = None
        while True:
            e = min(good + step, self.n - 1)
            if e == good:
                return good
            if self.fit(kind, O, t0, s, e, True) is None:
                bad = e
                break
            good, step = e, step * 2
        while bad - good > 1:
            mid = (good + bad) // 2
            if self.fit(kind, O, t0, s, mid, True) is None:
                bad = mid
            else:
                good = mid
        return good

    def fit(self, kind: PrimitiveKind, O: Array, t0: Array | None, s: int, e: int,
            first_feasible: bool = False) -> Primitive | None:
        """The primitive from O covering nodes s+1..e within tolerance, or None.

        Several arc guesses may fit: the closest one is returned, or with `first_feasible`
        (growth only asks whether one exists) the first found.
        """
        pts = self.nodes[s + 1 : e + 1]
        if kind == PrimitiveKind.LINE:
            return self._line(O, t0, pts, s, e)
        return self._arc(O, t0, pts, s, e, first_feasible)

    # ------------------------------------------------------------ lines and arcs
    def _line(self, O: Array, t0: Array | None, pts: Array, s: int, e: int,
              ) -> LinePrimitive | None:
        ok, end = fit_line(_vec(O), _tangent(t0), t0 is not None, _rows(pts),
                           self.p.tolerance, self.p.tangent_slack)
        return LinePrimitive(O, end, s, e) if ok else None

    def _arc(self, O: Array, t0: Array | None, pts: Array, s: int, e: int,
             first_feasible: bool = False) -> ArcPrimitive | None:
        """Arc guesses (`fit_kernels.fit_arc`): after a line or an arc, growth asks only the
        tangent ones. On 134 benchmark fits a free circle fitted where no tangent one did in
        2 of 8100 growth steps, and computing the free guesses for the 5700 steps where none
        fits was a quarter of the fit's time (same primitive count)."""
        p = self.p
        ok, r = fit_arc(_vec(O), _tangent(t0), t0 is not None, _rows(pts), p.tolerance,
                        p.tangent_slack, p.r_min, p.r_max, p.max_sweep, first_feasible)
        if not ok:
            return None
        return ArcPrimitive(O.copy(), r[6:9], r[9:12], r[0:3], float(r[12]), r[3:6],
                            float(r[13]), s, e)


def _constraint(prev: PrimitiveKind | None, kind: PrimitiveKind, t_in: Array | None,
                ) -> Array | None:
    """Tangent a new primitive must start with: none at the start or for a line after a line."""
    if prev is None or (prev == PrimitiveKind.LINE and kind == PrimitiveKind.LINE):
        return None
    return t_in


def _reach_key(kind: PrimitiveKind, s: int, O: Array, t0: Array | None) -> tuple:
    """What `_Fitter.reach` remembers its answers by (the exact start point and tangent)."""
    return kind, s, O.tobytes(), None if t0 is None else t0.tobytes()


def _min_nodes(kind: PrimitiveKind) -> int:
    return 1 if kind == PrimitiveKind.LINE else 2


def _shift_end(prim: Primitive, delta: float) -> Primitive | None:
    """The same primitive with its end moved `delta` metres along it (None if degenerate)."""
    if prim.kind == PrimitiveKind.LINE:
        L = prim.length + delta
        if L <= 1e-9:
            return None
        return LinePrimitive(prim.start, prim.start + L * prim.direction, prim.first_node,
                             prim.last_node)
    sweep = prim.sweep + delta / prim.radius
    if sweep <= 1e-9:
        return None
    r0 = prim.start - prim.centre
    return ArcPrimitive(prim.start, prim.centre + _rotate_radius(r0, prim.normal, sweep / 2),
                        prim.centre + _rotate_radius(r0, prim.normal, sweep), prim.centre,
                        prim.radius, prim.normal, sweep, prim.first_node, prim.last_node)


