"""Exact distances from line segments to oriented boxes, many at once (numpy).

The clearance report (`CollisionChecker.min_clearance_along`) asks FCL for the distance of
the pairs that may be nearest, in the order of a lower bound. The covering spheres of the
broad phase bound a capsule link only loosely (the RV-2AJ's 250 mm upper arm is covered by
spheres 25 mm larger than the capsule), so hundreds to thousands of pairs along a path used
to fall below the answer and each cost an FCL call. A capsule is the set of points within r
of its axis segment, and an obstacle lies inside its oriented bounding box, so

    distance(capsule, obstacle) >= distance(axis segment, box) - r,

which for a box obstacle *is* the distance. Spheres are segments of length zero; a cylinder
lies inside the capsule with its radius and length.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.robot_model import CollisionShape, ShapeKind

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


def segment_box_distance(a: Array, b: Array, half: Array) -> Array:
    """Distance from each segment a->b (..., 3) to the box [-half, half] (..., 3), all in the
    box's frame; 0 where they meet.

    The squared distance along the segment, f(t) = sum_i max(|a_i + t d_i| - h_i, 0)^2, is
    convex and quadratic between the parameters where a coordinate crosses a face plane.
    Each such piece is minimised in closed form (its faces are fixed at its middle), and
    the smallest piece minimum is the exact answer.
    """
    a, b, half = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float),
                                     np.asarray(half, float))
    d = b - a
    with np.errstate(invalid="ignore", divide="ignore"):
        cross = np.concatenate([(half - a) / d, (-half - a) / d], axis=-1)  # (..., 6)
    cross = np.where(np.isfinite(cross), np.clip(cross, 0.0, 1.0), 0.0)
    zeros = np.zeros(cross.shape[:-1] + (1,))
    t = np.sort(np.concatenate([zeros, cross, zeros + 1.0], axis=-1), axis=-1)  # (..., 8)
    lo, hi = t[..., :-1], t[..., 1:]  # 7 pieces
    mid = 0.5 * (lo + hi)
    x = a[..., None, :] + mid[..., None] * d[..., None, :]  # (..., 7, 3)
    h = half[..., None, :]
    face = np.where(x > h, h, np.where(x < -h, -h, np.nan))  # the face each coordinate is past
    outside = ~np.isnan(face)
    e = np.where(outside, a[..., None, :] - np.nan_to_num(face), 0.0)  # offsets past the faces
    dd = np.where(outside, d[..., None, :], 0.0)
    den = (dd * dd).sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        ts = np.where(den > 0.0, -(dd * e).sum(axis=-1) / den, lo)
    ts = np.clip(ts, lo, hi)
    r = e + ts[..., None] * dd
    return np.sqrt((r * r).sum(axis=-1).min(axis=-1))


def segment_box_bounds(A: Array, B: Array, radius: Array, R: Array, centre: Array,
                       half: Array) -> Array:
    """Lower bounds of the distance from the capsules A->B with these radii (rows, base
    frame) to shapes inside the oriented boxes (R, centre, half) of the same rows; -inf
    where the capsule may reach into the box (a penetration depth has no such bound)."""
    la = np.einsum("nji,nj->ni", R, A - centre)  # R^T (A - centre)
    lb = np.einsum("nji,nj->ni", R, B - centre)
    gap = segment_box_distance(la, lb, half) - radius
    return np.where(gap > 0.0, gap, -np.inf)
