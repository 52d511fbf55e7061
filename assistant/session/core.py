"""The session's core: the state every part shares, the lock, the action wrapper, the long-task
runners and the event bus - what the composed parts reach through `PartContract`. The rest of
the document (link settings, hidden obstacles, pointer set-up, world settings, the plan, the
dialect) is kept by the part that owns it and named here only (`Forward`), so the page, the
scripts and the other parts read and write it as before.

Each action is checked by the workflow machine (a refused action raises `TransitionRefused`
with the sentence to show and changes nothing), applied under the session lock, recorded for
undo if it edits the document, counted, autosaved before the lock is let go (a page reads the
session under the same lock: what it shows is saved, `saving.py`), and announced on the event
bus. An action that fails half-way is rolled back to the snapshot taken before it. Long work
(world model, planning, execution, exploration) runs on the worker thread with progress and
Cancel (`run_busy`, `run_motion`); the machine's busy/moving modes keep edits out meanwhile.
The workflow's own verbs (next, previous, a jump, undo, redo) live here too.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import numpy as np

from assistant.cell.model import Cell
from assistant.collision.checker import CollisionChecker
from assistant.links.settings import LinkSettings
from assistant.mission.model import Location, Mission
from assistant.mission.motion import Trajectory
from assistant.progress import Cancelled, Progress
from assistant.robots.model import Robot
from assistant.session.commands import PageCommand
from assistant.session.contract import PartContract
from assistant.session.document import Document
from assistant.session.events import ErrorRaised, EventBus, Notice, SceneChanged, StateChanged
from assistant.session.handover import Forward
from assistant.session.history import History
from assistant.session.motion_hold import MotionHold
from assistant.session.types import Counters, HiddenObstacle, hint_for
from assistant.session.worker import Worker
from assistant.session.world_settings import WorldSettings
from workflow.machine import Facts, Machine, Mode, TransitionRefused

Array = np.ndarray


class SessionCore(PartContract):
    """The shared state, the lock, the action wrapper and the workflow (see the module)."""

    def __init__(self, folder: str | Path | None = None, *, autosave: bool = True):
        # the core: events, the one long task, the workflow, the lock, undo, the counts
        self.bus = EventBus()
        self.worker = Worker(self.bus)
        self.machine = Machine()
        self.lock = threading.RLock()
        self.history = History()
        self.counters = Counters()
        #: The enabling switch: who may move the robot (enforced once pages serve this).
        self.hold = MotionHold()
        # the operator's document (saved with the session)
        self.cell = Cell()
        self.locations: dict[str, Location] = {}
        self.mission = Mission()
        # (the rest of the document is kept by the parts that own it: see below)
        # where it is saved, where it came from
        self.folder = Path(folder) if folder is not None else None
        self.autosave_enabled = autosave and self.folder is not None
        self.sample: str | None = None  # the sample cell this session started from
        self.load_notes: list[str] = []  # what loading ignored (unknown keys), to report
        self._last_error: str = ""

    # ============================================= the document the parts keep, by its names
    #: How to reach the robot; what only the simulated robot knows (`setup` keeps them).
    link_settings = Forward[LinkSettings]("setup", "link_settings")
    hidden = Forward[list[HiddenObstacle]]("setup", "hidden")
    #: The cameras and the pointer's colour (`teaching`).
    pointer_config = Forward[dict[str, Any]]("teaching", "pointer_config")
    #: The world model's and the run's settings, and the plan (`planning`).
    world_settings = Forward[WorldSettings]("planning", "world_settings")
    trajectory = Forward[Trajectory | None]("planning", "trajectory")
    plan_report = Forward[dict[str, Any] | None]("planning", "plan_report")
    #: The dialect last written (`exporter`).
    export_dialect = Forward[str]("exporter", "export_dialect")

    # ================================================================== queries
    @property
    def robot(self) -> Robot:
        return self.cell.robot()

    @property
    def world_ready(self) -> bool:
        """The world model is built for the current obstacles (`PlanningPart.world_ready`)."""
        return self.planning.world_ready

    def facts(self) -> Facts:
        m = self.mission
        return Facts(robot_ready=True, objects=len(self.cell.objects),
                     locations=len(self.locations), has_start=m.start is not None,
                     has_goal=m.goal is not None, paths=len(m.paths),
                     world_ready=self.world_ready, plan_ready=self.trajectory is not None,
                     program_ready=self.program is not None,
                     link_ok=self.machine.mode != Mode.ERROR)

    def transitions(self):  # noqa: ANN201
        return self.machine.transitions(self.facts())

    def document(self) -> Document:
        return Document.capture(self.cell, self.locations, self.mission)

    def current_joints(self) -> Array:
        """Where the robot stands: the connected link's joints, else the simulated robot's
        (its home until it moves)."""
        setup = self.setup
        if setup.robot_link is not None and setup.robot_link.connected:
            return np.asarray(setup.robot_link.current_joints(), dtype=float)
        if setup.q_sim is None:
            setup.q_sim = self._home()
        return setup.q_sim.copy()

    def _home(self) -> Array:
        """Where the simulated robot starts: the zero posture (clipped to the limits) unless
        that puts a moving link below the mounting plane (a UR arm at zero lies stretched
        over its table), else the nearest posture that keeps every moving link 50 mm above
        it (`home.raised_posture`); free of the cell's objects when there are any."""
        from assistant.session.home import raised_posture

        return raised_posture(self.robot, self.cell.collision_objects_in_base())

    def T_world_base(self) -> Array:
        return np.asarray(self.cell.T_world_base, dtype=float)

    def tcp_world(self, q: Array | None = None) -> Array:
        q = self.current_joints() if q is None else q
        return self.T_world_base() @ self.robot.fk(q)

    def known_checker(self) -> CollisionChecker:
        """The exact check against what is known of the cell (its objects and the robot's
        self-collision rule): teach, jog, plan and the start posture use it."""
        return CollisionChecker(self.robot, self.cell.collision_objects_in_base())

    def obstacles_key(self) -> tuple:
        """What the world model depends on: the obstacles, the robot, the world settings."""
        return (self.document().obstacles_key(), self.cell.robot_spec, self.world_settings)

    @property
    def program(self) -> Any:
        """The last exported program (owned by `exporter`); None when stale or not yet."""
        return self.exporter.program

    @program.setter
    def program(self, value: Any) -> None:
        self.exporter.program = value

    # ================================================================== action plumbing
    @contextlib.contextmanager
    def action(self, label: str, steps: tuple[str, ...] | None, *, undoable: bool = True,
               scene: str = "", count: bool = True) -> Iterator[None]:
        """One operator action (see the module): checked, locked, undoable, saved, said."""
        with self.lock:
            try:
                if steps is not None:
                    self.machine.require(steps, label)
                elif self.machine.mode not in (Mode.IDLE,):
                    self.machine.require((self.machine.main,), label)
            except TransitionRefused as exc:
                self.error(str(exc))
                raise
            before = self.document()
            mission_before = self.mission
            try:
                yield
            except TransitionRefused:
                raise
            except Exception as exc:
                mission = before.restore(self.cell, self.locations)
                self.mission = mission if mission_before is not None else Mission()
                self.error(f"{label}: {exc}", hint_for(exc))
                raise
            if undoable:
                self.history.record(label, before)
                self._invalidate(before)
            if count:
                self.counters.operator_actions += 1
            self.saving.autosave()
        if scene:
            self.bus.emit(SceneChanged(scene))
        self.emit_state()

    def _invalidate(self, before: Document) -> None:
        """Edits make the plan and the program stale (the world only if obstacles moved)."""
        now = self.document()
        if now.mission != before.mission or now.locations != before.locations or \
                now.obstacles_key() != before.obstacles_key():
            self.trajectory = None
            self.plan_report = None
            self.program = None
        if now.obstacles_key() != before.obstacles_key():
            self.start_posture.recheck()

    def run_busy(self, task: str, fn: Callable[[Progress], Any],
                 steps: tuple[str, ...] | None = None, *, moving: bool = False) -> Future:
        """Run long work on the worker: the machine is busy (or moving) until it ends."""
        if moving:
            self.hold.check_start()  # only the present holder of motion authority
        with self.lock:
            if steps is not None:
                self.machine.require(steps, task)
            if moving:
                self.machine.begin_moving()
                self.setup.begin_run()
            else:
                self.machine.begin_busy(task)
        self.emit_state()
        try:
            return self.worker.submit(task, fn, self._ended(task, say_cancelled=True))
        except RuntimeError:
            with self.lock:
                self.machine.end_mode()
            self.emit_state()
            raise

    def run_motion(self, task: str, fn: Callable[[Progress], Any]) -> Future:
        """Move the robot on the worker (a jog, the way to a free posture): the machine is
        moving until it ends; only the holder of motion authority may start it."""
        self.hold.check_start()
        with self.lock:
            self.machine.begin_moving()
        self.emit_state()
        return self.worker.submit(task, fn, self._ended(task, say_cancelled=False))

    def _ended(self, task: str, *, say_cancelled: bool) -> Callable[[Future], None]:
        """The worker's callback when `task` ends: the mode ends, an error is shown (a
        cancel is not an error; long work says it was cancelled, a stopped motion needs no
        word), and the session is saved."""

        def done(fut: Future) -> None:
            with self.lock:
                self.machine.end_mode()
                exc = fut.exception()
                if exc is not None and not isinstance(exc, Cancelled):
                    self.error(f"{task}: {exc}", hint_for(exc))
                elif isinstance(exc, Cancelled) and say_cancelled:
                    self.bus.emit(Notice(f"{task} cancelled; nothing was lost"))
                self.saving.autosave()
            self.emit_state()

        return done

    def error(self, message: str, hint: str = "") -> None:
        """Say an error (`ErrorRaised`), keeping the last one."""
        self._last_error = message
        self.bus.emit(ErrorRaised(message, hint))

    def emit_state(self) -> None:
        """Announce the workflow's state (`StateChanged`)."""
        m = self.machine
        self.bus.emit(StateChanged(m.state, m.number, m.title, m.mode.value))

    # ================================================================== workflow
    def next(self) -> str:
        return self.fire(PageCommand.NEXT)

    def previous(self) -> str:
        return self.fire(PageCommand.PREVIOUS)

    def fire(self, command: PageCommand | str) -> str:
        """A toolbar command (`PageCommand`: next, previous, cancel, stop, collision, ...) or
        another of the machine's transitions by name; returns the workflow step after it."""
        event = command.value if isinstance(command, PageCommand) else str(command)
        handler = {PageCommand.CANCEL.value: self.motion.cancel,
                   PageCommand.STOP.value: self.motion.stop,
                   PageCommand.COLLISION.value: self.motion.indicate_collision,
                   PageCommand.ACKNOWLEDGE.value: self.setup.acknowledge_error,
                   PageCommand.RECONNECT.value: self.setup.reconnect_link}.get(event)
        if handler is not None:
            handler()
            return self.machine.state
        return self._move(lambda facts: self.machine.fire(event, facts))

    def goto(self, step: str) -> str:
        """Jump to any step whose guards hold (the step list, loading a session)."""
        return self._move(lambda facts: self.machine.goto(step, facts))

    def _move(self, move: Callable[[Facts], str]) -> str:
        """A step of the workflow: refused with the reason, else counted, saved, said."""
        with self.lock:
            try:
                state = move(self.facts())
            except TransitionRefused as exc:
                self.error(str(exc))
                raise
            self.counters.operator_actions += 1
            self.saving.autosave()
        self.emit_state()
        return state

    def undo(self) -> str:
        return self._travel("undo", self.history.undo)

    def redo(self) -> str:
        return self._travel("redo", self.history.redo)

    def _travel(self, what: str, step: Callable[[Document], tuple[str, Document]]) -> str:
        """Undo or redo: the document `step` returns replaces the current one."""
        with self.lock:
            self.machine.require((self.machine.main,), what)
            label, doc = step(self.document())
            self._restore(doc)
        self.bus.emit(SceneChanged("all"))
        self.emit_state()
        return label

    def _restore(self, doc: Document) -> None:
        before = self.document()
        self.mission = doc.restore(self.cell, self.locations)
        self._invalidate(before)
        self.saving.autosave()
