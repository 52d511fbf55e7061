"""Arm configuration from a joint solution: which of the IK branches a Cartesian target means.

A Cartesian position is ambiguous: the same TCP pose is reached with the arm in front of or
behind the base, elbow up or down, wrist flipped or not, and with joints turned by 360 deg.
Controllers carry this as flags (MELFA FL1/FL2, KUKA S/T, ABB confdata). We never guess them:
they are computed geometrically from the joint solution the planner actually produced, and a
reader turns them back into an `ArmConfig` that filters the IK solutions in the round trip.

Geometry (robot-independent, from the link frames; each link frame lies on its joint axis):

* ``front``: the reference point lies in front of the J1 axis, i.e. its component along the
  arm's forward direction f(q) is >= 0, where f(q) is the base x axis turned with J1 (the
  direction the arm faces at J1 = 0 for the RV-2AJ, KUKA and ABB arms). The reference point
  is the wrist centre (J5 axis; KUKA "wrist root point", ABB "wrist centre", MELFA 6-axis
  "Q") or, for MELFA 5-axis arms, the flange centre ("P" in the MELFA manual).
* ``elbow_up``: the forearm bends downwards from the upper arm: ((E - S) x (W - E)) points
  along (u x f), with S, E, W the J2, J3 and wrist points and u the J1 axis. For the RV-2AJ
  this is J3 > 0 (MELFA ABOVE); for KUKA "A3 >= phi" (S bit 1), for ABB "wrist in front of
  the lower arm" (cfx bit 1 clear).
* ``wrist_negative``: J5 < 0 (KUKA S bit 2, ABB cfx bit 0, MELFA FLIP for 6-axis arms).

Joints are mapped to controller axis slots A1..A6 by the digit their name ends with when
every name has one (the RV-2AJ's J1, J2, J3, J5, J6 -> slots 1, 2, 3, 5, 6), else in order.
A 7-axis arm's third joint is the external axis (`redundant_axis`: slot 7, RAPID eax_a, KRL
E1), the others A1..A6; a target's `ArmConfig.redundant` holds that joint's value.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Hashable
from dataclasses import dataclass

import numpy as np

from assistant.export.redundant_axis import SEVEN_AXIS_SLOTS
from assistant.robots.model import Robot

Array = np.ndarray

#: Reference point used for `front`.
WRIST = "wrist"
FLANGE = "flange"


@dataclass(frozen=True)
class JointRange:
    """A constraint a controller flag puts on one joint: lower <= q < upper (rad)."""

    joint: int  # index into the robot's joints
    lower: float
    upper: float

    def contains(self, q: Array, tol: float = 1e-6) -> bool:
        v = float(q[self.joint])
        return self.lower - tol <= v < self.upper + tol


@dataclass(frozen=True)
class ArmConfig:
    """The branch a Cartesian target belongs to; None entries are unconstrained."""

    front: bool | None = None
    elbow_up: bool | None = None
    wrist_negative: bool | None = None
    joint_ranges: tuple[JointRange, ...] = ()
    front_reference: str = WRIST
    #: (joint, value rad): a 7-axis arm's redundant joint, held at the value the target
    #: carries (RAPID eax_a, KRL E1); None for arms without one.
    redundant: tuple[int, float] | None = None
    #: Constraints that are unions of ranges (Yaskawa's flip and "R >= 180" flags): the joint
    #: of each group lies in at least one of the group's ranges.
    joint_sets: tuple[tuple[JointRange, ...], ...] = ()

    def matches(self, robot: Robot, q: Array, tol: float = 1e-6) -> bool:
        if self.redundant is not None and abs(q[self.redundant[0]] - self.redundant[1]) > tol:
            return False
        got = arm_configuration(robot, q, front_reference=self.front_reference)
        for mine, theirs in ((self.front, got.front), (self.elbow_up, got.elbow_up),
                             (self.wrist_negative, got.wrist_negative)):
            if mine is not None and theirs is not None and mine != theirs:
                return False
        return all(r.contains(q, tol) for r in self.joint_ranges) and \
            all(any(r.contains(q, tol) for r in group) for group in self.joint_sets)


def axis_slots(robot: Robot) -> list[int]:
    """Controller axis number (1-based, A1..A6; 7 for a 7-axis arm's external axis) for
    each joint of the robot."""
    if robot.dof == len(SEVEN_AXIS_SLOTS):
        return list(SEVEN_AXIS_SLOTS)
    digits = []
    for name in robot.joint_names:
        m = re.search(r"(\d+)$", name)
        digits.append(int(m.group(1)) if m else None)
    if (all(d is not None for d in digits) and len(set(digits)) == len(digits)
            and all(1 <= d <= 6 for d in digits) and digits == sorted(digits)):
        return [int(d) for d in digits]
    if robot.dof > 6:
        raise ValueError(f"{robot.name}: {robot.dof} joints cannot be written as A1..A6 (and "
                         "one external axis)")
    return list(range(1, robot.dof + 1))


def joint_for_slot(robot: Robot, slot: int) -> int | None:
    slots = axis_slots(robot)
    return slots.index(slot) if slot in slots else None


def arm_configuration(robot: Robot, q: Array, *, front_reference: str = WRIST) -> ArmConfig:
    """The geometric configuration of `q` (see the module docstring)."""
    q = np.asarray(q, dtype=float)
    frames = robot.link_poses(q)
    frames0 = robot.link_poses(np.zeros(robot.dof))
    n = robot.dof
    if n < 4:
        return ArmConfig(front_reference=front_reference)
    u = frames[1][:3, 2]
    o1 = frames[1][:3, 3]
    # Forward direction: base x turned by J1 (about its own axis).
    R1 = frames[1][:3, :3] @ frames0[1][:3, :3].T
    f = R1 @ np.array([1.0, 0.0, 0.0])
    f = f - (f @ u) * u
    f /= max(np.linalg.norm(f), 1e-12)
    # shoulder J2, elbow A3 (a 7-axis arm's fourth joint, behind the redundant third)
    j3 = joint_for_slot(robot, 3)
    S, E = frames[2][:3, 3], frames[3 if j3 is None else j3 + 1][:3, 3]
    W = frames[n - 1][:3, 3]
    ref = W
    if front_reference == FLANGE:
        ref = (robot.fk(q) @ np.linalg.inv(robot.T_flange_tool))[:3, 3]
    front = bool((ref - o1) @ f >= -1e-9)
    bend = np.cross(E - S, W - E) @ np.cross(u, f)
    elbow_up = bool(bend >= 0.0)
    j5 = joint_for_slot(robot, 5)
    wrist_negative = None if j5 is None else bool(q[j5] < 0.0)
    return ArmConfig(front, elbow_up, wrist_negative, (), front_reference)


def turn_ambiguous_joints(robot: Robot, q: Array, flags: Callable[[Array], Hashable]
                          ) -> list[int]:
    """Joints a controller's flags cannot place: turning the joint by a whole turn (+-360 or
    +-720 deg) stays inside the robot's limits and gives the same `flags(q)`, so the same
    pose with the same flags has a second joint solution (a UR's shoulder, +-360 deg)."""
    lo = np.asarray(robot.limits.lower, dtype=float)
    hi = np.asarray(robot.limits.upper, dtype=float)
    q = np.asarray(q, dtype=float)
    mine = flags(q)
    out = []
    for j in range(len(q)):
        for k in (-2, -1, 1, 2):
            v = q[j] + 2.0 * math.pi * k
            if not lo[j] - 1e-9 <= v <= hi[j] + 1e-9:
                continue
            other = q.copy()
            other[j] = v
            if flags(other) == mine:
                out.append(j)
                break
    return out


def turn_count(angle: float) -> int:
    """Whole turns beyond (-180, 180] deg: 190 deg -> 1, -190 deg -> -1 (MELFA FL2)."""
    return int(math.ceil((angle - math.pi) / (2.0 * math.pi) - 1e-12))


def quadrant(angle: float) -> int:
    """ABB confdata quadrant: floor(angle / 90 deg) (0..90 -> 0, -90..0 -> -1)."""
    return int(math.floor(angle / (math.pi / 2.0) + 1e-12))
