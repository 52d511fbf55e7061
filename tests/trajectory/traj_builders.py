"""Shared builders for the trajectory tests (paths through IK, boxes, distances)."""

from __future__ import annotations

import numpy as np

from assistant.collision.reports import Obstacle
from assistant.robots.model import CollisionShape, Robot, ShapeKind
from assistant.transforms import make_T


def ik_path(robot: Robot, points, seed=None) -> np.ndarray:
    """A joint path through TCP points by position-only IK, each seeded from the previous."""
    q = None if seed is None else np.asarray(seed, dtype=float)
    out = []
    for p in np.asarray(points, dtype=float):
        T = np.eye(4)
        T[:3, 3] = p
        q = robot.ik(T, q, position_only=True).best(q)
        out.append(q)
    return np.array(out)


def box(name: str, centre, size) -> Obstacle:
    return Obstacle(name, make_T(p=centre), (CollisionShape(ShapeKind.BOX, tuple(size)),))


TABLE = box("table", [0.0, 0.0, -0.011], [1.5, 1.5, 0.02])


def box_distance(points, centre, size) -> np.ndarray:
    """Euclidean distance of points to an axis-aligned box (0 inside)."""
    half = np.asarray(size, dtype=float) / 2.0
    d = np.maximum(np.abs(np.atleast_2d(points) - centre) - half, 0.0)
    return np.linalg.norm(d, axis=1)


def densify(points, step=0.001) -> np.ndarray:
    """Points every `step` along a polyline (for checking what lies between nodes)."""
    out = [points[:1]]
    for a, b in zip(points[:-1], points[1:], strict=True):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out.append(a + np.linspace(0, 1, n + 1)[1:, None] * (b - a))
    return np.concatenate(out)
