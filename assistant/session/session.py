"""`Session`: the one facade every operator action goes through (web UI, scripts, tests, CLI).

Each action is checked by the workflow machine (a refused action raises `TransitionRefused`
with the sentence to show and changes nothing), applied under the session lock, recorded for
undo if it edits the document, counted, autosaved before the lock is let go (a page reads the
session under the same lock: what it shows is saved, `saving.py`), and announced on the event
bus. An action that fails half-way is rolled back to the snapshot taken before it. Long work
(world model, planning, execution, exploration) runs on the worker thread with progress and
Cancel; the machine's busy/moving modes keep edits out meanwhile.

The actions live in parts by concern (`*_part.py`). Some are composed: an object built with
the session as its core, owning its own state, whose verbs the session hands over to (`export`
-> `exporter.export`). The rest are still mixed into `Session`: their methods run on the
Session's state, under its lock and workflow. Either kind reaches the whole only through
`contract.PartContract`.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from assistant.cell.model import Cell, CellObject
from assistant.links.link import RobotLink
from assistant.links.settings import LinkSettings
from assistant.mission.model import (
    Location,
    Mission,
)
from assistant.mission.motion import Trajectory
from assistant.robots.model import Robot
from assistant.session.cell_part import CellActions
from assistant.session.document import Document
from assistant.session.events import (
    ErrorRaised,
    EventBus,
    Notice,
    SceneChanged,
    StateChanged,
)
from assistant.session.export_part import ExportPart
from assistant.session.history import History
from assistant.session.layout_part import LayoutActions
from assistant.session.motion_hold import MotionHold
from assistant.session.motion_part import MotionActions
from assistant.session.persistence_part import Persistence
from assistant.session.planning_part import PlanningActions
from assistant.session.saving import Saving
from assistant.session.scene_part import ScenePart
from assistant.session.setup_part import SetupActions
from assistant.session.start_part import StartPosturePart
from assistant.session.study_part import StudyPart
from assistant.session.teach_part import TeachActions
from assistant.session.types import (
    Counters,
    HiddenObstacle,
    hint_for,
)
from assistant.session.worker import Worker
from assistant.session.world_settings import WorldSettings
from workflow.machine import Facts, Machine, Mode, TransitionRefused

if TYPE_CHECKING:
    from concurrent.futures import Future

    from assistant.session.pointer_live import LivePointer
    from assistant.study import Region, Scoring, StudyProblem, StudyResult, StudySettings

Array = np.ndarray


class Session(SetupActions, CellActions, LayoutActions, TeachActions, MotionActions,
              PlanningActions, Persistence, Saving):
    """Everything the operator does, headless or behind the web page: the state, the action
    plumbing and the workflow here; the actions by concern in its parts - composed
    (`exporter`, `studies`, `scene`, `start_posture`) or, for the rest, mixed in."""

    def __init__(self, folder: str | Path | None = None, *, autosave: bool = True):
        self.bus = EventBus()
        self.worker = Worker(self.bus)
        self.machine = Machine()
        self.cell = Cell()
        self.locations: dict[str, Location] = {}
        self.mission = Mission()
        self.link_settings = LinkSettings()
        self.hidden: list[HiddenObstacle] = []
        self.counters = Counters()
        self.history = History()
        self.folder = Path(folder) if folder is not None else None
        self.autosave_enabled = autosave and self.folder is not None
        self.pointer_config: dict[str, Any] = {}
        self.export_dialect = "melfa"
        self.world_settings = WorldSettings()
        self.trajectory: Trajectory | None = None
        self.plan_report: dict[str, Any] | None = None
        #: Step 7, composed: the exported program and the verbs that make and send it.
        self.exporter = ExportPart(self)
        #: Placement studies, composed: the last study's result and the verbs that run one.
        self.studies = StudyPart(self)
        #: What the page draws, composed (as viser's `server.scene`).
        self.scene = ScenePart(self)
        #: The start posture against the cell, composed: what touches and the way out.
        self.start_posture = StartPosturePart(self)
        self.recorded_collisions: list[Array] = []
        #: The enabling switch: who may move the robot (enforced once pages serve this).
        self.hold = MotionHold()
        self.hold.on_lost(self._holder_gone)
        self._lock = threading.RLock()
        self._link: RobotLink | None = None
        self._q_sim: Array | None = None  # joints of the robot when no link is connected
        #: The page's simulated robot halts against a hidden obstacle and waits for the
        #: operator's Collision!; scripts keep the self-reporting robot.
        self.operator_confirms_contacts = False
        #: The simulated robot stands against something unknown, waiting for Collision!.
        self.halted = False
        self.halts_this_run = 0
        #: How the last run ended (`ExecutionFinished.summary`); None when planned since.
        self.last_run: dict | None = None
        self._world: Any = None  # planning back end (world model + roadmap), built on demand
        self._world_key: tuple | None = None
        self._last_error: str = ""
        self._pointer: LivePointer | None = None  # while the camera step is open
        self.pending_point: Any = None  # the last dwell TaughtPoint, waiting for a name
        self.sample: str | None = None  # the sample cell this session started from
        self.load_notes: list[str] = []  # what loading ignored (unknown keys), to report

    # ================================================================== queries
    @property
    def robot(self) -> Robot:
        return self.cell.robot()

    def facts(self) -> Facts:
        m = self.mission
        return Facts(robot_ready=True, objects=len(self.cell.objects),
                     locations=len(self.locations), has_start=m.start is not None,
                     has_goal=m.goal is not None, paths=len(m.paths),
                     world_ready=self.world_ready, plan_ready=self.trajectory is not None,
                     program_ready=self.program is not None,
                     link_ok=self.machine.mode != Mode.ERROR)

    @property
    def world_ready(self) -> bool:
        return self._world is not None and self._world_key == self._obstacles_key()

    def transitions(self):
        return self.machine.transitions(self.facts())

    def document(self) -> Document:
        return Document.capture(self.cell, self.locations, self.mission)

    def current_joints(self) -> Array:
        if self._link is not None and self._link.connected:
            return np.asarray(self._link.current_joints(), dtype=float)
        if self._q_sim is None:
            self._q_sim = self._home()
        return self._q_sim.copy()

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

    @property
    def program(self) -> Any:
        """The last exported program (owned by `exporter`); None when stale or not yet."""
        return self.exporter.program

    @program.setter
    def program(self, value: Any) -> None:
        self.exporter.program = value

    # ================================================================== 7. export
    def export(self, dialect: str | None = None, *, name: str | None = None,
               frame: str | None = None, count: bool = True) -> Any:
        """Write the planned mission as a robot program (`ExportPart.export`)."""
        return self.exporter.export(dialect, name=name, frame=frame, count=count)

    def upload_program(self) -> str:
        """Send the exported program to the robot controller (`ExportPart.upload_program`)."""
        return self.exporter.upload_program()

    # ================================================================== the start posture
    def start_posture_problem(self) -> str | None:
        """What the current posture touches, checked now (`StartPosturePart.problem_now`)."""
        return self.start_posture.problem_now()

    def start_posture_links(self) -> tuple[str, ...]:
        """The links the last start check found touching (the page draws them red)."""
        return self.start_posture.links

    def start_posture_text(self) -> str:
        """What the last start check found touching, in the operator's words ("" if free)."""
        return self.start_posture.problem or ""

    def move_to_free_posture(self, *, wait: bool = True) -> Future:
        """Drive the robot out of what it touches (`StartPosturePart.move_to_free_posture`)."""
        return self.start_posture.move_to_free_posture(wait=wait)

    def _require_free_start(self) -> None:
        """Planning refuses a start posture that touches the cell (`require_free`)."""
        self.start_posture.require_free()

    # ================================================================== scene for the UI
    def scene_objects(self) -> list[CellObject]:
        """Placed objects (`ScenePart.scene_objects`)."""
        return self.scene.scene_objects()

    def robot_visuals(self) -> list[tuple[str, Any, tuple[int, int, int]]]:
        """(link name, mesh, colour) of every visual link (`ScenePart.robot_visuals`)."""
        return self.scene.robot_visuals()

    def link_poses_world(self, q: Array | None = None) -> Array:
        """T_world_link for every robot link at q (`ScenePart.link_poses_world`)."""
        return self.scene.link_poses_world(q)

    def path_polylines(self, tol: float = 0.0005) -> list[tuple[str, Array]]:
        """Each application path as points for drawing (`ScenePart.path_polylines`)."""
        return self.scene.path_polylines(tol)

    def plan_polylines(self) -> list[tuple[str, Array]]:
        """The planned trajectory per motion (`ScenePart.plan_polylines`)."""
        return self.scene.plan_polylines()

    # ================================================================== placement studies
    @property
    def placement_study(self) -> StudyResult | None:
        """The last placement study's result (owned by `studies`); None before the first."""
        return self.studies.placement_study

    def study_problem(self, *, object_name: str | None = None, carry: bool = True,
                      joint_margin_deg: float = 5.0,
                      clearance_mm: float | None = None) -> StudyProblem:
        """The study of this cell and mission (`StudyPart.study_problem`)."""
        return self.studies.study_problem(object_name=object_name, carry=carry,
                                          joint_margin_deg=joint_margin_deg,
                                          clearance_mm=clearance_mm)

    def start_study_placement(self, region: Region, settings: StudySettings | None = None,
                              *, scoring: Scoring | None = None, **problem: Any) -> Future:
        """A placement study in the background (`StudyPart.start_study_placement`)."""
        return self.studies.start_study_placement(region, settings, scoring=scoring,
                                                   **problem)

    def study_placement(self, region: Region, settings: StudySettings | None = None,
                        *, scoring: Scoring | None = None, **problem: Any) -> StudyResult:
        """A placement study, waited for (`StudyPart.study_placement`)."""
        return self.studies.study_placement(region, settings, scoring=scoring, **problem)

    def apply_placement(self, index: int) -> Array:
        """Move the study's subject to candidate `index` (`StudyPart.apply_placement`)."""
        return self.studies.apply_placement(index)

    # ================================================================== action plumbing
    @contextlib.contextmanager
    def _action(self, label: str, steps: tuple[str, ...] | None, *, undoable: bool = True,
                scene: str = "", count: bool = True) -> Iterator[None]:
        with self._lock:
            try:
                if steps is not None:
                    self.machine.require(steps, label)
                elif self.machine.mode not in (Mode.IDLE,):
                    self.machine.require((self.machine.main,), label)
            except TransitionRefused as exc:
                self._error(str(exc))
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
                self._error(f"{label}: {exc}", hint_for(exc))
                raise
            if undoable:
                self.history.record(label, before)
                self._invalidate(before)
            if count:
                self.counters.operator_actions += 1
            self._autosave()
        if scene:
            self.bus.emit(SceneChanged(scene))
        self._emit_state()

    def _invalidate(self, before: Document) -> None:
        """Edits make the plan and the program stale (the world only if obstacles moved)."""
        now = self.document()
        if now.mission != before.mission or now.locations != before.locations or \
                now.obstacles_key() != before.obstacles_key():
            self.trajectory = None
            self.plan_report = None
            self.program = None
        if now.obstacles_key() != before.obstacles_key():
            self._start_check()

    def _start_check(self) -> None:
        """`start_posture.check` after an edit; a check that cannot run (a lost link) is
        said, and never undoes the edit."""
        try:
            self.start_posture.check()
        except Exception as exc:  # noqa: BLE001 - the edit stands; the operator is told
            self.bus.emit(Notice(f"the start posture could not be checked against the cell: "
                                 f"{exc}"))

    def _obstacles_key(self) -> tuple:
        return (self.document().obstacles_key(), self.cell.robot_spec, self.world_settings)

    def _error(self, message: str, hint: str = "") -> None:
        self._last_error = message
        self.bus.emit(ErrorRaised(message, hint))

    def _emit_state(self) -> None:
        m = self.machine
        self.bus.emit(StateChanged(m.state, m.number, m.title, m.mode.value))

    # ================================================================== workflow
    def next(self) -> str:
        return self.fire("next")

    def previous(self) -> str:
        return self.fire("previous")

    def fire(self, event: str) -> str:
        """A toolbar transition (next, previous, a jump, cancel, stop, collision, ...)."""
        if event == "cancel":
            self.cancel()
            return self.machine.state
        if event == "stop":
            self.stop()
            return self.machine.state
        if event == "collision":
            self.indicate_collision()
            return self.machine.state
        if event == "acknowledge":
            self.acknowledge_error()
            return self.machine.state
        if event == "reconnect":
            self.reconnect_link()
            return self.machine.state
        with self._lock:
            try:
                state = self.machine.fire(event, self.facts())
            except TransitionRefused as exc:
                self._error(str(exc))
                raise
            self.counters.operator_actions += 1
            self._autosave()
        self._emit_state()
        return state

    def goto(self, step: str) -> str:
        with self._lock:
            try:
                state = self.machine.goto(step, self.facts())
            except TransitionRefused as exc:
                self._error(str(exc))
                raise
            self.counters.operator_actions += 1
            self._autosave()
        self._emit_state()
        return state

    def undo(self) -> str:
        return self._travel("undo", self.history.undo)

    def redo(self) -> str:
        return self._travel("redo", self.history.redo)

    def _travel(self, what: str, step: Callable[[Document], tuple[str, Document]]) -> str:
        """Undo or redo: the document `step` returns replaces the current one."""
        with self._lock:
            self.machine.require((self.machine.main,), what)
            label, doc = step(self.document())
            self._restore(doc)
        self.bus.emit(SceneChanged("all"))
        self._emit_state()
        return label

    def _restore(self, doc: Document) -> None:
        before = self.document()
        self.mission = doc.restore(self.cell, self.locations)
        self._invalidate(before)
        self._autosave()
