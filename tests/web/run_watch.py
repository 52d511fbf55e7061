"""What the operator saw the arm do, from the session's own pose updates: shared by
`test_web_run_pace.py` (which asserts on it) and `benchmarks/operator_effort.py` (which
reports `surprise_moves` and `run_vs_predicted` from it)."""

from __future__ import annotations

import time

import numpy as np

from assistant.session.events import CollisionRecorded, Notice, RobotMoved

#: A taught location is reached within this (m): the arm stops on it to well under 1 mm.
AT_M = 0.001
#: ... left once the TCP is this far away (m), and revisited if it comes this close again.
LEFT_M = 0.02
REVISIT_M = 0.005


class Watch:
    """Every pose the session publishes (wall time, TCP in the world), every Collision! and
    every notice (a failed run's message then says why the robot stopped)."""

    def __init__(self, session) -> None:
        self.robot = session.robot
        self.T_wb = session.T_world_base()
        self.poses: list[tuple[float, np.ndarray]] = []
        self.collisions: list[float] = []
        self.notices: list[str] = []
        session.bus.subscribe(self._on)

    def _on(self, ev: object) -> None:
        if isinstance(ev, RobotMoved):
            p = self.T_wb @ np.r_[self.robot.fk(np.asarray(ev.q, dtype=float))[:3, 3], 1.0]
            self.poses.append((time.monotonic(), p[:3]))
        elif isinstance(ev, CollisionRecorded):
            self.collisions.append(time.monotonic())
        elif isinstance(ev, Notice):
            self.notices.append(ev.message)


def taught_points(session) -> dict[str, np.ndarray]:
    """Each taught location's TCP position in the world (m)."""
    return {name: np.asarray(loc.T_world_tool, dtype=float)[:3, 3]
            for name, loc in session.locations.items()}


def revisits(watch: Watch, taught: dict[str, np.ndarray], after: float,
             upto: int | None = None) -> list[str]:
    """Taught locations reached and left before `after` that the TCP came close to again after
    it (over the poses before index `upto`: later the operator started a drive): work
    repeated or a drive back the operator did not start."""
    poses = watch.poses[:upto]
    before = [p for t, p in poses if t <= after]
    later = [p for t, p in poses if t > after]
    out = []
    for name, x in taught.items():
        d = np.array([np.linalg.norm(p - x) for p in before])
        reached = np.nonzero(d <= AT_M)[0]
        if not len(reached) or not np.any(d[reached[0]:] >= LEFT_M):
            continue  # never reached, or still there: not completed work
        back = min((float(np.linalg.norm(p - x)) for p in later), default=np.inf)
        if back <= REVISIT_M:
            out.append(f"{name} ({back * 1000:.1f} mm)")
    return out


def program_seconds(watch: Watch, start: np.ndarray, goal: np.ndarray, since: int) -> float:
    """Wall seconds from the arm leaving `start` to its arrival at `goal`, over the poses
    from index `since` (one drive of the program)."""
    drive = watch.poses[since:]
    at_start = [t for t, p in drive if np.linalg.norm(p - start) <= AT_M]
    if not at_start:
        raise AssertionError("the drive did not pass the program's start")
    left = at_start[-1]
    at_goal = [t for t, p in drive if t > left and np.linalg.norm(p - goal) <= AT_M]
    if not at_goal:
        raise AssertionError("the drive did not end at the program's goal")
    return at_goal[0] - left
