"""A robot as its controller sees it: the base moved to the frame the controller takes poses
in (`Robot.program_frame`).

FANUC's world frame sits 330 mm up on the J1 axis of an LR Mate, a UR's base is turned 180
deg about z from its ROS base_link: programs and controllers count poses from there. The
exporters write programs through this view (`export.program_frame`), the controller
emulators read them through it, and the links turn what a controller reports back into the
model's base - the joints are the same in every frame.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from assistant.robots.model import BatchPoses, IKResult, Robot
from assistant.transforms import inv_T

Array = np.ndarray


class FramedRobot(Robot):
    """`robot` with its base moved to the frame T_base_frame (a view; the robot is shared)."""

    def __init__(self, robot: Robot, T_base_frame: Array, words: str):
        self._robot = robot
        self._T = np.asarray(T_base_frame, dtype=float)
        self._Ti = inv_T(self._T)
        self._words = words
        self.name = robot.name
        self.joint_names = list(robot.joint_names)
        self.limits = robot.limits
        self.links = robot.links
        self.T_flange_tool = robot.T_flange_tool
        self.tool = getattr(robot, "tool", None)
        self.ik_settings = getattr(robot, "ik_settings", None)

    @property
    def T_base_frame(self) -> Array:
        """Where the view's base (the program frame) is in the robot's model base."""
        return self._T.copy()

    def program_frame(self) -> tuple[Array, str]:
        return np.eye(4), self._words

    @property
    def model_limits(self):  # noqa: ANN201 - JointLimits, as the robot's
        return self._robot.model_limits

    def rule_key(self) -> str:
        return self._robot.rule_key()

    def fk(self, q: Array) -> Array:
        return self._Ti @ self._robot.fk(q)

    def link_poses(self, q: Array) -> Array:
        return self._Ti @ self._robot.link_poses(q)

    def batch_fk(self, Q: Array) -> BatchPoses:
        b = self._robot.batch_fk(Q)
        R = self._Ti[:3, :3]
        return BatchPoses(np.asarray(b.positions) @ R.T + self._Ti[:3, 3],
                          R @ np.asarray(b.rotations))

    def batch_link_poses(self, Q: Array) -> Array:
        return self._Ti @ self._robot.batch_link_poses(Q)

    def ik(self, T_base_tool: Array, seed: Array | None = None, *,
           position_only: bool = False) -> IKResult:
        res = self._robot.ik(self._T @ np.asarray(T_base_tool, dtype=float), seed,
                             position_only=position_only)
        near = res.nearest_T_base_tool
        return replace(res, nearest_T_base_tool=None if near is None else self._Ti @ near)

    def fixed_frame(self, name: str) -> Array | None:
        T = self._robot.fixed_frame(name)
        return None if T is None else self._Ti @ T

    def with_tool(self, T_flange_tool: Array) -> Robot:
        return FramedRobot(self._robot.with_tool(T_flange_tool), self._T, self._words)

    def with_ik_settings(self, settings) -> Robot:  # noqa: ANN001 - the robot's own type
        inner = getattr(self._robot, "with_ik_settings", None)
        return self if inner is None else FramedRobot(inner(settings), self._T, self._words)

    def urdf(self) -> str:
        return self._robot.urdf()

    def description_hash(self) -> str:
        return f"{self._robot.description_hash()}:framed"


def controller_view(robot: Robot) -> Robot:
    """`robot` seen from its program frame: a `FramedRobot`, or the robot itself when that
    frame is its base."""
    T, words = robot.program_frame()
    if np.allclose(T, np.eye(4), atol=1e-12):
        return robot
    return FramedRobot(robot, T, words)
