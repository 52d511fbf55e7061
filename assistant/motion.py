"""Planned motion as the rest of the product sees it: waypoints with poses *and* joints, joined
by joint, linear, circular or spline moves.

The planner produces a `Trajectory`; the exporter turns it (plus the mission's tool actions)
into a neutral program and then a dialect; the robot links execute its dense joint path.
Every waypoint carries the joint solution so configuration flags (MELFA FL1, KUKA S/T, ABB
confdata) come from the arm that was actually planned, not from a guess.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

Array = np.ndarray


class ToolActionKind(str, Enum):
    GRIPPER_OPEN = "gripper_open"  # MELFA HOPEN, KRL/RAPID/UR: an output
    GRIPPER_CLOSE = "gripper_close"
    OUTPUT = "output"  # set digital output `channel` to `value`
    WAIT = "wait"  # dwell `seconds`


@dataclass(frozen=True)
class ToolAction:
    """Something the tool does between moves (gripper, output, dwell)."""

    kind: ToolActionKind
    channel: int = 1
    value: bool = True
    seconds: float = 0.0

    def to_json(self) -> dict:
        return {"kind": self.kind.value, "channel": self.channel, "value": self.value,
                "seconds": self.seconds}

    @staticmethod
    def from_json(d: dict) -> ToolAction:
        return ToolAction(ToolActionKind(d["kind"]), int(d.get("channel", 1)),
                          bool(d.get("value", True)), float(d.get("seconds", 0.0)))


class MotionKind(str, Enum):
    JOINT = "joint"  # PTP / MOV / MoveJ / movej
    LINEAR = "linear"  # LIN / MVS / MoveL / movel
    CIRCULAR = "circular"  # CIRC / MVR / MoveC / movec: start (previous target), via, end
    SPLINE = "spline"  # SPL / free-shape: through `through` points to the target


@dataclass(frozen=True)
class Waypoint:
    """A TCP pose in the robot base frame with the joint solution that reaches it."""

    T_base_tool: Array
    q: Array
    name: str = ""

    @property
    def position(self) -> Array:
        return self.T_base_tool[:3, 3]


@dataclass(frozen=True)
class Motion:
    """One move from the previous waypoint to `target`."""

    kind: MotionKind
    target: Waypoint
    via: Waypoint | None = None  # CIRCULAR only
    through: tuple[Waypoint, ...] = ()  # SPLINE only: intermediate points
    #: Dense joint path from the previous target to this one (for execution/verification).
    joint_path: Array | None = field(default=None, repr=False)
    label: str = ""  # mission step name, for comments in programs
    #: Cartesian speed (m/s) for LINEAR/CIRCULAR/SPLINE; for JOINT a fraction of max speed.
    speed: float | None = None
    #: Blend into the next move (controller approximation/CNT) within this radius (m).
    blend_radius: float = 0.0
    #: Tool actions performed after arriving at `target` (gripper, outputs, waits).
    actions_after: tuple[ToolAction, ...] = ()


@dataclass
class Trajectory:
    """A start waypoint and the moves after it."""

    start: Waypoint
    motions: list[Motion] = field(default_factory=list)
    #: Tool actions before the first move (e.g. open the gripper).
    actions_at_start: tuple[ToolAction, ...] = ()

    def waypoints(self) -> list[Waypoint]:
        return [self.start] + [m.target for m in self.motions]

    def dense_joint_path(self) -> Array:
        """All joint configurations in order (start, each motion's path or its target)."""
        out = [np.asarray(self.start.q, dtype=float)[None]]
        for m in self.motions:
            if m.joint_path is not None and len(m.joint_path):
                out.append(np.asarray(m.joint_path, dtype=float)[1:])
            else:
                out.append(np.asarray(m.target.q, dtype=float)[None])
        return np.concatenate(out)

    def primitive_counts(self) -> dict[str, int]:
        counts: dict[str, int] = {}
        for m in self.motions:
            counts[m.kind.value] = counts.get(m.kind.value, 0) + 1
        return counts
