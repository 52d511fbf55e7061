"""A mission plan is a chain of pieces: transfers (re-plannable) and application paths (fixed).

Execution drives a plan piece by piece: a transfer may be re-planned from wherever the robot
stopped, an application path may not (it is the work itself). Pieces are joined into one
`Trajectory` for display, verification and export by `join_pieces`, which also puts each
application path's "before" tool actions on the move that arrives at it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from enum import Enum

import numpy as np

from assistant.mission.motion import Trajectory, Waypoint
from assistant.trajectory.assemble import TrajectoryReport

Array = np.ndarray


class PieceKind(str, Enum):
    TRANSFER = "transfer"
    APPLICATION = "application"


@dataclass(frozen=True)
class PlanPiece:
    """One transfer or application path with its trajectory (robot base frame)."""

    kind: PieceKind
    label: str
    trajectory: Trajectory
    report: TrajectoryReport | None = None
    #: Application path name (APPLICATION pieces).
    path_name: str = ""
    #: Program position names for where the piece starts and ends ("" = numbered).
    start_name: str = ""
    end_name: str = ""

    @property
    def q_start(self) -> Array:
        return np.asarray(self.trajectory.start.q, dtype=float)

    @property
    def q_end(self) -> Array:
        wps = self.trajectory.waypoints()
        return np.asarray(wps[-1].q, dtype=float)

    def dense(self) -> Array:
        return self.trajectory.dense_joint_path()


def join_pieces(pieces: Sequence[PlanPiece], start_name: str = "",
                end_name: str = "") -> Trajectory:
    """One trajectory through all pieces, in order.

    Each piece's first waypoint must equal the previous piece's last (within 1e-6 rad).
    Application pieces carry `actions_at_start` (e.g. close the gripper): they go onto the
    previous move as `actions_after`, or to the trajectory start if nothing comes before.
    Pieces' `start_name`/`end_name` name the waypoints where they start and end.
    """
    if not pieces:
        raise ValueError("no pieces to join")
    first = pieces[0].trajectory
    start = _named(first.start, start_name or pieces[0].start_name)
    motions = []
    actions_at_start = tuple(first.actions_at_start)
    for k, piece in enumerate(pieces):
        t = piece.trajectory
        if k > 0:
            gap = float(np.abs(piece.q_start - pieces[k - 1].q_end).max())
            if gap > 1e-6:
                raise ValueError(f"piece {piece.label!r} starts {gap:.2e} rad away from where "
                                 f"{pieces[k - 1].label!r} ends")
            if t.actions_at_start:
                if motions:
                    last = motions[-1]
                    motions[-1] = replace(last, actions_after=tuple(last.actions_after)
                                          + tuple(t.actions_at_start))
                else:
                    actions_at_start += tuple(t.actions_at_start)
            if piece.start_name and motions:
                motions[-1] = replace(motions[-1],
                                      target=_named(motions[-1].target, piece.start_name))
        motions += list(t.motions)
        if piece.end_name and motions:
            motions[-1] = replace(motions[-1], target=_named(motions[-1].target, piece.end_name))
    if end_name and motions:
        motions[-1] = replace(motions[-1], target=_named(motions[-1].target, end_name))
    return Trajectory(start, motions, actions_at_start)


def _named(w: Waypoint, name: str) -> Waypoint:
    return replace(w, name=name) if name else w
