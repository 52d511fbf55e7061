"""Where the simulated robot stands before anyone moves it."""

from __future__ import annotations

import numpy as np
from scipy.stats import qmc

from assistant.collision.checker import CollisionChecker
from assistant.robots.model import Robot, ShapeKind

Array = np.ndarray

#: Height (m) every moving link keeps above the mounting plane at home.
CLEAR_OF_MOUNT = 0.05


def lowest_point(robot: Robot, q: Array, first_link: int = 3) -> float:
    """Lowest z (base frame, m) of the collision shapes of links from `first_link` on (the
    forearm: the upper arm hangs from a shoulder a few cm above the mount)
    (mesh vertices exactly, primitives by their bounding spheres)."""
    frames = robot.link_poses(np.asarray(q, dtype=float))
    low = np.inf
    for k in range(first_link, len(robot.links)):
        for s in robot.links[k].collision:
            T = frames[k] @ s.T_link_shape
            if s.kind == ShapeKind.MESH and s.mesh is not None:
                z = np.asarray(s.mesh.vertices) @ T[2, :3] + T[2, 3]
                low = min(low, float(z.min()))
            else:
                low = min(low, float(T[2, 3]) - s.bounding_radius())
    return low


def raised_posture(robot: Robot) -> Array:
    """The zero posture clipped to the limits if every moving link is `CLEAR_OF_MOUNT` above
    the mounting plane and free of self-collision; else the nearest such posture (arm-radius
    weighted joint distance) whose joints are each 0 or +-90 deg (a UR arm: upright), then
    among Sobol samples of the limits; the zero posture if none is."""
    lo, hi = robot.limits.lower, robot.limits.upper
    zero = np.clip(np.zeros(robot.dof), lo, hi)
    checker = CollisionChecker(robot, ())
    right = np.radians([0.0, -90.0, 90.0])
    grid = np.stack(np.meshgrid(*[right] * robot.dof, indexing="ij"), -1).reshape(-1, robot.dof)
    U = qmc.Sobol(d=robot.dof, scramble=True, seed=0).random(256)
    Q = np.vstack([zero, np.clip(grid, lo, hi)])
    w = robot.arm_radii()
    order = np.argsort(np.linalg.norm((Q - zero) * w, axis=1), kind="stable")
    for q in [*Q[order], *(lo + U * (hi - lo))]:
        if lowest_point(robot, q) >= CLEAR_OF_MOUNT and checker.is_valid(q):
            return q
    return zero
