"""The elastic net's particles: TCP points with the joint configurations that reach them.

A planner's joint path (e.g. A* through road cells) jumps from cell to cell; the net wants
roughly equidistant TCP points. Resampling happens along the joint path itself (linear joint
interpolation between its configurations, which is what the search already checked), so every
particle is a real configuration and ``points[i] == fk(joints[i])`` exactly.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from assistant.robots.model import Robot

Array = np.ndarray


@dataclass(frozen=True)
class Particles:
    """Ordered path nodes: TCP positions (N, 3) in the base frame and their joints (N, dof)."""

    points: Array
    joints: Array

    def __post_init__(self) -> None:
        if self.points.ndim != 2 or self.points.shape[1] != 3:
            raise ValueError(f"points must be (N, 3), got {self.points.shape}")
        if len(self.joints) != len(self.points):
            raise ValueError("points and joints must have the same length")

    def __len__(self) -> int:
        return len(self.points)

    def tcp_length(self) -> float:
        """Length of the TCP polyline through the particles (m)."""
        return polyline_length(self.points)

    def spacing(self) -> Array:
        return row_norms(np.diff(self.points, axis=0))


def row_norms(X: Array) -> Array:
    """Euclidean norm of each row of X (N, k): bit for bit `np.linalg.norm(X, axis=1)` (the
    same products summed by the same reduction), without its argument handling, which
    costs more than the arithmetic on the net's few dozen particles."""
    return np.sqrt((X * X).sum(axis=1))


def polyline_length(points: Array) -> float:
    """Length of the polyline through points (N, 3)."""
    return float(row_norms(np.diff(points, axis=0)).sum())


#: Subdivision passes (bounded: each pass at least halves the longest chord).
_PASSES = 6


def densify_joint_path(robot: Robot, joint_path: Sequence[Array] | Array, max_tcp_step: float,
                       ) -> tuple[Array, Array]:
    """Subdivide a joint path linearly until no TCP chord exceeds `max_tcp_step`.

    Returns (joints (M, dof), TCP points (M, 3)). The subdivision is refined a few times
    because a joint step's TCP chord is only known after FK.
    """
    Q = np.atleast_2d(np.asarray(joint_path, dtype=float))
    if len(Q) < 2:
        raise ValueError("a joint path needs at least two configurations")
    P = robot.batch_fk(Q).positions
    for _ in range(_PASSES):
        chord = np.linalg.norm(np.diff(P, axis=0), axis=1)
        if chord.max(initial=0.0) <= max_tcp_step:
            break
        parts = np.maximum(1, np.ceil(chord / max_tcp_step).astype(int))
        # Segment i gets the fractions 1/k .. k/k (k = parts[i]), all segments at once.
        seg = np.repeat(np.arange(len(parts)), parts)
        j = np.arange(1, len(seg) + 1) - np.repeat(np.cumsum(parts) - parts, parts)
        f = (j / parts[seg])[:, None]
        new = Q[seg] + f * (Q[seg + 1] - Q[seg])
        ends = j == parts[seg]  # each segment's end is the given row, not a + 1 (b - a)
        new[ends] = Q[seg + 1][ends]
        Q = np.concatenate([Q[:1], new])
        P = robot.batch_fk(Q).positions
    return Q, np.array(P, dtype=float)


def resample_joint_path(robot: Robot, joint_path: Sequence[Array] | Array, spacing: float,
                        ) -> Particles:
    """Particles about `spacing` apart along the TCP path; first and last configs kept exactly.

    The count is chosen so the spacing is as even as the path allows; each particle's joints
    come from linear joint interpolation along the (densified) input path.
    """
    if spacing <= 0.0:
        raise ValueError("spacing must be positive")
    Q, P = densify_joint_path(robot, joint_path, spacing / 8.0)
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(s[-1])
    n_seg = max(1, int(round(total / spacing)))
    targets = np.linspace(0.0, total, n_seg + 1)
    idx = np.clip(np.searchsorted(s, targets, side="right") - 1, 0, len(Q) - 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        f = np.where(seg[idx] > 0.0, (targets - s[idx]) / seg[idx], 0.0)
    f = np.clip(f, 0.0, 1.0)[:, None]
    joints = Q[idx] + f * (Q[idx + 1] - Q[idx])
    joints[0], joints[-1] = Q[0], Q[-1]
    points = np.array(robot.batch_fk(joints).positions, dtype=float)
    return Particles(points, joints)
