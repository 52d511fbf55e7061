"""Taught locations into joint configurations, with the reason when there is none.

The operator needs to know *which* location fails and *why*: out of reach, an orientation a
5-axis arm cannot take (then the nearest reachable orientation is offered - never used
silently), every arm configuration outside the limits, or every configuration colliding
(and with what). Among valid solutions the one nearest the seed is taken: the posture the
robot was taught in if it was taught by driving the robot (`branch_hint`), else where the arm
comes from turned to face the location, so transfers stay on one arm branch.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.mission.model import Location, LocationSource
from assistant.robots.model import IKFailure, IKResult, Robot
from assistant.transforms import inv_T

Array = np.ndarray


class LocationProblem(str, Enum):
    UNREACHABLE = "unreachable"
    ORIENTATION = "orientation"
    JOINT_LIMIT = "joint_limit"
    IN_COLLISION = "in_collision"
    #: Every posture that reaches the pose has the arm touching itself: no cell change helps.
    SELF_COLLISION = "self_collision"


class LocationError(ValueError):
    """A location the robot cannot take; `suggestion_T_world_tool` is offered when known."""

    def __init__(self, name: str, problem: LocationProblem, message: str,
                 suggestion_T_world_tool: Array | None = None):
        super().__init__(message)
        self.name = name
        self.problem = problem
        self.suggestion_T_world_tool = suggestion_T_world_tool


@dataclass(frozen=True)
class SolvedLocation:
    name: str
    q: Array
    T_base_tool: Array


def branch_seed(q_ref: Array, p_base: Array) -> Array:
    """A seed for IK at TCP point `p_base`: `q_ref` with J1 turned to face the point.

    IK picks the solution nearest its seed; with the raw configuration of a far-away location
    as seed, the nearest solution for a target on the other side of the robot can be the
    "flipped" one (J1 + 180 deg, reaching back over the shoulder). Facing J1 to the target
    first keeps the reference's arm branch (elbow up/down) without that flip. Assumes J1
    turns about the base z axis (true for the arms we support; harmless otherwise).
    """
    q = np.array(q_ref, dtype=float, copy=True)
    if np.hypot(p_base[0], p_base[1]) > 1e-6:
        q[0] = float(np.arctan2(p_base[1], p_base[0]))
    return q


def branch_hint(location: Location) -> Array | None:
    """The arm configuration to keep for a location, if it has one that means something.

    A location taught by driving the robot there (`ROBOT_POSE`) carries the posture it was
    taught in: that arm branch is the operator's choice and is kept. Typed, clicked and
    pointer locations carry whatever IK solution was nearest the arm when they were taught
    - for a point on the far side that can be the flipped branch (J1 + 180 deg, reaching
    back over the shoulder), which turns every transfer to it into a swing over the robot.
    For those the planner chooses the branch (`branch_seed`: where the arm comes from,
    turned to face the location).
    """
    if location.source == LocationSource.ROBOT_POSE and location.q_hint is not None:
        return np.asarray(location.q_hint, dtype=float)
    return None


def solve_location(robot: Robot, checker: CollisionChecker | None, name: str,
                   T_world_tool: Array, T_world_base: Array, *, seed: Array | None = None,
                   q_hint: Array | None = None, taught: Array | None = None,
                   ) -> SolvedLocation:
    """The valid joint solution of a taught pose nearest `q_hint` (else `seed`, turned to
    face the location: `branch_seed`); `taught`, the posture teach accepted for it, when
    none of IK's solutions from here is free (teach and plan agree: `first_free`).

    Raises:
        LocationError naming the location and the problem (see the module docstring).
    """
    T_base_world = inv_T(np.asarray(T_world_base, dtype=float))
    T_base_tool = T_base_world @ np.asarray(T_world_tool, dtype=float)
    pref = q_hint if q_hint is not None else (
        None if seed is None else branch_seed(seed, T_base_tool[:3, 3]))
    res = robot.ik(T_base_tool, pref)
    known = taught is not None and _reaches(robot, taught, T_base_tool)
    if not res.ok and known:
        res = IKResult([np.asarray(taught, dtype=float)])
        known = False
    if not res.ok:
        p_mm = np.asarray(T_world_tool)[:3, 3] * 1000.0
        where = f"({p_mm[0]:.0f}, {p_mm[1]:.0f}, {p_mm[2]:.0f}) mm"
        if res.failure == IKFailure.ORIENTATION:
            sugg = None
            if res.nearest_T_base_tool is not None:
                sugg = np.asarray(T_world_base, dtype=float) @ res.nearest_T_base_tool
            raise LocationError(name, LocationProblem.ORIENTATION,
                                f"{name} at {where}: orientation not reachable - {res.message}; "
                                "accept the projected orientation to use it", sugg)
        if res.failure == IKFailure.JOINT_LIMIT:
            raise LocationError(name, LocationProblem.JOINT_LIMIT,
                                f"{name} at {where} is unreachable: {res.message}")
        raise LocationError(name, LocationProblem.UNREACHABLE,
                            f"{name} at {where} is unreachable: {res.message}")
    sols = [np.asarray(q, dtype=float) for q in res.solutions]
    if pref is not None:
        sols.sort(key=lambda q: float(np.linalg.norm(q - np.asarray(pref, dtype=float))))
    if checker is None:
        return SolvedLocation(name, sols[0], T_base_tool)
    if known:
        # Last: the posture teach accepted is a solution too, should IK from here miss it.
        sols.append(np.asarray(taught, dtype=float))
    k, problem = first_free(checker, name, sols)
    if problem is not None:
        raise problem
    return SolvedLocation(name, sols[k], T_base_tool)


def first_free(checker: CollisionChecker, name: str, sols: list[Array],
               ) -> tuple[int, LocationError | None]:
    """The first collision-free posture among `sols` (best first), or why there is none.

    The one verdict teach and plan share: every posture touching the arm itself is a
    `SELF_COLLISION` (the pose cannot be taught like this), else an `IN_COLLISION` with the
    cell; the contacts of the first posture are named in the operator's words."""
    ok = checker.is_valid_batch(np.array(sols))
    if ok.any():
        return int(np.argmax(ok)), None
    reports = [checker.check(q) for q in sols]
    why = reports[0].describe(checker.link_words)
    if all(any(c.self_collision for c in r.contacts) for r in reports):
        return 0, LocationError(name, LocationProblem.SELF_COLLISION,
                                f"{name}: the arm would touch itself in every posture that "
                                f"reaches it ({why}); give it another tool orientation or "
                                "position")
    return 0, LocationError(name, LocationProblem.IN_COLLISION,
                            f"{name} is inside an obstacle: every arm configuration collides "
                            f"({why})")


def _reaches(robot: Robot, q: Array, T_base_tool: Array, tol: float = 1e-4) -> bool:
    """`q` is within the limits and puts the TCP on the pose (m; the rotation in rad x 1 m)."""
    q = np.asarray(q, dtype=float)
    if q.shape != (robot.dof,) or not robot.limits.contains(q):
        return False
    T = robot.fk(q)
    dR = T[:3, :3].T @ np.asarray(T_base_tool)[:3, :3]
    return bool(np.linalg.norm(T[:3, 3] - T_base_tool[:3, 3]) < tol
                and np.linalg.norm(dR - np.eye(3)) < tol)
