"""Following a timed joint path step by step, stopping before the arm touches an obstacle.

The simulated robot and both emulators move their model with a `PathFollower`: each path
segment is checked once, whole, with an exact FCL `CollisionChecker` when the arm enters it;
on contact the arm stops at the segment's last free sample when time reaches it, which is
what an operator pressing the Collision! button (or a controller's collision detection)
achieves on a real cell, minus the braking distance. Checking whole segments makes where the
arm stops independent of how time is cut into steps (a loaded machine's longer steps, 1x or
20x): the same path stops at the same posture.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import MotionCheck
from assistant.links.timing import TimedPath

Array = np.ndarray


@dataclass(frozen=True)
class Advance:
    """Result of one step: where the arm is now and why it stopped, if it did."""

    q: Array
    #: Segment i (path[i] -> path[i+1]) the arm is on; N-1 once finished.
    segment: int
    used_s: float
    finished: bool
    #: Set when the step hit an obstacle; `q` is then the last free configuration.
    collision: MotionCheck | None = None

    def contact_names(self) -> list[str]:
        if self.collision is None or self.collision.report is None:
            return []
        return sorted({c.other for c in self.collision.report.contacts})

    def describe_contact(self) -> str:
        if self.collision is None or self.collision.report is None:
            return "contact"
        return self.collision.report.describe()


class PathFollower:
    """Walks a `TimedPath` in time; each segment is checked against the obstacles once."""

    def __init__(self, timed: TimedPath, checker: CollisionChecker | None = None):
        self.timed = timed
        self.checker = checker
        self.t = 0.0
        self.q = timed.q[0].copy()
        self.finished = len(timed.q) < 2 or timed.duration <= 0.0
        self.stopped_by_contact = False
        #: segment -> None (free) or (last free fraction, the check that met the contact)
        self._contacts: dict[int, tuple[float, MotionCheck] | None] = {}

    @property
    def segment(self) -> int:
        return len(self.timed.q) - 1 if self.finished else self.timed.segment_at(self.t)

    def check_start(self) -> MotionCheck | None:
        """A contact at the very first configuration (the arm already touches something)."""
        if self.checker is None:
            return None
        mc = self.checker.check_motion(self.q, self.q)
        return None if mc.valid else mc

    def _contact(self, i: int) -> tuple[float, MotionCheck] | None:
        if i not in self._contacts:
            qa, qb = self.timed.q[i], self.timed.q[i + 1]
            found = None
            if self.checker is not None and not np.allclose(qa, qb, atol=1e-12):
                mc = self.checker.check_motion(qa, qb)
                if not mc.valid:
                    f = float(mc.first_invalid_fraction or 0.0)
                    found = (max(0.0, f - 1.0 / mc.samples), mc)
            self._contacts[i] = found
        return self._contacts[i]

    def advance(self, dt: float) -> Advance:
        if self.finished or self.stopped_by_contact:
            return Advance(self.q.copy(), self.segment, 0.0, self.finished)
        tp = self.timed
        t0, t1 = self.t, min(self.t + max(dt, 0.0), tp.duration)
        for i in range(tp.segment_at(t0), tp.segment_at(t1) + 1):
            hit = self._contact(i)
            if hit is None:
                continue
            f_free, mc = hit
            t_c = float(tp.t[i] + f_free * (tp.t[i + 1] - tp.t[i]))
            if t_c <= t1:
                self.q = tp.q[i] + f_free * (tp.q[i + 1] - tp.q[i])
                self.t = max(t0, t_c)
                self.stopped_by_contact = True
                return Advance(self.q.copy(), i, self.t - t0, False, mc)
        q1, seg1 = tp.sample(t1)
        self.q, self.t = q1, t1
        if t1 >= tp.duration:
            self.finished = True
            self.q = tp.q[-1].copy()
            return Advance(self.q.copy(), len(tp.q) - 1, t1 - t0, True)
        return Advance(q1.copy(), seg1, t1 - t0, False)
