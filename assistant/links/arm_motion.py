"""Following a timed joint path step by step, stopping before the arm touches an obstacle.

The simulated robot and both emulators move their model with a `PathFollower`: each step
sweeps the arm from where it is to where time says it should be and checks that swept motion
(through every path vertex in between) with an exact FCL `CollisionChecker`. On contact it
stops at the last free sample, which is what an operator pressing the Collision! button (or
a controller's collision detection) achieves on a real cell, minus the braking distance.
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
    """Walks a `TimedPath` in time; each `advance(dt)` is checked against the obstacles."""

    def __init__(self, timed: TimedPath, checker: CollisionChecker | None = None):
        self.timed = timed
        self.checker = checker
        self.t = 0.0
        self.q = timed.q[0].copy()
        self.finished = len(timed.q) < 2 or timed.duration <= 0.0
        self.stopped_by_contact = False

    @property
    def segment(self) -> int:
        return len(self.timed.q) - 1 if self.finished else self.timed.segment_at(self.t)

    def check_start(self) -> MotionCheck | None:
        """A contact at the very first configuration (the arm already touches something)."""
        if self.checker is None:
            return None
        mc = self.checker.check_motion(self.q, self.q)
        return None if mc.valid else mc

    def advance(self, dt: float) -> Advance:
        if self.finished or self.stopped_by_contact:
            return Advance(self.q.copy(), self.segment, 0.0, self.finished)
        tp = self.timed
        t0, t1 = self.t, min(self.t + max(dt, 0.0), tp.duration)
        q1, seg1 = tp.sample(t1)
        if self.checker is not None:
            # The swept motion passes through every vertex strictly between t0 and t1.
            inner = [i for i in range(1, len(tp.t) - 1) if t0 < tp.t[i] < t1]
            knots = [(t0, self.q)] + [(float(tp.t[i]), tp.q[i]) for i in inner] + [(t1, q1)]
            for (ta, qa), (tb, qb) in zip(knots[:-1], knots[1:], strict=True):
                if np.allclose(qa, qb, atol=1e-12):
                    continue
                mc = self.checker.check_motion(qa, qb)
                if mc.valid:
                    continue
                f = float(mc.first_invalid_fraction or 0.0)
                f_free = max(0.0, f - 1.0 / mc.samples)
                q_free = qa + f_free * (qb - qa)
                t_free = ta + f_free * (tb - ta)
                self.q, self.t = q_free, t_free
                self.stopped_by_contact = True
                return Advance(q_free.copy(), tp.segment_at(t_free), t_free - t0, False, mc)
        self.q, self.t = q1, t1
        if t1 >= tp.duration:
            self.finished = True
            self.q = tp.q[-1].copy()
            return Advance(self.q.copy(), len(tp.q) - 1, t1 - t0, True)
        return Advance(q1.copy(), seg1, t1 - t0, False)
