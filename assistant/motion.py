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


@dataclass
class Trajectory:
    """A start waypoint and the moves after it."""

    start: Waypoint
    motions: list[Motion] = field(default_factory=list)

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
