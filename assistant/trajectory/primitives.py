"""Line and arc primitives fitted to the smoothed path nodes (thesis §8.6.1-8.6.3).

The robot program should read like a hand-written one: a few MVS/LIN lines and MVR/CIRC arcs
instead of hundreds of points. Nodes come from the elastic net, each with a position
tolerance `tolerance` (the thesis' node spheres). From the current start point a primitive
grows node by node while *every* node it covers stays within the tolerance:

* a line from the start point (its direction fitted through the start point, or fixed to
  the incoming tangent after an arc);
* an arc through the start point whose nodes stay coplanar and on one circle with a radius
  inside [r_min, r_max] and a sweep below `max_sweep` (tangent to the incoming direction
  after a line or an arc).

The thesis grows angle corridors (for lines: the directions through the start that touch all
node spheres; for arcs: a shrinking normal-vector corridor and a feasible radius interval);
we fit the candidate directly and test its true maximum deviation, which is the same
question answered exactly (the fits themselves are compiled: `fit_kernels`). At each start
both types are grown; the thesis keeps the one that covers the most nodes. We add a one-step
look-ahead: for each type, its last few possible end nodes are tried and the choice is the
one that lets the *next* primitive reach farthest (then the most nodes, then a line before
an arc). That is the "care at transition points" of §8.6.3: a line otherwise overshoots into
a following arc by about sqrt(2 R tolerance), and the tangent arc after it can then not fit.

Joints: line/arc, arc/line and arc/arc are tangent by construction (the next primitive
starts at the previous end with its end tangent). Line/line corners are left to the
controller's blending (CNT / C_DIS). The first primitive starts at the first node and the
last ends exactly at the last node (the taught goal), which may bend its final tangency by a
fraction of the tolerance; the fit reports every required joint's tangency error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from assistant.trajectory.fit_kernels import (
    arc_distances,
    circle_through_kernel,
    fit_arc,
    fit_line,
    line_distances,
)

Array = np.ndarray


class PrimitiveKind(str, Enum):
    LINE = "line"
    ARC = "arc"


@dataclass(frozen=True)
class LinePrimitive:
    """A straight TCP move; it covers nodes first_node..last_node of the fitted path."""

    start: Array
    end: Array
    first_node: int
    last_node: int

    kind = PrimitiveKind.LINE

    @property
    def length(self) -> float:
        return _norm(self.end - self.start)

    @property
    def direction(self) -> Array:
        d = self.end - self.start
        return d / max(_norm(d), 1e-15)

    @property
    def tangent_start(self) -> Array:
        return self.direction

    @property
    def tangent_end(self) -> Array:
        return self.direction

    def point_at(self, u: Array | float) -> Array:
        """Points at fractions u in [0, 1] of the length."""
        u = np.asarray(u, dtype=float)
        return self.start + u[..., None] * (self.end - self.start)

    def distance(self, points: Array) -> Array:
        """Distance of each point to the segment."""
        return line_distances(_vec(self.start), _vec(self.end), _rows(points))


@dataclass(frozen=True)
class ArcPrimitive:
    """A circular TCP move start -> via -> end about `centre`, turning about `normal`."""

    start: Array
    via: Array
    end: Array
    centre: Array
    radius: float
    normal: Array  # unit rotation axis: start turns into end right-handed about it
    sweep: float  # radians, in (0, 2 pi)
    first_node: int
    last_node: int

    kind = PrimitiveKind.ARC

    @property
    def length(self) -> float:
        return self.radius * self.sweep

    @property
    def tangent_start(self) -> Array:
        return _unit(_cross(self.normal, self.start - self.centre))

    @property
    def tangent_end(self) -> Array:
        return _unit(_cross(self.normal, self.end - self.centre))

    def point_at(self, u: Array | float) -> Array:
        """Points at fractions u in [0, 1] of the sweep."""
        a = np.asarray(u, dtype=float)[..., None] * self.sweep
        r0 = self.start - self.centre
        return self.centre + np.cos(a) * r0 + np.sin(a) * _cross(self.normal, r0)

    def distance(self, points: Array) -> Array:
        """Distance of each point to the arc (not the full circle)."""
        return arc_distances(_vec(self.start), _vec(self.end), _vec(self.centre),
                             float(self.radius), _vec(self.normal), float(self.sweep),
                             _rows(points))

    @staticmethod
    def through(start: Array, via: Array, end: Array, first_node: int = 0,
                last_node: int = 0) -> ArcPrimitive:
        """The arc from start through via to end (raises on collinear points)."""
        start, via, end = (np.asarray(p, dtype=float) for p in (start, via, end))
        centre, radius, n = circle_through(start, via, end)
        phi_via = _angles_about(start - centre, (via - centre)[None], n)[0]
        phi_end = _angles_about(start - centre, (end - centre)[None], n)[0]
        if phi_via > phi_end:  # via not between: the arc turns the other way
            n = -n
            phi_end = 2.0 * np.pi - phi_end
        mid = centre + _rotate_radius(start - centre, n, phi_end / 2.0)
        return ArcPrimitive(start, mid, end, centre, radius, n, float(phi_end), first_node,
                            last_node)


Primitive = LinePrimitive | ArcPrimitive


@dataclass(frozen=True)
class FitParams:
    #: Largest allowed distance of a node from its primitive (m): the node spheres.
    tolerance: float = 0.002
    r_min: float = 0.005
    #: Arcs flatter than this are not arcs (a line covers them, or they are split).
    r_max: float = 1.0
    max_sweep: float = np.radians(300.0)
    #: How many end nodes below a primitive's longest reach the look-ahead tries.
    lookahead: int = 8
    #: Tangent joints may kink by up to this angle (rad). The node tolerance makes a fitted
    #: arc's end tangent uncertain by about tolerance / arc length; forcing the next line
    #: onto it exactly would break a long line into pieces. Controllers blend such kinks.
    tangent_slack: float = np.radians(1.0)


@dataclass(frozen=True)
class PrimitiveFit:
    primitives: list[Primitive]
    #: Distance of every node to the primitive it was assigned to (m).
    node_deviation: Array
    #: Angle (rad) between consecutive primitives at joints that must be tangent
    #: (None at line/line corners, which the controller blends).
    tangency_error: list[float | None]
    #: Joints where no tangent continuation was feasible and a corner was made instead.
    tangency_breaks: int

    @property
    def max_deviation(self) -> float:
        return float(self.node_deviation.max(initial=0.0))

    def counts(self) -> dict[str, int]:
        out = {"line": 0, "arc": 0}
        for p in self.primitives:
            out[p.kind.value] += 1
        return out

    @property
    def length(self) -> float:
        return float(sum(p.length for p in self.primitives))


def fit_primitives(nodes: Array, params: FitParams | None = None) -> PrimitiveFit:
    """Lines and arcs through ordered nodes (N, 3) within `params.tolerance`."""
    params = params or FitParams()
    nodes = np.asarray(nodes, dtype=float)
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
    prims[-1] = _snap_end(prims[-1], nodes[-1])
    # Node k belongs to the primitive covering it: each one covers first_node+1..last_node
    # (its first node is the previous primitive's last); node 0 is the start point.
    dev = np.zeros(n)
    for p in prims:
        rng = slice(p.first_node + 1, p.last_node + 1)
        dev[rng] = p.distance(nodes[rng])
    tangency: list[float | None] = []
    for a, b in zip(prims[:-1], prims[1:], strict=True):
        if a.kind == PrimitiveKind.LINE and b.kind == PrimitiveKind.LINE:
            tangency.append(None)
        else:
            c = float(np.clip(a.tangent_end @ b.tangent_start, -1.0, 1.0))
            tangency.append(float(np.arccos(c)))
    return PrimitiveFit(prims, dev, tangency, breaks)


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


def sample_primitive(prim: Primitive, max_step: float) -> tuple[Array, Array]:
    """Fractions u (0..1, always with 0 and 1; arcs also with 0.5, the via) and TCP points,
    at most `max_step` apart along the primitive."""
    n = max(1, int(np.ceil(prim.length / max_step)))
    if prim.kind == PrimitiveKind.ARC:
        n += n % 2
        n = max(n, 2)
    u = np.linspace(0.0, 1.0, n + 1)
    return u, np.atleast_2d(prim.point_at(u))


def circle_through(a: Array, b: Array, c: Array) -> tuple[Array, float, Array]:
    """Centre, radius and unit normal (a->b->c right-handed) of the circle through 3 points."""
    ok, centre, radius, n = circle_through_kernel(_vec(a), _vec(b), _vec(c))
    if not ok:
        raise ValueError("the three points are collinear")
    return centre, radius, n


def _angles_about(r0: Array, V: Array, normal: Array) -> Array:
    """Angle in [0, 2 pi) from r0 to each row of V, right-handed about `normal`."""
    x = V @ r0
    y = V @ _cross(normal, r0)
    return np.mod(np.arctan2(y, x), 2.0 * np.pi)


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


def _snap_end(prim: Primitive, goal: Array) -> Primitive:
    """End the last primitive exactly on the last node (the taught goal)."""
    if prim.kind == PrimitiveKind.LINE:
        return LinePrimitive(prim.start, goal.copy(), prim.first_node, prim.last_node)
    try:
        return ArcPrimitive.through(prim.start, prim.via, goal, prim.first_node, prim.last_node)
    except ValueError:
        return LinePrimitive(prim.start, goal.copy(), prim.first_node, prim.last_node)


def _cross(a: Array, b: Array) -> Array:
    """Cross product of two 3-vectors through Python floats (the same IEEE products as
    np.cross, without its axis handling, which cost more than the product)."""
    a0, a1, a2 = np.asarray(a, dtype=float).tolist()
    b0, b1, b2 = np.asarray(b, dtype=float).tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _rotate_radius(r0: Array, normal: Array, angle: float) -> Array:
    """r0 (perpendicular to the unit normal) turned by angle about it."""
    return np.cos(angle) * r0 + np.sin(angle) * _cross(normal, r0)


def _norm(v: Array) -> float:
    """Length of one vector: what np.linalg.norm computes (sqrt of the dot product), without
    its dispatch overhead."""
    return math.sqrt(float(v @ v))


def _unit(v: Array) -> Array:
    v = np.asarray(v, dtype=float)
    n = _norm(v)
    return v / n if n > 1e-15 else v * 0.0


def _vec(v: Array) -> Array:
    """A contiguous float64 3-vector, as the kernels are compiled for."""
    return np.ascontiguousarray(v, dtype=np.float64)


def _rows(points: Array) -> Array:
    return np.ascontiguousarray(np.atleast_2d(points), dtype=np.float64)


_NO_TANGENT = np.zeros(3)


def _tangent(t0: Array | None) -> Array:
    return _NO_TANGENT if t0 is None else _vec(t0)
