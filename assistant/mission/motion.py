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


# ---------------------------------------------------------------------- JSON (session files)
def _arr(a: Array | None) -> list | None:
    return None if a is None else np.asarray(a, dtype=float).tolist()


def _finite(v: object, shape: tuple[int, ...] | None, what: str) -> Array:
    a = np.asarray(v, dtype=float)
    if (shape is not None and a.shape != shape) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: expected finite numbers of shape {shape}, got {a.shape}")
    return a


def waypoint_to_json(w: Waypoint) -> dict:
    return {"T_base_tool": _arr(w.T_base_tool), "q": _arr(w.q), "name": w.name}


def waypoint_from_json(d: dict) -> Waypoint:
    return Waypoint(_finite(d["T_base_tool"], (4, 4), "waypoint pose"),
                    _finite(d["q"], None, "waypoint joints"), str(d.get("name", "")))


def trajectory_to_json(t: Trajectory) -> dict:
    return {
        "start": waypoint_to_json(t.start),
        "actions_at_start": [a.to_json() for a in t.actions_at_start],
        "motions": [{
            "kind": m.kind.value, "target": waypoint_to_json(m.target),
            "via": waypoint_to_json(m.via) if m.via else None,
            "through": [waypoint_to_json(w) for w in m.through],
            "joint_path": _arr(m.joint_path), "label": m.label, "speed": m.speed,
            "blend_radius": m.blend_radius,
            "actions_after": [a.to_json() for a in m.actions_after],
        } for m in t.motions],
    }


def trajectory_from_json(d: dict) -> Trajectory:
    motions = []
    for i, m in enumerate(d.get("motions", [])):
        jp = m.get("joint_path")
        motions.append(Motion(
            MotionKind(m["kind"]), waypoint_from_json(m["target"]),
            waypoint_from_json(m["via"]) if m.get("via") else None,
            tuple(waypoint_from_json(w) for w in m.get("through", [])),
            None if jp is None else _finite(jp, None, f"motion {i} joint path"),
            str(m.get("label", "")),
            None if m.get("speed") is None else float(m["speed"]),
            float(m.get("blend_radius", 0.0)),
            tuple(ToolAction.from_json(a) for a in m.get("actions_after", []))))
    return Trajectory(waypoint_from_json(d["start"]), motions,
                      tuple(ToolAction.from_json(a) for a in d.get("actions_at_start", [])))
