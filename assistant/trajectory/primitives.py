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
question answered exactly (the fits compiled in `fit_kernels`, the growth and look-ahead
around them in `fit_growth`). At each start
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

from assistant.trajectory.cartesian_follow import poses_from, slerp_rotations
from assistant.trajectory.fit_kernels import (
    arc_distances,
    circle_through_kernel,
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


def finished_fit(prims: list[Primitive], nodes: Array, breaks: int) -> PrimitiveFit:
    """The fit of these primitives (the last one snapped onto the last node): each node's
    deviation and the tangency error at each joint that must be tangent."""
    n = len(nodes)
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
            # atan2(|a x b|, a . b): exact near 0 where arccos of the dot loses half the digits
            ta, tb = a.tangent_end, b.tangent_start
            tangency.append(float(np.arctan2(np.linalg.norm(np.cross(ta, tb)), ta @ tb)))
    return PrimitiveFit(prims, dev, tangency, breaks)


def sample_primitive(prim: Primitive, max_step: float) -> tuple[Array, Array]:
    """Fractions u (0..1, always with 0 and 1; arcs also with 0.5, the via) and TCP points,
    at most `max_step` apart along the primitive."""
    u = np.linspace(0.0, 1.0, _sample_count(prim, max_step) + 1)
    return u, np.atleast_2d(prim.point_at(u))


def _sample_count(prim: Primitive, max_step: float) -> int:
    """`sample_primitive`'s number of steps."""
    n = max(1, int(np.ceil(prim.length / max_step)))
    if prim.kind == PrimitiveKind.ARC:
        n += n % 2
        n = max(n, 2)
    return n


def primitive_poses(prim: Primitive, max_step: float, R0: Array, R1: Array,
                    ) -> tuple[Array, Array]:
    """(u, T_base_tool (M, 4, 4)): `sample_primitive`'s fractions and points with the tool
    turning from R0 to R1 (`slerp_rotations`) - what a LINEAR or CIRCULAR move's IK walk is
    given."""
    u, points = sample_primitive(prim, max_step)
    return u, poses_from(points, slerp_rotations(R0, R1, u))


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
