"""The program's pace along a planned piece: when the arm passes each sample of its joint path.

The simulated robot follows these times, so a run at 1x real time lasts what the predicted
cycle time says and the program step's per-step times match what the operator watched. One
time law serves both: `cycle_time.profiled_moves` (the ruckig profile of every move as a
controller runs it, blends and programmed speeds included), applied here to the joint path
the executor sends instead of a fresh simulation. Gripper actions and waits become holds: the
arm stands at the sample where the program performs them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.export.cycle_time import CycleTimeLimits, profiled_moves
from assistant.export.errors import ExportError
from assistant.export.program import Gripper, Move, SetOutput, Wait, program_from_trajectory
from assistant.export.simulate import SimulatedMove, Simulation, tcp_points
from assistant.mission.motion import Trajectory
from assistant.robots.model import Robot

Array = np.ndarray

#: A program position is the path sample within this (rad, every joint): both come from the
#: same planned waypoint, so only copying can differ.
SAME_POSTURE = 1e-6


@dataclass(frozen=True)
class ProgramPace:
    """Per sample of a joint path: `t` when the arm arrives (s from the piece's start, holds
    before it included) and `hold` how long it then stands there (a gripper action, a wait)."""

    t: Array
    hold: Array

    @property
    def seconds(self) -> float:
        return float(self.t[-1] + self.hold[-1]) if len(self.t) else 0.0


def program_pace(traj: Trajectory, robot: Robot, path: Array,
                 limits: CycleTimeLimits | None = None) -> ProgramPace | None:
    """The program's pace along `path` (the piece's dense joint path, `traj.dense_joint_path`).

    None when the program's positions cannot be found on the path in order (the caller then
    times the path by the joints' limits) or the program cannot be timed (no speed for a
    Cartesian move, a path the kinematics cannot follow).
    """
    P = np.asarray(path, dtype=float)
    if P.ndim != 2 or len(P) < 1:
        return None
    try:
        program = program_from_trajectory(traj, robot, name="PACE", move_to_start=False)
    except (ExportError, ValueError):
        return None
    moves = program.moves()
    ends = _move_ends(P, moves)
    if ends is None:
        return None
    starts = [0, *ends[:-1]]
    sim = Simulation([SimulatedMove(k, m.step, m.kind, tcp_points(robot, P[a:b + 1]),
                                    P[a:b + 1]) for k, (m, a, b)
                      in enumerate(zip(moves, starts, ends, strict=True))])
    lim = limits or CycleTimeLimits()
    try:
        segs = profiled_moves(program, robot, lim, simulation=sim)
    except (ExportError, ValueError):
        return None
    t = np.zeros(len(P))
    hold = np.zeros(len(P))
    clock, at, k = 0.0, 0, 0
    for ins in program.instructions:
        if isinstance(ins, Move):
            s, a, b = segs[k], starts[k], ends[k]
            # arrival at the move's start stays as it was (before any hold there)
            t[a + 1:b + 1] = clock + s.sample_times()[1:]
            clock, at, k = clock + s.seconds, b, k + 1
            continue
        extra = {Wait: lambda i: float(i.seconds), Gripper: lambda i: lim.gripper_s,
                 SetOutput: lambda i: lim.output_s}.get(type(ins))
        if extra is not None:
            dt = extra(ins)
            hold[at] += dt
            clock += dt
    # samples past the last move (none when the path ends at the last target) stay put
    if ends and ends[-1] < len(P) - 1:
        t[ends[-1] + 1:] = clock
    return ProgramPace(np.maximum.accumulate(t), hold)


def _move_ends(P: Array, moves: list[Move]) -> list[int] | None:
    """The path index where each move's target is, in order (None: not found)."""
    out: list[int] = []
    cur = 0
    for m in moves:
        q = m.target.q
        if q is None:
            return None
        d = np.max(np.abs(P[cur:] - np.asarray(q, dtype=float)), axis=1)
        hits = np.nonzero(d <= SAME_POSTURE)[0]
        if not len(hits):
            return None
        # the first hit after where the move starts; the start itself only for a move that
        # goes nowhere
        later = hits[hits > 0]
        cur = cur + int(later[0] if len(later) else hits[0])
        out.append(cur)
    return out
