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
question answered exactly. At each start both types are grown; the thesis keeps the one that
covers the most nodes. We add a one-step look-ahead: for each type, its last few possible
end nodes are tried and the choice is the one that lets the *next* primitive reach farthest
(then the most nodes, then a line before an arc). That is the "care at transition points"
of §8.6.3: a line otherwise overshoots into a following arc by about sqrt(2 R tolerance),
and the tangent arc after it can then not fit.

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
        d = self.end - self.start
        L2 = float(d @ d)
        X = np.atleast_2d(points) - self.start
        s = np.clip(X @ d / L2, 0.0, 1.0) if L2 > 0 else np.zeros(len(X))
        return np.linalg.norm(X - s[:, None] * d, axis=1)


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
        X = np.atleast_2d(points) - self.centre
        h = X @ self.normal
        V = X - h[:, None] * self.normal
        rho = np.linalg.norm(V, axis=1)
        phi = _angles_about(self.start - self.centre, V, self.normal)
        on = phi <= self.sweep + 1e-12
        d_arc = np.sqrt(h ** 2 + (rho - self.radius) ** 2)
        d_end = np.minimum(np.linalg.norm(np.atleast_2d(points) - self.start, axis=1),
                           np.linalg.norm(np.atleast_2d(points) - self.end, axis=1))
        return np.where(on, d_arc, d_end)

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

    # ------------------------------------------------------------ lines
    def _line(self, O: Array, t0: Array | None, pts: Array, s: int, e: int,
              ) -> LinePrimitive | None:
        X = pts - O
        _, _, Vt = np.linalg.svd(X, full_matrices=False)
        d_ls = Vt[0] * np.sign(Vt[0] @ X.sum(axis=0) or 1.0)
        if t0 is not None:
            dirs = [t0, _within_cone(d_ls, t0, self.p.tangent_slack)]
        else:
            dirs = [d_ls, _unit(X[-1])]
        tol = self.p.tolerance
        for d in dirs:
            proj = X @ d
            if proj[-1] <= 0.0 or np.any(np.diff(proj) < -tol):
                continue
            prim = LinePrimitive(O, O + proj[-1] * d, s, e)
            if prim.distance(pts).max() <= tol:
                return prim
        return None

    # ------------------------------------------------------------ arcs
    def _arc(self, O: Array, t0: Array | None, pts: Array, s: int, e: int,
             first_feasible: bool = False) -> ArcPrimitive | None:
        X = pts - O
        if len(X) < 2 or _norm(X[-1]) < 1e-9:
            return None
        # Tangent guesses, and free circles whose start tangent is within the slack.
        kinds = (t0, None) if t0 is not None else (None,)
        if first_feasible:
            # Growth asks whether any guess fits: after a line or an arc only the tangent
            # ones are asked. On 134 benchmark fits a free circle fitted where no tangent one
            # did in 2 of 8100 growth steps, and computing the free guesses for the 5700
            # steps where none fits was a quarter of the fit's time (same primitive count).
            batches = (self._arc_candidates(O, t, X) for t in kinds[:1])
        else:  # the closest of all guesses
            batches = [[g for t in kinds for g in self._arc_candidates(O, t, X)]]
        best = None
        for cands in batches:
            for centre, normal in self._on_circle(O, cands, pts):
                prim = self._arc_from(O, centre, normal, pts, s, e, tangent=t0)
                if prim is None:
                    continue
                if first_feasible:
                    return prim[0]
                if best is None or prim[1] < best[1]:
                    best = prim
        return None if best is None else best[0]

    def _arc_candidates(self, O: Array, t0: Array | None, X: Array) -> list[tuple[Array, Array]]:
        """(centre, plane normal) guesses: least squares, and the circle through O/mid/last."""
        out = []
        if t0 is None:
            _, _, Vt = np.linalg.svd(X, full_matrices=False)
            n = Vt[2] if Vt.shape[0] > 2 else _unit(_cross(X[0], X[-1]))
            if _norm(n) < 0.5:
                return out
            e1 = _unit(X[-1] - (X[-1] @ n) * n)
            e2 = _cross(n, e1)
            xy = np.stack([X @ e1, X @ e2], axis=1)
            c2, *_ = np.linalg.lstsq(2.0 * xy, (xy ** 2).sum(axis=1), rcond=None)
            out.append((O + c2[0] * e1 + c2[1] * e2, n))
            try:
                c, _, n3 = circle_through(O, O + X[len(X) // 2], O + X[-1])
                out.append((c, n3))
            except ValueError:
                pass
        else:
            b1 = _unit(_cross(t0, [1.0, 0.0, 0.0] if abs(t0[0]) < 0.9 else [0.0, 1.0, 0.0]))
            b2 = _cross(t0, b1)
            Y = np.stack([X @ b1, X @ b2], axis=1)
            # Plane through O containing t0: its normal is the least-variance direction of the
            # nodes' components across t0.
            _, _, Vt = np.linalg.svd(Y, full_matrices=False)
            for m_coef in (Vt[0], _unit(Y[-1]) if _norm(Y[-1]) > 1e-12 else None):
                if m_coef is None:
                    continue
                m = m_coef[0] * b1 + m_coef[1] * b2  # in-plane normal to t0
                r2 = (X ** 2).sum(axis=1)
                xm = X @ m
                denom = float((r2 ** 2).sum())
                kappa = float(2.0 * (xm * r2).sum() / denom) if denom > 0 else 0.0
                if abs(kappa) < 1e-9:
                    continue
                out.append((O + m / kappa, _unit(_cross(t0, m / kappa))))
                # exact circle tangent at O through the last node
                xl, rl = float(X[-1] @ m), float(X[-1] @ X[-1])
                if abs(xl) > 1e-12:
                    k2 = 2.0 * xl / rl
                    out.append((O + m / k2, _unit(_cross(t0, m / k2))))
        return out

    def _on_circle(self, O: Array, cands: list[tuple[Array, Array]], pts: Array,
                   ) -> list[tuple[Array, Array]]:
        """The guesses (centre, unit normal) whose circle through O passes within the
        tolerance of every node, with a radius in [r_min, r_max], in their order.

        The arc is part of its circle, so the rest need not be tried; all guesses are tested
        in one batch (most end here). Normals come back perpendicular to the radius at O.
        """
        if not cands:
            return []
        p = self.p
        C = np.array([c for c, _ in cands])
        N = np.array([n for _, n in cands])
        R0 = O - C
        r2 = np.einsum("kj,kj->k", R0, R0)
        with np.errstate(invalid="ignore", divide="ignore"):
            N = N - (np.einsum("kj,kj->k", N, R0) / r2)[:, None] * R0
            N /= np.sqrt(np.einsum("kj,kj->k", N, N))[:, None]
            X = pts[None] - C[:, None]
            h = np.einsum("kmj,kj->km", X, N)
            W = X - h[..., None] * N[:, None]
            rho = np.sqrt(np.einsum("kmj,kmj->km", W, W))
            dev2 = (h * h + (rho - np.sqrt(r2)[:, None]) ** 2).max(axis=1)
            keep = ((r2 >= p.r_min ** 2) & (r2 <= p.r_max ** 2) & np.isfinite(C).all(axis=1)
                    & (dev2 <= p.tolerance ** 2))
        return [(C[k], N[k]) for k in np.nonzero(keep)[0]]

    def _arc_from(self, O: Array, centre: Array, normal: Array, pts: Array, s: int, e: int,
                  tangent: Array | None) -> tuple[ArcPrimitive, float] | None:
        """The arc about `centre` (a guess passed by `_on_circle`) from O over the nodes."""
        p, tol = self.p, self.p.tolerance
        r0 = O - centre
        radius = _norm(r0)
        X = pts - centre
        V = np.vstack([r0, X - (X @ normal)[:, None] * normal])
        # Unwrapped angle of each node about the normal: sum of the signed steps between
        # consecutive radius vectors (handles sweeps past pi and noise near the start).
        cr = _cross(V[:-1], V[1:]) @ normal
        dt = np.einsum("ij,ij->i", V[:-1], V[1:])
        phi = np.cumsum(np.arctan2(cr, dt))
        if phi[-1] < 0.0:
            normal, phi = -normal, -phi
        if tangent is not None:
            t_start = _unit(_cross(normal, r0))
            if t_start @ tangent < np.cos(p.tangent_slack) - 1e-12:
                return None
        slack = tol / radius
        if np.any(np.diff(phi) < -slack) or phi[-1] > p.max_sweep or phi[-1] <= 0.0:
            return None
        sweep = float(phi[-1])
        end = centre + _rotate_radius(r0, normal, sweep)
        via = centre + _rotate_radius(r0, normal, sweep / 2.0)
        prim = ArcPrimitive(O.copy(), via, end, centre, radius, normal, sweep, s, e)
        dev = float(prim.distance(pts).max())
        if dev > tol:
            return None
        return prim, dev


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
    ab, ac = b - a, c - a
    n = _cross(ab, ac)
    nn = float(n @ n)
    if nn < 1e-18 * max(1e-30, float(ab @ ab) * float(ac @ ac)):
        raise ValueError("the three points are collinear")
    centre = a + (_cross(n, ab) * float(ac @ ac) + _cross(ac, n) * float(ab @ ab)) / (2 * nn)
    return centre, _norm(centre - a), n / np.sqrt(nn)


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


def _within_cone(d: Array, axis: Array, angle: float) -> Array:
    """d, or the closest direction to it within `angle` of `axis`."""
    c = float(np.clip(d @ axis, -1.0, 1.0))
    if c >= np.cos(angle):
        return d
    perp = _unit(d - c * axis)
    if not perp.any():
        return axis
    return np.cos(angle) * axis + np.sin(angle) * perp


def _cross(a: Array, b: Array) -> Array:
    """Cross product of 3-vectors (or rows), without np.cross's axis handling overhead.

    The fitter crosses single vectors tens of thousands of times per path: those go through
    Python floats (the same IEEE products, a tenth of the cost of numpy scalars).
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.ndim == 1 and b.ndim == 1:
        a0, a1, a2 = a.tolist()
        b0, b1, b2 = b.tolist()
        return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


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
