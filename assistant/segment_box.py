"""Exact distances from line segments to oriented boxes, many at once (compiled, numba).

The clearance report (`CollisionChecker.min_clearance_along`) asks FCL for the distance of
the pairs that may be nearest, in the order of a lower bound. The covering spheres of the
broad phase bound a capsule link only loosely (the RV-2AJ's 250 mm upper arm is covered by
spheres 25 mm larger than the capsule), so hundreds to thousands of pairs along a path used
to fall below the answer and each cost an FCL call. A capsule is the set of points within r
of its axis segment, and an obstacle lies inside its oriented bounding box, so

    distance(capsule, obstacle) >= distance(axis segment, box) - r,

which for a box obstacle *is* the distance. Spheres are segments of length zero; a cylinder
lies inside the capsule with its radius and length. The collision broad phase uses the same
bound to keep pairs that are clearly apart from FCL (`broad_phase.prune_round_pairs`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

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
    box's frame; 0 where they meet (`segment_box_distance_one` per row)."""
    a, b, half = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float),
                                     np.asarray(half, float))
    shape = a.shape[:-1]
    rows = [np.ascontiguousarray(v.reshape(-1, 3)) for v in (a, b, half)]
    return _segment_box_distances(*rows).reshape(shape)


@njit(cache=True)
def segment_box_distance_one(a: Array, b: Array, half: Array) -> float:
    """Distance from the segment a->b (3,) to the box [-half, half] (3,), in the box's frame;
    0 where they meet.

    The squared distance along the segment, f(t) = sum_i max(|a_i + t d_i| - h_i, 0)^2, is
    convex and quadratic between the parameters where a coordinate crosses a face plane.
    Each such piece is minimised in closed form (its faces are fixed at its middle), and
    the smallest piece minimum is the exact answer. Compiled (numba): the collision broad
    phase calls it per candidate pair.
    """
    d = b - a
    t = np.empty(8)
    t[0], t[7] = 0.0, 1.0
    for i in range(3):  # where the segment crosses the face planes (0 if parallel)
        if d[i] != 0.0:
            t[1 + 2 * i] = min(max((half[i] - a[i]) / d[i], 0.0), 1.0)
            t[2 + 2 * i] = min(max((-half[i] - a[i]) / d[i], 0.0), 1.0)
        else:
            t[1 + 2 * i] = t[2 + 2 * i] = 0.0
    t.sort()
    best = np.inf
    for p in range(7):
        lo, hi = t[p], t[p + 1]
        mid = 0.5 * (lo + hi)
        e = np.zeros(3)
        dd = np.zeros(3)
        for i in range(3):
            x = a[i] + mid * d[i]
            if x > half[i]:
                e[i], dd[i] = a[i] - half[i], d[i]
            elif x < -half[i]:
                e[i], dd[i] = a[i] + half[i], d[i]
        den = dd[0] * dd[0] + dd[1] * dd[1] + dd[2] * dd[2]
        ts = -(dd[0] * e[0] + dd[1] * e[1] + dd[2] * e[2]) / den if den > 0.0 else lo
        ts = min(max(ts, lo), hi)
        s = 0.0
        for i in range(3):
            r = e[i] + ts * dd[i]
            s += r * r
        best = min(best, s)
    return np.sqrt(best)



@njit(cache=True)
def _segment_box_distances(a: Array, b: Array, half: Array) -> Array:
    out = np.empty(a.shape[0])
    for i in range(a.shape[0]):
        out[i] = segment_box_distance_one(a[i], b[i], half[i])
    return out


def segment_box_bounds(A: Array, B: Array, radius: Array, R: Array, centre: Array,
                       half: Array) -> Array:
    """Lower bounds of the distance from the capsules A->B with these radii (rows, base
    frame) to shapes inside the oriented boxes (R, centre, half) of the same rows; -inf
    where the capsule may reach into the box (a penetration depth has no such bound)."""
    la = np.einsum("nji,nj->ni", R, A - centre)  # R^T (A - centre)
    lb = np.einsum("nji,nj->ni", R, B - centre)
    gap = segment_box_distance(la, lb, half) - radius
    return np.where(gap > 0.0, gap, -np.inf)


@njit(cache=True)
def scan_tight_bounds(frames: Array, lb: Array, movable: Array, first: int, best: float,
                      shape_link: Array, seg_a: Array, seg_b: Array, seg_r: Array,
                      seg_exact: Array, box_R: Array, box_c: Array, box_h: Array,
                      box_exact: Array) -> tuple[float, Array, Array]:
    """The clearance report's second pass (`CollisionChecker.min_clearance_along`) in one
    loop: over (sample, movable shape, obstacle) rows in order, those whose sphere bound
    lb is below the smallest distance found so far get the capsule-to-box bound
    (`segment_box_bounds`, the same products in the same order). Where that bound is the
    exact distance (a capsule or sphere clear of a box) it lowers the best; the others are
    returned (flat row, bound = max(sphere bound, capsule bound)) for FCL. Rows skipped
    have a sphere bound at or above a distance already found, so neither their exact
    distance nor an FCL answer for them could be smaller: the result is that of bounding
    every row below the first answer `best` (row `first`) and then measuring."""
    n, n_mov, n_env = lb.shape
    rows = np.empty(n * n_mov * n_env, dtype=np.int64)
    bounds = np.empty(n * n_mov * n_env)
    m = 0
    A = np.empty(3)
    B = np.empty(3)
    la = np.empty(3)
    lbx = np.empty(3)
    j = -1
    for k in range(n):
        for r in range(n_mov):
            s = movable[r]
            link = shape_link[s]
            for e in range(n_env):
                j += 1
                v = lb[k, r, e]
                if j == first or not v < best:
                    continue
                for i in range(3):  # frame @ segment ends, as einsum "nij,nj->ni" + t
                    A[i] = (0.0 + frames[k, link, i, 0] * seg_a[s, 0]
                            + frames[k, link, i, 1] * seg_a[s, 1]
                            + frames[k, link, i, 2] * seg_a[s, 2]) + frames[k, link, i, 3]
                    B[i] = (0.0 + frames[k, link, i, 0] * seg_b[s, 0]
                            + frames[k, link, i, 1] * seg_b[s, 1]
                            + frames[k, link, i, 2] * seg_b[s, 2]) + frames[k, link, i, 3]
                for i in range(3):  # R^T (end - centre), as einsum "nji,nj->ni"
                    la[i] = (0.0 + box_R[e, 0, i] * (A[0] - box_c[e, 0])
                             + box_R[e, 1, i] * (A[1] - box_c[e, 1])
                             + box_R[e, 2, i] * (A[2] - box_c[e, 2]))
                    lbx[i] = (0.0 + box_R[e, 0, i] * (B[0] - box_c[e, 0])
                              + box_R[e, 1, i] * (B[1] - box_c[e, 1])
                              + box_R[e, 2, i] * (B[2] - box_c[e, 2]))
                gap = segment_box_distance_one(la, lbx, box_h[e]) - seg_r[s]
                tight = gap if gap > 0.0 else -np.inf
                if seg_exact[s] and box_exact[e] and np.isfinite(tight):
                    best = min(best, tight)
                else:
                    rows[m] = j
                    bounds[m] = max(v, tight)
                    m += 1
    return best, rows[:m].copy(), bounds[:m].copy()
