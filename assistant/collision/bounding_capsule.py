"""A capsule around a mesh shape: the segment-to-box bound the broad phase prunes with.

Why: the checker clears a robot shape against an obstacle box without FCL when the
distance from the shape's axis segment to the box, less its radius, exceeds the margin
(`broad_phase.prune_round_pairs`). Capsules, cylinders and spheres have that segment
(`segment_box.axis_segment`); a URDF arm's links are meshes (a UR5's: 450-1200
triangles each) and had none, so every pair its covering spheres passed went to FCL's
mesh test. A capsule containing every vertex contains the mesh (the capsule is convex), so
the bound stays a lower bound and the answers stay FCL's.
"""

from __future__ import annotations

import numpy as np

from assistant.robots.model import CollisionShape, ShapeKind

Array = np.ndarray


def mesh_capsule(shape: CollisionShape) -> tuple[Array, Array, float] | None:
    """(a, b, radius) in the link frame of a capsule around the mesh's vertices, along
    their principal axis; None for other kinds or an empty mesh."""
    if shape.kind != ShapeKind.MESH or shape.mesh is None:
        return None
    V = np.asarray(getattr(shape.mesh, "vertices", ()), dtype=float).reshape(-1, 3)
    if len(V) == 0 or not np.all(np.isfinite(V)):
        return None
    T = shape.T_link_shape
    V = V @ T[:3, :3].T + T[:3, 3]
    return capsule_around(V)


def capsule_around(V: Array) -> tuple[Array, Array, float]:
    """(a, b, radius): every point of V within radius of the segment a-b. The axis is
    the points' principal direction; the radius their largest distance from that line; the
    ends pulled in as far as the end spheres still cover every point beyond them."""
    c = V.mean(axis=0)
    X = V - c
    axis = np.linalg.svd(X, full_matrices=False)[2][0] if len(V) > 1 else np.zeros(3)
    t = X @ axis
    d2 = np.maximum((X * X).sum(axis=1) - t * t, 0.0)
    r = float(np.sqrt(d2.max()))
    slack = np.sqrt(np.maximum(r * r - d2, 0.0))
    lo, hi = float((t + slack).min()), float((t - slack).max())
    if lo > hi:  # a ball-like shape: one centre, its radius from the points
        m = 0.5 * (lo + hi)
        p = c + m * axis
        return p, p.copy(), _padded(float(np.sqrt(((V - p) ** 2).sum(axis=1).max())))
    return c + lo * axis, c + hi * axis, _padded(r)


def _padded(r: float) -> float:
    """The radius a hair larger: the points' distances were rounded once more than the
    broad phase's segment distance will be."""
    return r * (1.0 + 1e-9) + 1e-12
