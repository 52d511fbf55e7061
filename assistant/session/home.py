"""Where the simulated robot stands before anyone moves it, and the way out when a cell change
puts that posture inside an object (`way_to_free_posture`)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import ObstacleView
from assistant.robots.model import Robot, ShapeKind

Array = np.ndarray

#: Height (m) every moving link keeps above the mounting plane at home.
CLEAR_OF_MOUNT = 0.05
#: Smallest Jacobian singular value a home posture keeps (`dexterity`).
MIN_DEXTERITY = 0.02


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


def dexterity(robot: Robot, q: Array, h: float = 1e-5) -> float:
    """Smallest singular value of the TCP Jacobian (m/rad; rotation rows scaled by 0.1 m):
    ~0 at a singularity (a stretched elbow, aligned wrist axes), where a Cartesian move from
    the posture would make joints race."""
    q = np.asarray(q, dtype=float)
    T0 = robot.fk(q)
    cols = []
    for i in range(robot.dof):
        dq = np.zeros(robot.dof)
        dq[i] = h
        T = robot.fk(q + dq)
        dR = T0[:3, :3].T @ T[:3, :3]
        w = 0.5 * np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]])
        cols.append(np.r_[(T[:3, 3] - T0[:3, 3]) / h, 0.1 * (T0[:3, :3] @ w) / h])
    J = np.array(cols).T
    k = min(6, robot.dof)
    return float(np.linalg.svd(J, compute_uv=False)[k - 1])


def raised_posture(robot: Robot, obstacles: Sequence[ObstacleView] = ()) -> Array:
    """The zero posture clipped to the limits if every moving link is `CLEAR_OF_MOUNT` above
    the mounting plane, away from singularities (`dexterity`) and free of self-collision; else
    the middle of the ranges, then the nearest such posture (arm-radius weighted joint
    distance) whose joints are each 0, +-45 or +-90 deg, then among Sobol samples of the
    limits; the zero posture if none is. Arms of fewer than 6 axes skip the singularity test
    (the RV-2AJ starts upright at zero, as in the thesis). With `obstacles` (the cell's
    objects) the posture is free of them too."""
    lo, hi = robot.limits.lower, robot.limits.upper
    zero = np.clip(np.zeros(robot.dof), lo, hi)
    checker = CollisionChecker(robot, obstacles)
    right = np.radians([0.0, -45.0, 45.0, -90.0, 90.0])
    grid = np.stack(np.meshgrid(*[right] * robot.dof, indexing="ij"), -1).reshape(-1, robot.dof)
    Q = np.clip(grid, lo, hi)
    w = robot.arm_radii()
    order = np.argsort(np.linalg.norm((Q - zero) * w, axis=1), kind="stable")
    # 5-axis arms (the RV-2AJ) start at zero as in the thesis: they follow no 6-D pose
    dexterous = robot.dof < 6
    for q in _candidates(zero, 0.5 * (lo + hi), Q[order], lo, hi):
        if (lowest_point(robot, q) >= CLEAR_OF_MOUNT
                and (dexterous or dexterity(robot, q) >= MIN_DEXTERITY)
                and checker.is_valid(q)):
            return q
    return zero


def way_to_free_posture(robot: Robot, checker: CollisionChecker, q0: Array,
                        tries: int = 64) -> Array | None:
    """A joint path from `q0` (touching something) to the nearest free posture that leaves
    the contact and never touches anything else: along the path the postures that touch
    form one stretch at its start, and touch only what `q0` touches. Candidates, nearest
    first by arm travel: `q0` with one or two joints turned by 10-90 deg, 256 Sobol
    postures over the limits. None if none of the
    nearest `tries` free ones has such a path."""
    q0 = np.asarray(q0, dtype=float)
    lo, hi = robot.limits.lower, robot.limits.upper
    steps = np.radians([10.0, -10.0, 20.0, -20.0, 45.0, -45.0, 90.0, -90.0])
    near = []
    for i in range(robot.dof):
        for a in steps:
            q = q0.copy()
            q[i] += a
            near.append(q)
            for j in range(i + 1, robot.dof):
                for b in steps[:4]:
                    q2 = q.copy()
                    q2[j] += b
                    near.append(q2)
    from scipy.stats import qmc

    sobol = lo + qmc.Sobol(d=robot.dof, scramble=True, seed=0).random(256) * (hi - lo)
    Q = np.clip(np.vstack([near, sobol]), lo, hi)
    free = Q[checker.is_valid_batch(Q)]
    if not len(free):
        return None
    w = robot.arm_radii()
    free = free[np.argsort(np.abs(free - q0) @ w, kind="stable")]
    touching = {(c.link, c.other) for c in checker.check(q0).contacts}
    for q1 in free[:tries]:
        path = _leaves_cleanly(checker, q0, q1, w, touching)
        if path is not None:
            return path
    return None


def _leaves_cleanly(checker: CollisionChecker, q0: Array, q1: Array, w: Array,
                    touching: set[tuple[str, str]]) -> Array | None:
    """The straight joint path q0 -> q1 sampled every `checker.max_step` of arm travel if
    its touching postures are one stretch at the start touching only `touching`."""
    n = max(2, int(np.ceil(float(np.abs(q1 - q0) @ w) / checker.max_step)) + 1)
    path = q0 + np.linspace(0.0, 1.0, n)[:, None] * (q1 - q0)
    ok = checker.is_valid_batch(path)
    first_free = int(np.argmax(ok))
    if not ok[-1] or not ok[first_free:].all():
        return None
    for q in path[1:first_free]:
        if not {(c.link, c.other) for c in checker.check(q).contacts} <= touching:
            return None
    return path


def _candidates(zero: Array, middle: Array, right_angles: Array, lo: Array,
                hi: Array) -> Iterator[Array]:
    """Home candidates, best first; 256 Sobol postures over the limits last (scipy.stats
    is imported only then: 0.4-1.4 s of import that most sessions never need)."""
    yield zero
    yield middle
    yield from right_angles
    from scipy.stats import qmc

    yield from lo + qmc.Sobol(d=len(lo), scramble=True, seed=0).random(256) * (hi - lo)
