"""The start posture against the cell: checked whenever the cell changes and when planning
starts, so "the start posture touches the wall" is said before a run, never during it.

The start posture is where the robot stands now (the simulated robot's home until it moves):
a run begins by moving from there. A part of the `Session`, composed rather than mixed in
(`Session.start_posture`): it owns what the last check found; the session's start-posture
verbs hand over to it, and it reaches the session only through the parts' contract."""

from __future__ import annotations

from concurrent.futures import Future

import numpy as np

from assistant.session.contract import PartContract
from assistant.session.events import Notice, SceneChanged
from assistant.session.types import SessionError

Array = np.ndarray


class StartPosturePart:
    """What the start posture touches, said when the cell changes; the way out of it."""

    def __init__(self, core: PartContract) -> None:
        self._core = core
        #: What the last check found touching, in the operator's words (None when free),
        #: and the names of the links that touch (the page draws them red).
        self.problem: str | None = None
        self.links: tuple[str, ...] = ()

    def problem_now(self) -> str | None:
        """What the robot's current posture touches, in the operator's words ("the J3 link
        (forearm_link) touches wall"); None when it is free. The same check as teach and
        plan (the cell's objects and the robot's self-collision rule)."""
        checker = self._core.known_checker()
        report = checker.check(self._core.current_joints())
        if not report.contacts:
            return None
        return report.describe(checker.link_words)

    def check(self) -> None:
        """After a cell change, a robot move or a load: check the start posture; a new
        problem is announced once with the way out, and the page redraws the robot."""
        checker = self._core.known_checker()
        report = checker.check(self._core.current_joints())
        links = tuple(sorted({c.link for c in report.contacts}
                             | {c.other for c in report.contacts if c.self_collision}))
        problem = report.describe(checker.link_words) if report.contacts else None
        before = self.problem
        self.problem, self.links = problem, links
        if problem is not None and problem != before:
            objects = sorted({c.other for c in report.contacts if not c.self_collision})
            place = f"place {', '.join(objects)} elsewhere or " if objects else ""
            self._core.bus.emit(Notice(
                f"The start posture touches something: {problem}. Before planning, {place}move "
                "the robot to a free posture (Jog the robot: Move to a free posture)"))
        if problem != before:
            self._core.bus.emit(SceneChanged("start"))

    def recheck(self) -> None:
        """`check` after an edit; a check that cannot run (a lost link) is said, and never
        undoes the edit."""
        try:
            self.check()
        except Exception as exc:  # noqa: BLE001 - the edit stands; the operator is told
            self._core.bus.emit(Notice(f"the start posture could not be checked against the "
                                       f"cell: {exc}"))

    def require_free(self) -> None:
        """Planning refuses a start posture that touches the cell (the run could not leave
        it), naming what it touches; `move_to_free_posture` is the way out."""
        problem = self.problem_now()
        if problem is not None:
            raise SessionError(f"no plan: the start posture touches something ({problem}); "
                               "move the robot to a free posture first (Move to a free "
                               "posture)")

    def move_to_free_posture(self, *, wait: bool = True) -> Future:
        """Drive the robot out of what its posture touches, to the nearest free posture, on
        a path that never touches anything new (`home.way_to_free_posture`)."""
        from assistant.session.home import way_to_free_posture

        checker = self._core.known_checker()
        q0 = self._core.current_joints()
        if checker.check(q0).valid:
            raise SessionError("the robot's posture touches nothing: no need to move it")
        path = way_to_free_posture(self._core.robot, checker, q0)
        if path is None:
            raise SessionError("no free posture found that the robot can reach without "
                               "touching something else: jog it out joint by joint")
        def run(progress: object) -> object:
            event = self._core.setup.link().move_path(np.asarray(path))
            self.check()  # clears the red start before the move reports done
            return event

        fut = self._core.run_motion("move to a free posture", run)
        if wait:
            fut.result()
        return fut
