"""Small pieces of a transfer the mission planner builds: the roadmap's joint path as joint
moves, and a smoothed transfer made to end exactly on the next piece's start posture."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from assistant.mission.motion import Motion, MotionKind, Trajectory, Waypoint
from assistant.robots.model import Robot
from assistant.trajectory.assemble import joint_interpolation

Array = np.ndarray


def _snap_end(robot: Robot, traj: Trajectory, q_goal: Array, tol: float = 1e-3,
              ) -> Trajectory | None:
    """Make the trajectory end exactly at q_goal (the next piece starts there).

    The assembly re-solves the last pose by IK, so its joints may differ from the goal
    posture by rounding; beyond `tol` (rad) it is another posture and None is returned.
    """
    last = traj.motions[-1]
    gap = float(np.abs(np.asarray(last.target.q) - q_goal).max())
    if gap > tol:
        return None
    if gap == 0.0:
        return traj
    target = Waypoint(robot.fk(q_goal), q_goal.copy(), last.target.name)
    jp = None
    if last.joint_path is not None:
        jp = np.array(last.joint_path, dtype=float, copy=True)
        jp[-1] = q_goal
    motions = list(traj.motions)
    motions[-1] = replace(last, target=target, joint_path=jp)
    return Trajectory(traj.start, motions, traj.actions_at_start)


def _joint_moves(robot: Robot, joint_path: Sequence[Array], label: str, assembly) -> Trajectory:
    """The roadmap's joint path as JOINT motions (dense paths for execution and checks)."""
    q0 = np.asarray(joint_path[0], dtype=float)
    motions = []
    prev = q0
    for q in joint_path[1:]:
        q = np.asarray(q, dtype=float)
        Q = joint_interpolation(robot, prev, q, assembly.step)
        motions.append(Motion(MotionKind.JOINT, Waypoint(robot.fk(q), q), joint_path=Q,
                              label=label, speed=assembly.joint_speed))
        prev = q
    return Trajectory(Waypoint(robot.fk(q0), q0), motions)

