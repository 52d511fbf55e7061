"""The arm's reach as a sphere around its shoulder: where it can get at all, and how far beyond
it a refused target lies (the operator's "120 mm too far" instead of "out of reach").

Why a sphere: every TCP position lies within the sum of the link lengths from the shoulder
(triangle inequality), so a target farther than the largest TCP distance is out of reach for
any orientation; a target inside may still be refused for its orientation or a joint limit.
Computed once per robot (robots are immutable): random joint samples, then a local ascent from
the farthest ones, so the radius is within a fraction of a millimetre of the true maximum for
the catalogue's arms (a sample-only maximum falls short by millimetres).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.robots.model import Robot

Array = np.ndarray

#: Joint samples for the first estimate; the ascent does the rest.
SAMPLES = 4096
#: Farthest samples the local ascent starts from (their basins may differ).
ASCENTS = 4

@dataclass(frozen=True)
class ArmReach:
    """The shoulder (base frame, m) and the largest TCP distance from it (m)."""

    centre_base: Array
    radius: float

    def centre_world(self, T_world_base: Array) -> Array:
        return (np.asarray(T_world_base, float) @ np.append(self.centre_base, 1.0))[:3]

    def beyond(self, p_base: Array) -> float:
        """How far (m) the point lies outside the reach sphere; negative: inside by that much."""
        return float(np.linalg.norm(np.asarray(p_base, float) - self.centre_base) - self.radius)

    def beyond_world(self, p_world: Array, T_world_base: Array) -> float:
        """`beyond` for a point in the world frame, the robot base at `T_world_base`."""
        return float(np.linalg.norm(np.asarray(p_world, float)
                                    - self.centre_world(T_world_base)) - self.radius)


def arm_reach(robot: Robot, samples: int = SAMPLES) -> ArmReach:
    """The reach sphere of `robot` (with its tool), remembered on the robot object (robots
    are immutable; `with_tool` makes a new one, which gets its own)."""
    cached = robot.__dict__.get("_arm_reach")
    if cached is not None and cached[0] == samples:
        return cached[1]
    centre = shoulder_centre(robot)
    out = ArmReach(centre, _max_distance(robot, centre, samples))
    robot.__dict__["_arm_reach"] = (samples, out)
    return out


def _q0(robot: Robot) -> Array:
    return np.clip(np.zeros(robot.dof), robot.limits.lower, robot.limits.upper)


def shoulder_centre(robot: Robot) -> Array:
    """The second joint's origin projected onto the first joint's axis (base frame, m): the
    point the arm turns about. Joint 1's axis is found from two of its positions, so any
    model works; a one-axis robot (or a degenerate turn) falls back to link 2's origin."""
    q0 = _q0(robot)
    frames0 = robot.link_poses(q0)
    k = min(2, robot.dof)
    shoulder = frames0[k, :3, 3].copy()
    if robot.dof < 2:
        return shoulder
    q1 = q0.copy()
    step = 0.5 if q0[0] + 0.5 <= robot.limits.upper[0] else -0.5
    q1[0] += step
    T = robot.link_poses(q1)[1] @ np.linalg.inv(frames0[1])  # the turn about joint 1 (base)
    R, t = T[:3, :3], T[:3, 3]
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if np.linalg.norm(w) < 1e-6:  # no turn: a prismatic first joint or a zero range
        return shoulder
    axis = w / np.linalg.norm(w)
    point = np.linalg.lstsq(np.eye(3) - R, t, rcond=None)[0]  # a point the turn keeps
    return point + axis * float(np.dot(shoulder - point, axis))


def _max_distance(robot: Robot, centre: Array, samples: int) -> float:
    from scipy.optimize import minimize

    lo, hi = robot.limits.lower, robot.limits.upper
    rng = np.random.default_rng(0)
    Q = lo + rng.random((samples, robot.dof)) * (hi - lo)
    d = np.linalg.norm(np.asarray(robot.batch_fk(Q).positions) - centre, axis=1)
    best = float(d.max())

    def neg(q: Array) -> float:
        return -float(np.linalg.norm(robot.tcp_position(q) - centre))

    for i in np.argsort(d)[::-1][:ASCENTS]:
        res = minimize(neg, Q[i], method="L-BFGS-B", bounds=list(zip(lo, hi, strict=True)),
                       options={"maxiter": 60})
        best = max(best, -float(res.fun))
    return best


def reach_note(robot: Robot, p_base: Array) -> str:
    """Words for a refused target (base frame, m): how far beyond the arm's reach it lies
    ("345 mm beyond the arm's reach (582 mm from the shoulder)"), or "" inside the reach,
    where the orientation or a joint limit is what refused it."""
    reach = arm_reach(robot)
    beyond = reach.beyond(p_base)
    if beyond <= 0.0005:  # within half a millimetre: nothing the operator can act on
        return ""
    return f"{beyond * 1000:.0f} mm beyond the arm's reach " \
           f"({reach.radius * 1000:.0f} mm from the shoulder)"
