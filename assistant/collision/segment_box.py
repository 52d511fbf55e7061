"""Exact distances from line segments to oriented boxes (compiled, numba).

The clearance report (`clearance_scan.pruned_clearance`) asks FCL for the distance of
the pairs that may be nearest, in the order of a lower bound. The covering spheres of the
broad phase bound a capsule link only loosely (the RV-2AJ's 250 mm upper arm is covered by
spheres 25 mm larger than the capsule), so by the spheres alone hundreds to thousands of
pairs along a path fall below the answer and each costs an FCL call. A capsule is the set of
points within r
of its axis segment, and an obstacle lies inside its oriented bounding box, so

    distance(capsule, obstacle) >= distance(axis segment, box) - r,

which for a box obstacle *is* the distance. Spheres are segments of length zero; a cylinder
lies inside the capsule with its radius and length. The collision broad phase uses the same
bound to keep pairs that are clearly apart from FCL (`broad_phase.prune_round_pairs`).

Serves (the user-felt figure): the pruning and clearance of every check: 1.5 s in Python in
the thesis run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.kernels.lazy import kernel
from assistant.robots.model import CollisionShape, ShapeKind

Array = np.ndarray


@dataclass(frozen=True)
class OrientedBox:
    """A box containing a shape: rotation (3, 3) and centre (3,) in the base frame, half
    extents (3,) along the rotation's columns."""

    R: Array
    centre: Array
    half: Array


def oriented_bounds(shape: CollisionShape, T_base_owner: Array) -> OrientedBox:
    """The box, in the shape's own frame, that contains the shape (exact for a box)."""
    T = np.asarray(T_base_owner, dtype=float) @ shape.T_link_shape
    offset = np.zeros(3)
    if shape.kind == ShapeKind.BOX:
        half = np.asarray(shape.size, dtype=float) / 2
    elif shape.kind == ShapeKind.SPHERE:
        half = np.full(3, float(shape.size[0]))
    elif shape.kind in (ShapeKind.CYLINDER, ShapeKind.CAPSULE):
        r, length = (float(v) for v in shape.size)
        cap = r if shape.kind == ShapeKind.CAPSULE else 0.0
        half = np.array([r, r, length / 2 + cap])
    else:
        assert shape.mesh is not None
        lo, hi = (np.asarray(b, dtype=float) for b in shape.mesh.bounds)
        offset, half = (lo + hi) / 2, (hi - lo) / 2
    return OrientedBox(T[:3, :3].copy(), T[:3, :3] @ offset + T[:3, 3], half)


def axis_segment(shape: CollisionShape) -> tuple[Array, Array, float] | None:
    """The segment (two points in the link frame) and radius whose swept sphere contains the
    shape, for capsules, cylinders and spheres; None for other kinds."""
    T = shape.T_link_shape
    if shape.kind == ShapeKind.SPHERE:
        return T[:3, 3].copy(), T[:3, 3].copy(), float(shape.size[0])
    if shape.kind in (ShapeKind.CAPSULE, ShapeKind.CYLINDER):
        r, length = (float(v) for v in shape.size)
        a = T[:3, :3] @ np.array([0.0, 0.0, -length / 2]) + T[:3, 3]
        b = T[:3, :3] @ np.array([0.0, 0.0, length / 2]) + T[:3, 3]
        return a, b, r
    return None


@kernel(cache=True, inline="always")
def _beyond(a: float, d: float, h: float, mid: float) -> tuple[float, float]:
    """(offset, direction) of the face plane the coordinate a + t d lies beyond at t = mid,
    (0, 0) inside the slab -h..h."""
    x = a + mid * d
    if x > h:
        return a - h, d
    if x < -h:
        return a + h, d
    return 0.0, 0.0


@kernel(cache=True)
def segment_box_distance_one(a: Array, b: Array, half: Array) -> float:
    """Distance from the segment a->b (3,) to the box [-half, half] (3,), in the box's frame;
    0 where they meet.

    The squared distance along the segment, f(t) = sum_i max(|a_i + t d_i| - h_i, 0)^2, is
    convex and quadratic between the parameters where a coordinate crosses a face plane.
    Each such piece is minimised in closed form (its faces are fixed at its middle), and
    the smallest piece minimum is the exact answer. Compiled (numba): the collision broad
    phase calls it per candidate pair; scalars, not small arrays, hold each piece (an array
    per piece would be an allocation per piece).
    """
    d0, d1, d2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    t = np.empty(8)
    t[0], t[7] = 0.0, 1.0
    for i in range(3):  # where the segment crosses the face planes (0 if parallel)
        di = b[i] - a[i]
        if di != 0.0:
            t[1 + 2 * i] = min(max((half[i] - a[i]) / di, 0.0), 1.0)
            t[2 + 2 * i] = min(max((-half[i] - a[i]) / di, 0.0), 1.0)
        else:
            t[1 + 2 * i] = t[2 + 2 * i] = 0.0
    for i in range(2, 7):  # insertion sort of t[1:7] (t[0], t[7] are the ends already)
        v = t[i]
        j = i - 1
        while j >= 1 and t[j] > v:
            t[j + 1] = t[j]
            j -= 1
        t[j + 1] = v
    best = np.inf
    for p in range(7):
        lo, hi = t[p], t[p + 1]
        mid = 0.5 * (lo + hi)
        # per axis: the face this piece lies beyond (offset e, direction dd), or none
        e0, dd0 = _beyond(a[0], d0, half[0], mid)
        e1, dd1 = _beyond(a[1], d1, half[1], mid)
        e2, dd2 = _beyond(a[2], d2, half[2], mid)
        den = dd0 * dd0 + dd1 * dd1 + dd2 * dd2
        ts = -(dd0 * e0 + dd1 * e1 + dd2 * e2) / den if den > 0.0 else lo
        ts = min(max(ts, lo), hi)
        r0, r1, r2 = e0 + ts * dd0, e1 + ts * dd1, e2 + ts * dd2
        s = 0.0 + r0 * r0
        s += r1 * r1
        s += r2 * r2
        best = min(best, s)
    return np.sqrt(best)
