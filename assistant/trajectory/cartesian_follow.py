"""Joint paths for Cartesian moves: IK pose by pose, each seeded from the previous one.

A LINEAR or CIRCULAR move is executed by the controller along the TCP path; our dense joint
path must be the configurations the arm actually passes through, so it is built the same way:
small TCP steps, each solved next to the previous solution. A step whose nearest solution is
still far away means a branch flip or a singularity on the way - the controller would stop
there - so it is reported, never silently bridged. For the 5-axis RV-2AJ an orientation off
the arm plane is projected into it (as the controller must) and the correction is reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.robots.model import IKFailure, Robot
from assistant.transforms import axis_angle_batch, rotation_angle

Array = np.ndarray


@dataclass(frozen=True)
class FollowResult:
    """Joints for each pose followed so far; `ok` False with the index and reason of the stop."""

    joints: Array  # (k, dof): the poses reached, k == len(poses) when ok
    ok: bool
    fail_index: int | None = None
    message: str = ""
    #: Largest rotation (rad) applied to a requested orientation to make it reachable.
    max_orientation_correction: float = 0.0


def follow_poses(robot: Robot, poses: Array, q_start: Array, *, max_joint_step: float = 0.1,
                 project_orientation: bool = True) -> FollowResult:
    """Solve IK along `poses` (M, 4, 4) starting next to `q_start`.

    Args:
        robot: kinematics.
        poses: T_base_tool per sample, the first one where the arm is at `q_start` or close.
        q_start: the configuration the move starts from (keeps its arm branch).
        max_joint_step: largest change of any joint between consecutive samples (rad).
        project_orientation: replace an unreachable orientation by the robot's nearest one.
    """
    q_prev = np.array(q_start, dtype=float)  # a contiguous copy: one compiled signature
    poses = np.asarray(poses, dtype=float)
    out = np.empty((len(poses), len(q_prev)))
    worst = 0.0
    # Robots with a batched closed form give every branch of every pose at once; the walk
    # takes the nearest of them pose by pose (`_walk_nearest`), a pose the batch cannot
    # answer like `ik` (or with no solution: the reason) goes through `ik`.
    batch = getattr(robot, "ik_candidates_batch", None)
    cands = batch(poses) if batch is not None and len(poses) else None
    usable = None
    if cands is not None:
        usable = cands.exact & cands.valid.any(axis=1)
        if not project_orientation:
            usable &= ~cands.projected
    i = 0
    while i < len(poses):
        if usable is not None and usable[i]:
            stop, joint = _walk_nearest(cands.joints, cands.valid, usable, q_prev,
                                        max_joint_step, i, out)
            if stop > i:
                worst = max(worst, float(cands.angle[i:stop].max()))
                q_prev = out[stop - 1]
            if joint >= 0:
                worst = max(worst, float(cands.angle[stop]))
                return _jump(robot, out, stop, joint, out[stop] - q_prev, worst)
            i = stop
            continue
        if (cands is not None and cands.exact[i] and not cands.valid[i].any()
                and (project_orientation or not cands.projected[i])):
            # The batch stands in for `ik` here and has no solution: its reason, without
            # asking `ik` (twice when the orientation was turned) only to hear it again.
            worst = max(worst, float(cands.angle[i]))
            return FollowResult(out[:i].copy(), False, i,
                                cands.reason(i, poses[i], robot.limits, robot.joint_names),
                                worst)
        T = poses[i]
        near = robot.ik_near(T, q_prev) if hasattr(robot, "ik_near") else None
        if near is not None and np.abs(near - q_prev).max() <= max_joint_step:
            out[i] = near
            q_prev = near
            i += 1
            continue
        res = robot.ik(T, q_prev)
        if (not res.ok and project_orientation and res.failure == IKFailure.ORIENTATION
                and res.nearest_T_base_tool is not None):
            worst = max(worst, rotation_angle(res.nearest_T_base_tool[:3, :3].T @ T[:3, :3]))
            res = robot.ik(res.nearest_T_base_tool, q_prev)
        if not res.ok:
            return FollowResult(out[:i].copy(), False, i, res.message or "no IK solution",
                                worst)
        q = np.asarray(res.best(q_prev), dtype=float)
        jump = np.abs(q - q_prev)
        if jump.max() > max_joint_step:
            return _jump(robot, out, i, int(np.argmax(jump)), q - q_prev, worst)
        out[i] = q
        q_prev = q
        i += 1
    return FollowResult(out, True, None, "", worst)


def _jump(robot: Robot, out: Array, i: int, j: int, step: Array, worst: float,
          ) -> FollowResult:
    """The walk stops at pose i: joint j would jump by step[j] (a branch change or a
    singularity, where the controller would stop too)."""
    return FollowResult(
        out[:i].copy(), False, i,
        f"{robot.joint_names[j]} would jump {np.degrees(abs(step[j])):.1f} deg between two "
        "samples (arm branch change or singularity)", worst)


def _walk_nearest(joints: Array, valid: Array, usable: Array, q_prev: Array,
                  max_joint_step: float, first: int, out: Array) -> tuple[int, int]:
    """Walk poses first.. writing each one's nearest valid branch to `out` (M, dof).

    joints (M, K, dof) candidates, valid (M, K) which are solutions, usable (M,) poses the
    batch answers. Returns (stop, joint): stop = M when every pose was walked; else the pose
    it stopped at, with joint = the joint that would jump more than `max_joint_step` there
    (its row in `out` then holds that nearest branch), or -1 if the batch cannot answer it.
    ~10 us a pose in numpy: ~1 ms for a move's 20-60 poses."""
    q = q_prev
    for i in range(first, len(joints)):
        if not usable[i]:
            return i, -1
        rows = np.flatnonzero(valid[i])
        d = np.linalg.norm(joints[i, rows] - q, axis=1)
        out[i] = joints[i, rows[int(np.argmin(d))]]
        jump = np.abs(out[i] - q)
        j = int(np.argmax(jump))
        if jump[j] > max_joint_step:
            return i, j
        q = out[i]
    return len(joints), -1


def slerp_rotations(R0: Array, R1: Array, u: Array) -> Array:
    """Rotations (M, 3, 3) from R0 to R1 at fractions u in [0, 1] (what controllers
    interpolate): R0 turned by u times the rotation from R0 to R1 about its fixed axis, i.e.
    slerp. The turn R0^T R1 as a rotation vector (scipy: from its quaternion, so its angle
    is 2 atan2(|xyz|, w), well conditioned near 0 and pi, the shorter way), then one
    Rodrigues rotation per fraction."""
    from scipy.spatial.transform import Rotation

    R0 = np.asarray(R0, dtype=float)
    u = np.clip(np.atleast_1d(np.asarray(u, dtype=float)), 0.0, 1.0)
    turn = Rotation.from_matrix(R0.T @ np.asarray(R1, dtype=float)).as_rotvec()
    angle = float(np.linalg.norm(turn))
    R = axis_angle_batch(np.broadcast_to(turn, (len(u), 3)), u * angle)
    return R0 @ R


def poses_from(points: Array, rotations: Array) -> Array:
    """Stack positions (M, 3) and rotations (M, 3, 3) into T_base_tool (M, 4, 4)."""
    T = np.zeros((len(points), 4, 4))
    T[:, :3, :3] = rotations
    T[:, :3, 3] = points
    T[:, 3, 3] = 1.0
    return T
