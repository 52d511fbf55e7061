"""The bound every run ends within: a number of indications and seconds of planning.

Why: a learn-and-re-plan loop without a bound can run for many minutes with no word of why
(issue 56: 15 minutes, then killed). Every run ends - goal reached, or a reason - within
`ExecutionConfig.max_indications` and `max_planning_seconds` of planning (the time the arm
stands while the planner works: the first plan, each re-plan, the final plan; not the
driving). Every planning call gets a `Progress` that ends it at the deadline
(`PlanningTimeUp`, a kind of `Cancelled`, so everything unwinds as on Cancel): the roadmap's
search, the joint-space search and the smoothing report progress as they go, so none of them
searches past it. The progress line names the bound: "re-planning - indication 3 of 20, 95 s
of planning left".
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from assistant.progress import Cancelled, Progress


class PlanningTimeUp(Cancelled):
    """The run's planning time is used up (raised from a bounded progress)."""


class _Bounded(Progress):
    """Forwards to `parent` with the bound in every message; raises at `end`."""

    def __init__(self, parent: Progress, end: float, line: Callable[[str], str]):
        super().__init__(parent.task)
        self._cancel = parent._cancel  # the operator's Cancel still cancels
        self._parent, self._end, self._line = parent, end, line

    def update(self, fraction: float, message: str = "", *, force: bool = False) -> None:
        if time.perf_counter() > self._end:
            raise PlanningTimeUp("the run's planning time is used up")
        self._parent.update(fraction, self._line(message), force=force)
        super().update(fraction, message, force=force)

    def check(self) -> None:
        super().check()
        if time.perf_counter() > self._end:
            raise PlanningTimeUp("the run's planning time is used up")


class RunBounds:
    """Indications and planning seconds of one run (counted over `run` and `resume`)."""

    def __init__(self, indications: int, seconds: float):
        self.indications = int(indications)
        self.seconds = float(seconds)
        self.used = 0.0
        self._since: float | None = None  # start of the planning under way

    def left(self) -> float:
        """Planning seconds left (the planning under way counted)."""
        now = 0.0 if self._since is None else time.perf_counter() - self._since
        return max(0.0, self.seconds - self.used - now)

    @contextmanager
    def planning(self) -> Iterator[None]:
        """Count the time inside as planning (nested uses count once)."""
        if self._since is not None:
            yield
            return
        self._since = time.perf_counter()
        try:
            yield
        finally:
            self.used += time.perf_counter() - self._since
            self._since = None

    def check(self) -> None:
        if self.left() <= 0.0:
            raise PlanningTimeUp("the run's planning time is used up")

    def line(self, what: str, indications: int) -> str:
        """The progress line: what happens, indications so far of the bound, time left."""
        return (f"{what} - indication {indications} of {self.indications}, "
                f"{self.left():.0f} s of planning left")

    def progress(self, parent: Progress, what: str, indications: Callable[[], int],
                 ) -> Progress:
        """A progress for one planning call: its messages carry the bound, and it ends the
        call at the deadline (now + `left`)."""
        end = time.perf_counter() + self.left()

        def line(message: str) -> str:
            head = self.line(what, indications())
            return f"{head}: {message}" if message else head

        return _Bounded(parent, end, line)
