"""A 7-axis arm's redundant joint as the controller's one external axis (RAPID eax_a, KRL E1).

The two controllers here that run 7-axis arms keep six "robot" axes and write the seventh,
the redundant elbow joint, as the first external axis:

* ABB IRB 14000 YuMi (RobotWare 6, RAPID): the physical joints along the chain are axes
  1, 2, 7, 3, 4, 5, 6 - the third joint is axis 7, written as ``eax_a`` (degrees) of the
  ``extax`` of ``jointtarget`` and ``robtarget`` (``[eax_a, 9E9, 9E9, 9E9, 9E9, 9E9]``), the
  others as ``rax_1..rax_6``. In a robtarget eax_a is the arm angle the controller resolves
  the redundancy with. Sources: the driver configuration in ros-industrial/abb_robot_driver
  issue 15 (YuMi joint ``rob_R_3`` is logical axis 3 at kinematic axis 4, ...,
  ``rob_R_6`` logical 6 at kinematic 7), BerkeleyAutomation/yumirws ``YuMiArm.get_joints``
  (``rax_1, rax_2, eax_a, rax_3, ..., rax_6`` in chain order; MoveAbsJ targets built as
  ``RobJoint(q[:2] + q[3:]), ExtJoint(eax_a=q[2])``); RobotStudio's ``ExternalAxisValues``
  (eax_a..eax_f, 9E9 = "no axis").
* KUKA LBR (KRL on the KUKA controller, the LWR 4+ convention): the joints along the chain
  are A1, A2, E1, A3, A4, A5, A6 - the third joint is the external axis E1 of ``E6AXIS`` and
  ``E6POS``. Sources: CentroEPiaggio/kuka-lwr issue 96 (joints ``lwr_a1, lwr_a2, lwr_e1,
  lwr_a3 .. lwr_a6``) and the FRI client code whose joint arrays are "A1, A2, E1, A3, A4, A5,
  A6".

A generic 7-axis URDF (a Franka Panda's panda_joint1..7) is mapped the same way: URDF joint 3
(index `REDUNDANT_JOINT`) is the external axis, joints 1, 2, 4, 5, 6, 7 are the main axes
1..6. Cartesian targets carry the external axis too (the arm angle = that joint's value in
the planned posture), and the round-trip simulation solves them, and every sample of a
Cartesian path, with that joint held (`solve_pinned`; along a path it is interpolated
linearly from start to target, as the controllers interpolate an external axis).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from assistant.robots.model import Robot

Array = np.ndarray

#: The axis number `configuration.axis_slots` gives the external axis: not one of A1..A6.
EXTERNAL_SLOT = 7
#: Controller axis for each joint of a 7-axis arm (A1, A2, E1, A3, A4, A5, A6).
SEVEN_AXIS_SLOTS = (1, 2, EXTERNAL_SLOT, 3, 4, 5, 6)
#: The joint (0-based, chain order) a 7-axis arm's controller writes as its external axis.
REDUNDANT_JOINT = SEVEN_AXIS_SLOTS.index(EXTERNAL_SLOT)


def axis_values(slots: Sequence[int], q: Array) -> tuple[Array, float | None]:
    """(six main axis values by axis number, zero where the arm has no such axis; the
    external axis value or None), in the joints' units (rad). `slots`: `axis_slots(robot)`."""
    main = np.zeros(6)
    external = None
    for j, s in enumerate(slots):
        if s == EXTERNAL_SLOT:
            external = float(q[j])
        else:
            main[s - 1] = float(q[j])
    return main, external


def joints_from_axes(slots: Sequence[int], main: Sequence[float],
                     external: float | None) -> Array:
    """The joint vector back from `axis_values` (ValueError if the external axis is
    missing for an arm that has one)."""
    q = np.zeros(len(slots))
    for j, s in enumerate(slots):
        if s == EXTERNAL_SLOT:
            if external is None:
                raise ValueError("the 7-axis arm's external axis has no value")
            q[j] = external
        else:
            q[j] = main[s - 1]
    return q


def external_joint(slots: Sequence[int]) -> int | None:
    """Index of the joint written as the external axis, None for arms without one."""
    return slots.index(EXTERNAL_SLOT) if EXTERNAL_SLOT in slots else None


def solve_pinned(robot: Robot, T_base_tool: Array, joint: int, value: float,
                 seeds: Iterable[Array], *, max_iterations: int = 60,
                 position_tol: float = 1e-8, orientation_tol: float = 1e-7) -> list[Array]:
    """Joint solutions reaching the pose with `joint` held at `value`, one Newton run per seed.

    With one joint held a 7-axis arm is a 6-axis arm: a damped Newton iteration on the other
    six (numerical Jacobian from `robot.fk`; 10 us per call for a URDF arm) converges to the
    branch next to its seed. Solutions are clamped into the joint limits; distinct ones (by
    0.1 mrad) are returned in seed order, none if `value` is outside the joint's range.
    """
    T = np.asarray(T_base_tool, dtype=float)
    lo, hi = robot.limits.lower, robot.limits.upper
    if not lo[joint] - 1e-9 <= value <= hi[joint] + 1e-9:
        return []
    free = [k for k in range(robot.dof) if k != joint]
    out: list[Array] = []
    for seed in seeds:
        q = np.clip(np.asarray(seed, dtype=float).copy(), lo, hi)
        q[joint] = value
        for _ in range(max_iterations):
            e = _pose_error(robot.fk(q), T)
            if np.linalg.norm(e[:3]) < position_tol and np.linalg.norm(e[3:]) < orientation_tol:
                if all(np.max(np.abs(q - s)) > 1e-4 for s in out):
                    out.append(q.copy())
                break
            J = _jacobian(robot, q, free)
            lam2 = 1e-6 * min(1.0, float(np.linalg.norm(e)))
            dq = J.T @ np.linalg.solve(J @ J.T + lam2 * np.eye(6), e)
            step = float(np.max(np.abs(dq)))
            if step > 0.3:
                dq *= 0.3 / step
            q[free] = np.clip(q[free] + dq, lo[free], hi[free])
    return out


def _pose_error(T: Array, T_target: Array) -> Array:
    """(target - current position, rotation vector turning current into target), base frame."""
    rot = Rotation.from_matrix(T_target[:3, :3] @ T[:3, :3].T).as_rotvec()
    return np.concatenate([T_target[:3, 3] - T[:3, 3], rot])


def _jacobian(robot: Robot, q: Array, free: list[int], h: float = 1e-7) -> Array:
    """d(position, rotation) / d(free joints) by forward differences of `robot.fk`."""
    T0 = robot.fk(q)
    J = np.empty((6, len(free)))
    for c, k in enumerate(free):
        qk = q.copy()
        qk[k] += h
        Tk = robot.fk(qk)
        J[:3, c] = (Tk[:3, 3] - T0[:3, 3]) / h
        J[3:, c] = Rotation.from_matrix(Tk[:3, :3] @ T0[:3, :3].T).as_rotvec() / h
    return J
