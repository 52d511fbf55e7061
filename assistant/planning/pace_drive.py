"""Which pace a drive of the executor runs at: the program's, as far as the path is the piece.

A piece drives at the program's pace (`export.pace`: the time law of the predicted cycle
time), so the simulated run at 1x lasts what the program will. After a Collision! the arm
first backs off along where it came from - motion no program contains, timed by the joints'
speed limits at the run's speed - and then continues on the re-planned piece's tail at its
program pace.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.export.pace import ProgramPace, program_pace
from assistant.links.timing import time_parametrize
from assistant.planning.pieces import PlanPiece
from assistant.robots.model import Robot

Array = np.ndarray

#: Two samples are one posture within this (rad): the tail of a drive is copied from the
#: piece's path, so only copying can differ.
SAME_POSTURE = 1e-9


@dataclass(frozen=True)
class DrivePace:
    """Per sample of a drive: arrival time (s) and hold (s) at 100 % of the program's speed."""

    t: Array
    hold: Array


class PaceCache:
    """The program pace of each piece, computed once per piece (a few ms each)."""

    def __init__(self, robot: Robot):
        self.robot = robot
        self._paces: dict[int, tuple[PlanPiece, Array, ProgramPace | None]] = {}

    def piece_pace(self, piece: PlanPiece) -> tuple[Array, ProgramPace | None]:
        hit = self._paces.get(id(piece))
        if hit is None or hit[0] is not piece:
            dense = piece.dense()
            hit = (piece, dense, program_pace(piece.trajectory, self.robot, dense))
            self._paces[id(piece)] = hit
        return hit[1], hit[2]

    def drive_pace(self, path: Array, piece: PlanPiece, speed: float) -> DrivePace | None:
        """The pace of `path`, whose tail is the tail of `piece`'s path; None when the tail is
        shorter than one segment or the piece has no program pace."""
        dense, pace = self.piece_pace(piece)
        if pace is None:
            return None
        P = np.asarray(path, dtype=float)
        n = min(len(P), len(dense))
        same = np.all(np.abs(P[len(P) - n:][::-1] - dense[len(dense) - n:][::-1])
                      <= SAME_POSTURE, axis=1)
        tail = n if bool(np.all(same)) else int(np.argmin(same))
        if tail < 2:
            return None
        j, k = len(P) - tail, len(dense) - tail  # P[j:] is dense[k:]
        head = time_parametrize(P[:j + 1], self.robot.limits.velocity, speed).t
        t = np.concatenate([head[:-1], head[-1] + pace.t[k:] - pace.t[k]])
        hold = np.concatenate([np.zeros(j), pace.hold[k:]])
        return DrivePace(t, hold)
