"""`Session`: the one facade every operator action goes through (web UI, scripts, tests, CLI).

Each action is checked by the workflow machine (a refused action raises `TransitionRefused`
with the sentence to show and changes nothing), applied under the session lock, recorded for
undo if it edits the document, counted, autosaved, and announced on the event bus. An action
that fails half-way is rolled back to the snapshot taken before it. Long work (world model,
planning, execution, exploration) runs on the worker thread with progress and Cancel; the
machine's busy/moving modes keep edits out meanwhile.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from assistant.cad import CadImport, load_cad
from assistant.cell import Cell, CellError, CellObject, ObjectRole, PrimitiveKind, PrimitiveSpec
from assistant.cell_io import load_cell, save_cell
from assistant.collision import CollisionChecker, Obstacle
from assistant.links.settings import LinkSettings, make_link
from assistant.mission import (
    ApplicationPath,
    Location,
    LocationSource,
    Mission,
    PathSegment,
    SegmentKind,
)
from assistant.motion import ToolAction, Trajectory, trajectory_from_json, trajectory_to_json
from assistant.placement import PoseFit, fit_pose
from assistant.progress import Cancelled, Progress
from assistant.robot_catalog import RobotSpec, ToolSpec, robot_data_dirs
from assistant.robot_link import LinkEvent, LinkEventKind, RobotLink
from assistant.robot_model import IKResult, Robot, UnreachableError
from assistant.session.document import Document
from assistant.session.events import (
    CollisionRecorded,
    ErrorRaised,
    EventBus,
    ExecutionFinished,
    Notice,
    PlanReady,
    ProgramReady,
    RobotMoved,
    SceneChanged,
    StateChanged,
)
from assistant.session.history import History
from assistant.session.store import (
    CELL_DIR,
    SESSION_JSON,
    SESSION_SCHEMA,
    SessionFileError,
    read_session_json,
    write_json_atomic,
)
from assistant.session.worker import Worker
from assistant.transforms import inv_T
from workflow.machine import Facts, Machine, Mode, TransitionRefused

Array = np.ndarray


class OccupiedCells(NamedTuple):
    """Occupied octree leaves for display: the octree is a lattice along the robot base's
    axes, so a turned base turns the lattice (`R_world_grid`: its axes in the world)."""

    centres: Array  # (N, 3) world frame
    p: Array  # (N,) occupancy probability
    leaf: float  # edge of a leaf (m)
    R_world_grid: Array  # (3, 3)


#: Steps in which each kind of edit is allowed (main state ids).
EDIT_CELL = ("cad", "place")
EDIT_PLACEMENT = ("place", "cad", "teach", "plan")
EDIT_MISSION = ("teach", "explore", "plan")
TEACH_STEPS = ("teach", "place", "explore", "plan")


class SessionError(ValueError):
    """An action that cannot be done as asked; the message says why and what to do."""


@dataclass
class Counters:
    operator_actions: int = 0
    collision_indications: int = 0
    replans: int = 0
    planning_time_s: float = 0.0
    replan_times_s: list[float] = field(default_factory=list)

    def to_json(self) -> dict:
        return {"operator_actions": self.operator_actions,
                "collision_indications": self.collision_indications, "replans": self.replans,
                "planning_time_s": self.planning_time_s, "replan_times_s": self.replan_times_s}

    @staticmethod
    def from_json(d: dict) -> Counters:
        return Counters(int(d.get("operator_actions", 0)), int(d.get("collision_indications", 0)),
                        int(d.get("replans", 0)), float(d.get("planning_time_s", 0.0)),
                        [float(v) for v in d.get("replan_times_s", [])])


@dataclass(frozen=True)
class HiddenObstacle:
    """An obstacle only the simulated robot knows (the thesis' O3): a primitive in the world
    frame, in the same JSON shape as a sample cell's ``hidden.json`` entries."""

    name: str
    kind: str  # box (size x, y, z) | cylinder (radius, height) | sphere (radius,)
    size: tuple[float, ...]
    T_world_object: Array

    def __post_init__(self) -> None:
        self.primitive()  # validates kind and size
        T = np.asarray(self.T_world_object, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"hidden obstacle {self.name!r}: pose must be a finite 4x4")

    def primitive(self) -> PrimitiveSpec:
        return PrimitiveSpec(PrimitiveKind(self.kind), tuple(float(v) for v in self.size))

    def to_json(self) -> dict:
        return {"name": self.name, "kind": self.kind, "size": list(self.size),
                "T_world_object": np.asarray(self.T_world_object).tolist()}

    @staticmethod
    def from_json(d: dict) -> HiddenObstacle:
        return HiddenObstacle(str(d["name"]), str(d.get("kind", "box")),
                              tuple(float(v) for v in d["size"]),
                              np.asarray(d.get("T_world_object", np.eye(4)), dtype=float))


class Session:
    """Everything the operator does, headless or behind the web page."""

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
        self.trajectory: Trajectory | None = None
        self.plan_report: dict[str, Any] | None = None
        self.program: Any = None
        self.recorded_collisions: list[Array] = []
        self._lock = threading.RLock()
        self._link: RobotLink | None = None
        self._q_sim: Array | None = None  # joints of the robot when no link is connected
        self._world: Any = None  # planning back end (world model + roadmap), built on demand
        self._world_key: tuple | None = None
        self._last_error: str = ""
        self._pointer: Any = None  # LivePointer while the camera step is open
        self.pending_point: Any = None  # the last dwell TaughtPoint, waiting for a name
        self.sample: str | None = None  # the sample cell this session started from

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
        r = self.robot
        q = np.clip(np.zeros(r.dof), r.limits.lower, r.limits.upper)
        return q

    def T_world_base(self) -> Array:
        return np.asarray(self.cell.T_world_base, dtype=float)

    def tcp_world(self, q: Array | None = None) -> Array:
        q = self.current_joints() if q is None else q
        return self.T_world_base() @ self.robot.fk(q)

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

    def _obstacles_key(self) -> tuple:
        return (self.document().obstacles_key(), self.cell.robot_spec)

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

    # ================================================================== 1. set-up
    def choose_robot(self, spec: RobotSpec) -> Robot:
        """Pick the robot (built-in RV-2AJ or a URDF) and its tool."""
        with self._action("choose the robot", ("setup",), scene="robot"):
            robot = spec.build()  # errors (missing URDF, bad mesh) before anything changes
            self.cell.robot_spec = spec
            self._q_sim = None
            self._drop_link()
            self._world = None
        return robot

    def set_tool(self, tool: ToolSpec) -> Robot:
        from dataclasses import replace

        return self.choose_robot(replace(self.cell.robot_spec, tool=tool))

    def set_link(self, settings: LinkSettings) -> None:
        """Choose how the assistant talks to the robot (simulated, MELFA, KUKA REST)."""
        with self._action("choose the robot link", ("setup",), undoable=False, scene="link"):
            self._drop_link()
            self.link_settings = settings

    def set_hidden_obstacles(self, hidden: list[HiddenObstacle]) -> None:
        """Obstacles only the simulated robot knows (they stand in for reality)."""
        with self._action("set the simulated world", None, undoable=False, scene="hidden"):
            self.hidden = list(hidden)
            self._drop_link()

    def link(self) -> RobotLink:
        """The connected link, connecting on first use."""
        with self._lock:
            if self._link is None:
                hidden = [Obstacle(h.name, inv_T(self.T_world_base()) @ h.T_world_object,
                                   (h.primitive().collision_shape(),)) for h in self.hidden]
                link = make_link(self.link_settings, self.robot, hidden)
                if self._q_sim is not None and hasattr(link, "set_joints"):
                    link.set_joints(self._q_sim)  # type: ignore[attr-defined]
                link.subscribe(self._on_link_event)
                self._link = link
            if not self._link.connected:
                self._link.connect()
            return self._link

    def _drop_link(self) -> None:
        if self._link is not None:
            with contextlib.suppress(Exception):
                self._q_sim = np.asarray(self._link.current_joints(), dtype=float)
            with contextlib.suppress(Exception):
                self._link.close()
            self._link = None

    def _on_link_event(self, ev: LinkEvent) -> None:
        if ev.q is not None:
            self._q_sim = np.asarray(ev.q, dtype=float)
            self.bus.emit(RobotMoved(self._q_sim.copy()))
        if ev.kind == LinkEventKind.COLLISION_INDICATED and ev.q is not None:
            # The executor/explorer feeds the world model; the session keeps the posture so a
            # reloaded session knows it too.
            with self._lock:
                self.recorded_collisions.append(np.asarray(ev.q, float).copy())
                self.counters.collision_indications += 1
            self.bus.emit(CollisionRecorded(np.asarray(ev.q, float).copy(),
                                            self.counters.collision_indications,
                                            "operator" if "operator" in ev.message else "robot"))
        if ev.kind == LinkEventKind.LINK_LOST:
            self.machine.enter_error(f"robot link lost: {ev.message}")
            self._error(f"robot link lost: {ev.message}",
                        "Check the cable/network, then press Reconnect; the plan is kept.")
            self._emit_state()

    def reconnect_link(self) -> None:
        with self._lock:
            link = self._link
        if link is None:
            self.link()
        else:
            link.connect()
        with self._lock:
            self.machine.clear_error()
        self._emit_state()

    def acknowledge_error(self) -> None:
        with self._lock:
            self.machine.clear_error()
        self._emit_state()

    # ================================================================== 2. CAD
    def import_cad(self, data: bytes, filename: str, *, name: str | None = None,
                   units: str | None = None, dxf_extrude_height: float | None = None,
                   role: ObjectRole | str = ObjectRole.OBSTACLE,
                   T_world_object: Array | None = None) -> tuple[CellObject, CadImport]:
        """Import a CAD file (bytes as uploaded); the part lands at the world origin or at T."""
        with self._action(f"import {filename}", EDIT_CELL, scene="objects"):
            cad = load_cad(data, filename, units=units, dxf_extrude_height=dxf_extrude_height)
            base = name or Path(filename).stem
            obj_name = self.cell.unique_name(_safe_name(base)) if name is None else name
            obj = CellObject.from_cad(obj_name, cad, T_world_object, role=role)
            self.cell.add_object(obj)
            for w in cad.warnings:
                self.bus.emit(Notice(f"{filename}: {w}"))
        return obj, cad

    def import_cad_path(self, path: str | Path, **kw: Any) -> tuple[CellObject, CadImport]:
        p = Path(path)
        try:
            data = p.read_bytes()
        except OSError as exc:
            raise SessionError(f"cannot read {p}: {exc.strerror}") from None
        return self.import_cad(data, p.name, **kw)

    def add_primitive(self, kind: str, size: tuple[float, ...], *, name: str | None = None,
                      role: ObjectRole | str = ObjectRole.OBSTACLE,
                      T_world_object: Array | None = None) -> CellObject:
        """A box (x, y, z), cylinder (radius, height) or sphere (radius,), metres."""
        with self._action(f"add a {kind}", EDIT_CELL, scene="objects"):
            spec = PrimitiveSpec(PrimitiveKind(kind), tuple(float(v) for v in size))
            obj = CellObject.from_primitive(name or self.cell.unique_name(kind), spec,
                                            T_world_object, role=role)
            self.cell.add_object(obj)
        return obj

    def remove_object(self, name: str) -> None:
        with self._action(f"remove {name}", EDIT_CELL + ("teach", "plan"), scene="objects"):
            self.cell.remove_object(name)

    def set_object_role(self, name: str, role: ObjectRole | str) -> None:
        from dataclasses import replace

        with self._action(f"change the role of {name}", EDIT_CELL, scene="objects"):
            obj = self.cell.get_object(name)
            role = ObjectRole(role)
            self.cell.objects[name] = replace(obj, role=role, color=None)

    # ================================================================== 3. placement
    def place_object(self, name: str, T_world_object: Array) -> CellObject:
        with self._action(f"place {name}", EDIT_PLACEMENT, scene="objects"):
            obj = self.cell.set_object_pose(name, np.asarray(T_world_object, dtype=float))
        return obj

    def fit_object_pose(self, name: str, model_points: Array, measured_points: Array) -> PoseFit:
        """N-point placement: model points (object frame) vs the same points measured."""
        with self._action(f"place {name} by points", EDIT_PLACEMENT, scene="objects"):
            self.cell.get_object(name)
            fit = fit_pose(np.asarray(model_points, float), np.asarray(measured_points, float))
            self.cell.set_object_pose(name, fit.T_world_object)
            for w in fit.warnings:
                self.bus.emit(Notice(w))
        return fit

    def measure_with_robot(self) -> Array:
        """The robot TCP position (world frame) - touch a point of the part with the tool."""
        return self.tcp_world()[:3, 3].copy()

    def calibrate_frame(self, name: str, origin: Array | str, x_point: Array | str,
                        xy_point: Array | str) -> FrameCalibration:
        """A named frame from three measured points (the controllers' 3-point base method):
        its origin, a point on its +x axis and a point in its XY plane on the +y side. Each
        point is a position (world, metres) or the name of a taught location (e.g. the tip
        of the tool touched to the pallet and taught from the robot pose). Re-calibrating an
        existing frame replaces it."""
        with self._action(f"calibrate the frame {name}", EDIT_PLACEMENT, scene="frames"):
            pts = [self._point_of(p) for p in (origin, x_point, xy_point)]
            cal = frame_from_three_points(name, *pts)
            self.cell.add_frame(name, cal.T_world_frame, replace_existing=True)
            self.bus.emit(Notice(cal.describe()))
        return cal

    def place_object_in_frame(self, name: str, frame: str, T_frame_object: Array) -> CellObject:
        """Place an object relative to a named (e.g. calibrated) frame."""
        with self._action(f"place {name} on {frame}", EDIT_PLACEMENT, scene="objects"):
            T_world_frame = self._frame(frame)
            obj = self.cell.set_object_pose(name, T_world_frame @ np.asarray(T_frame_object,
                                                                             dtype=float))
        return obj

    def _point_of(self, p: Array | str) -> Array:
        if isinstance(p, str):
            return self._loc(p).position.copy()
        a = np.asarray(p, dtype=float)
        if a.shape != (3,) or not np.all(np.isfinite(a)):
            raise SessionError("a measured point needs 3 finite coordinates")
        return a

    def _frame(self, name: str) -> Array:
        if name not in self.cell.frames:
            known = ", ".join(self.cell.frames) or "none yet"
            raise SessionError(f"no frame named {name!r} (frames: {known}); calibrate it first")
        return np.asarray(self.cell.frames[name], dtype=float)

    # ================================================================== 4. teach
    def teach(self, name: str, T_world_tool: Array, *,
              source: LocationSource = LocationSource.TYPED, q_hint: Array | None = None,
              uncertainty_m: float = 0.0, replace_existing: bool = True) -> Location:
        """Store a location. Out-of-reach poses are refused; a 5-axis robot's orientation is
        projected into its arm plane (the operator is told by how much)."""
        with self._action(f"teach {name}", TEACH_STEPS, scene="locations"):
            loc = self._make_location(name, np.asarray(T_world_tool, float), source, q_hint,
                                      uncertainty_m)
            if name in self.locations and not replace_existing:
                raise SessionError(f"a location named {name!r} exists already")
            self.locations[name] = loc
            self._relink_mission(name)
        return self.locations[name]

    def _make_location(self, name: str, T_world_tool: Array, source: LocationSource,
                       q_hint: Array | None, uncertainty_m: float) -> Location:
        _check_identifier(name, "location")
        T_base_world = inv_T(self.T_world_base())
        T_base = T_base_world @ T_world_tool
        seed = q_hint if q_hint is not None else self.current_joints()
        res: IKResult = self.robot.ik(T_base, seed=seed)
        if not res.ok and res.nearest_T_base_tool is not None and \
                res.failure is not None and res.failure.value == "orientation":
            near = res.nearest_T_base_tool
            res2 = self.robot.ik(near, seed=seed)
            if res2.ok:
                ang = np.degrees(_angle(near[:3, :3], T_base[:3, :3]))
                self.bus.emit(Notice(f"{name}: {res.message}; the orientation was turned by "
                                     f"{ang:.1f} deg into the arm plane"))
                T_base, res = near, res2
        if not res.ok:
            raise UnreachableError(f"{name}: {res.message}", res)
        q = res.best(seed)
        return Location(name, self.T_world_base() @ T_base, source, q, uncertainty_m)

    def teach_from_robot(self, name: str) -> Location:
        q = self.current_joints()
        return self.teach(name, self.tcp_world(q), source=LocationSource.ROBOT_POSE, q_hint=q)

    def teach_from_cad_click(self, name: str, point_world: Array,
                             normal_world: Array | None = None,
                             approach_distance: float = 0.0) -> Location:
        """A point clicked on a part: the tool points against the surface normal (or down)."""
        p = np.asarray(point_world, float)
        n = np.array([0.0, 0.0, 1.0]) if normal_world is None else np.asarray(normal_world, float)
        n = n / np.linalg.norm(n)
        T = np.eye(4)
        T[:3, :3] = _tool_frame_along(-n)
        T[:3, 3] = p + approach_distance * n
        return self.teach(name, T, source=LocationSource.CAD_CLICK)

    def teach_from_pointer(self, name: str, point_world: Array, uncertainty_m: float = 0.0,
                           R_world_tool: Array | None = None) -> Location:
        """A point measured by the marker pointer (dwell); tool down unless told otherwise."""
        T = np.eye(4)
        T[:3, :3] = _tool_frame_along(np.array([0.0, 0.0, -1.0])) if R_world_tool is None \
            else np.asarray(R_world_tool, float)
        T[:3, 3] = np.asarray(point_world, float)
        return self.teach(name, T, source=LocationSource.POINTER, uncertainty_m=uncertainty_m)

    def teach_by_pointer_dwell(self, name: str, point_world: Array, *, seed: int = 0) -> Location:
        """Synthetic camera: the pointer is brought to `point_world` and held still; the point
        the vision pipeline measures (with its error) is taught. Deterministic for a seed, so
        the web page and a script teaching the same point get the same location."""
        tp = self.simulate_pointer_dwell(point_world, seed=seed)
        return self.teach_from_pointer(name, np.asarray(tp.position_world),
                                       uncertainty_m=float(tp.uncertainty))

    def simulate_pointer_dwell(self, point_world: Array, *, seed: int = 0) -> Any:
        """Scripted sessions: the synthetic pointer moves to `point_world` and holds still; the
        real vision pipeline measures it. Returns the taught point (measured, not the truth)."""
        from vision.scripted import simulate_dwell

        return simulate_dwell(self.camera_models(), np.asarray(point_world, float), seed=seed)

    # -- live pointer (UI) ------------------------------------------------------------------
    def start_pointer(self) -> None:
        """Run the pointer pipeline in the background (synthetic cameras by default)."""
        from assistant.session.pointer_live import LivePointer
        from vision.color import ColorProfile

        with self._lock:
            if self._pointer is not None and self._pointer.running:
                return
            self._pointer = LivePointer(self.camera_models(), on_state=self._on_pointer,
                                        seed=int(self.pointer_config.get("seed", 0)))
            prof = self.pointer_config.get("profile")
            if prof:
                self._pointer.system.profile = ColorProfile.from_dict(prof)
            self._pointer.start()

    def stop_pointer(self) -> None:
        with self._lock:
            p, self._pointer = self._pointer, None
        if p is not None:
            p.stop()

    def pointer_move_to(self, point_world: Array | None) -> None:
        """Synthetic camera only: the simulated hand brings the ball to a point (None: away)."""
        if self._pointer is None:
            self.start_pointer()
        assert self._pointer is not None
        self._pointer.hand.move_to(None if point_world is None else np.asarray(point_world, float))

    def _on_pointer(self, state: Any) -> None:
        from assistant.session.events import PointerUpdated

        pos = None if state.position_world is None else np.asarray(state.position_world)
        std = float(np.sqrt(np.trace(state.covariance))) if pos is not None else 0.0
        self.bus.emit(PointerUpdated(pos, std, state.mode))
        if state.taught is not None:
            self.pending_point = state.taught
            p = np.asarray(state.taught.position_world) * 1000
            self.bus.emit(Notice(f"pointer held still: point measured at "
                                 f"({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm "
                                 f"+- {state.taught.uncertainty * 1000:.1f} mm"))

    def pointer_state(self) -> Any:
        """The last `vision.PointerState` of the live pointer (None when it is not running):
        camera views with frames and detections for the UI."""
        p = self._pointer
        return None if p is None else p.last_state

    def teach_pending_point(self, name: str) -> Location:
        """Teach the last point the pointer dwell produced."""
        tp = self.pending_point
        if tp is None:
            raise SessionError("no pointer point yet: hold the pointer still at the spot")
        loc = self.teach_from_pointer(name, np.asarray(tp.position_world),
                                      uncertainty_m=float(tp.uncertainty))
        self.pending_point = None
        return loc

    def calibrate_pointer_color(self, camera_index: int, center_px: tuple[float, float],
                                axes_px: tuple[float, float], angle_deg: float = 0.0) -> Any:
        """Colour calibration: the ellipse the operator drew over the ball in a live view."""
        from vision.color import calibrate_from_ellipse

        with self._action("calibrate the pointer colour", None, undoable=False):
            if self._pointer is None or self._pointer.last_state is None:
                raise SessionError("start the cameras first (the live view needs a frame)")
            views = list(self._pointer.last_state.cameras.values())
            if not 0 <= camera_index < len(views) or views[camera_index].frame is None:
                raise SessionError(f"no live frame from camera {camera_index}")
            frame = views[camera_index].frame
            prof = calibrate_from_ellipse(frame.image, center_px, axes_px, angle_deg)
            self._pointer.system.profile = prof
            self.pointer_config["profile"] = prof.to_dict()
        return prof

    def camera_models(self) -> list:
        from vision.camera_model import CameraModel
        from vision.rigs import default_stereo_rig

        cams = self.pointer_config.get("cameras")
        if cams:
            return [CameraModel.from_dict(c) for c in cams]
        return default_stereo_rig()

    def remove_location(self, name: str) -> None:
        with self._action(f"delete {name}", TEACH_STEPS, scene="locations"):
            if name not in self.locations:
                raise SessionError(f"no location named {name!r}")
            used = self._location_uses(name)
            if used:
                raise SessionError(f"{name} is used by {', '.join(used)}; change that first")
            del self.locations[name]

    def _location_uses(self, name: str) -> list[str]:
        uses = []
        m = self.mission
        if m.start is not None and m.start.name == name:
            uses.append("the mission start")
        if m.goal is not None and m.goal.name == name:
            uses.append("the mission goal")
        return uses

    def _relink_mission(self, name: str) -> None:
        """A re-taught location updates the mission's start/goal that refer to it."""
        from dataclasses import replace

        loc = self.locations[name]
        if self.mission.start is not None and self.mission.start.name == name:
            self.mission = replace(self.mission, start=loc)
        if self.mission.goal is not None and self.mission.goal.name == name:
            self.mission = replace(self.mission, goal=loc)

    def set_start(self, name: str) -> None:
        from dataclasses import replace

        with self._action("set the mission start", EDIT_MISSION, scene="mission"):
            self.mission = replace(self.mission, start=self._loc(name), order=None)

    def set_goal(self, name: str) -> None:
        from dataclasses import replace

        with self._action("set the mission goal", EDIT_MISSION, scene="mission"):
            self.mission = replace(self.mission, goal=self._loc(name), order=None)

    def _loc(self, name: str) -> Location:
        if name not in self.locations:
            known = ", ".join(self.locations) or "none yet"
            raise SessionError(f"no location named {name!r} (taught: {known})")
        return self.locations[name]

    def add_path(self, name: str, kind: str, points: list[str | Array], *,
                 before: list[ToolAction] = (), after: list[ToolAction] = (),
                 speed: float = 0.05, reversible: bool = False,
                 R_world_tool: Array | None = None) -> ApplicationPath:
        """An application path: a line (2 points), arc (3) or Bezier chain (1 + 3k control
        points) through taught locations (by name) or points; the tool orientation is that of
        the first named location unless given."""
        from dataclasses import replace

        with self._action(f"add the path {name}", EDIT_MISSION, scene="mission"):
            _check_identifier(name, "path")
            if any(p.name == name for p in self.mission.paths):
                raise SessionError(f"a path named {name!r} exists already")
            pts, R = self._path_points(points)
            segs = _segments(SegmentKind(kind), pts)
            R_tool = np.asarray(R_world_tool, float) if R_world_tool is not None else (
                R if R is not None else _tool_frame_along(np.array([0.0, 0.0, -1.0])))
            path = ApplicationPath(name, segs, R_tool, list(before), list(after), float(speed),
                                   bool(reversible))
            self.mission = replace(self.mission, paths=[*self.mission.paths, path], order=None)
        return path

    def _path_points(self, points: list[str | Array]) -> tuple[list[Array], Array | None]:
        out: list[Array] = []
        R: Array | None = None
        for p in points:
            if isinstance(p, str):
                loc = self._loc(p)
                out.append(loc.position.copy())
                if R is None:
                    R = loc.T_world_tool[:3, :3]
            else:
                out.append(np.asarray(p, float))
        return out, R

    def remove_path(self, name: str) -> None:
        from dataclasses import replace

        with self._action(f"delete the path {name}", EDIT_MISSION, scene="mission"):
            paths = [p for p in self.mission.paths if p.name != name]
            if len(paths) == len(self.mission.paths):
                raise SessionError(f"no path named {name!r}")
            self.mission = replace(self.mission, paths=paths, order=None)

    def move_path(self, name: str, index: int) -> None:
        """Reorder the mission's paths (the operator's order; the planner may reorder)."""
        from dataclasses import replace

        with self._action(f"move the path {name}", EDIT_MISSION, scene="mission"):
            paths = list(self.mission.paths)
            i = next((k for k, p in enumerate(paths) if p.name == name), None)
            if i is None:
                raise SessionError(f"no path named {name!r}")
            p = paths.pop(i)
            paths.insert(max(0, min(index, len(paths))), p)
            self.mission = replace(self.mission, paths=paths, order=None)

    def add_drawing(self, name: str, frame: str, drawing: int | Array, *,
                    at: tuple[float, float] = (0.0, 0.0), angle: float = 0.0,
                    lift: float = 0.03, before: list[ToolAction] = (),
                    after: list[ToolAction] = (), speed: float = 0.05,
                    reversible: bool = False, tool_angle: float = 0.0) -> ApplicationPath:
        """A pen drawing on a frame's XY plane as one application path: a line down to the
        paper (`lift` metres along the frame's -z), the chained cubic Bezier segments, a line
        back up; the pen stays perpendicular to the paper (tool z = -frame z).

        Args:
            name: the path's name (a controller identifier).
            frame: a named frame, e.g. the pallet calibrated from three points.
            drawing: one of the cell's drawings 1..9 (source 000: frames 1-3, keyboards 4-6,
                screens 7-9) or control points (1 + 3k, metres, 2-D in the frame).
            at: where the drawing's origin goes on the frame's XY plane (metres).
            angle: rotation of the drawing about the frame's z axis (rad).
            lift: approach and retreat height above the paper (m, > 0).
            tool_angle: the pen's turn about its own axis (rad; 0: tool x along the
                drawing's x). A pen draws the same either way; the wrist may not (e.g. a
                6-axis arm's last joint near its limit).
        """
        from dataclasses import replace

        with self._action(f"add the drawing {name}", EDIT_MISSION, scene="mission"):
            _check_identifier(name, "path")
            if any(p.name == name for p in self.mission.paths):
                raise SessionError(f"a path named {name!r} exists already")
            path = drawing_path(name, self._frame(frame), _drawing_control(drawing),
                                at=at, angle=angle, lift=lift, before=before, after=after,
                                speed=speed, reversible=reversible, tool_angle=tool_angle)
            self.mission = replace(self.mission, paths=[*self.mission.paths, path], order=None)
        return path

    def set_path_actions(self, name: str, before: list[ToolAction],
                         after: list[ToolAction]) -> None:
        from dataclasses import replace

        with self._action(f"change the tool actions of {name}", EDIT_MISSION, scene="mission"):
            paths = []
            found = False
            for p in self.mission.paths:
                if p.name == name:
                    p = replace(p, actions_before=list(before), actions_after=list(after))
                    found = True
                paths.append(p)
            if not found:
                raise SessionError(f"no path named {name!r}")
            self.mission = replace(self.mission, paths=paths)

    # ================================================================== robot motion (jog)
    def jog_joints(self, q: Array, *, wait: bool = True) -> Future:
        """Move the robot to joint values (checked against limits and known obstacles)."""
        q = np.asarray(q, dtype=float)
        r = self.robot
        if q.shape != (r.dof,):
            raise SessionError(f"{r.name} has {r.dof} joints, got {q.shape[0]} values")
        viol = r.limits.violations(q, r.joint_names)
        if viol:
            raise SessionError("joint limit: " + "; ".join(viol))
        checker = self._known_checker()
        q0 = self.current_joints()
        mc = checker.check_motion(q0, q)
        if not mc.valid:
            raise SessionError(f"that move would collide: {mc.report.describe()}"
                               if mc.report else "that move would collide")
        fut = self._run_motion("jog", lambda p: self.link().move_path(np.array([q0, q])))
        if wait:
            fut.result()
        return fut

    def jog_tcp(self, T_world_tool: Array, *, wait: bool = True) -> Future:
        """Move the TCP to a pose by IK (5-axis: the orientation is projected, and said so)."""
        T_base = inv_T(self.T_world_base()) @ np.asarray(T_world_tool, float)
        res = self.robot.ik(T_base, seed=self.current_joints())
        if not res.ok and res.nearest_T_base_tool is not None:
            self.bus.emit(Notice(res.message))
            res = self.robot.ik(res.nearest_T_base_tool, seed=self.current_joints())
        if not res.ok:
            raise UnreachableError(res.message, res)
        return self.jog_joints(res.best(self.current_joints()), wait=wait)

    def _run_motion(self, task: str, fn: Callable[[Progress], Any]) -> Future:
        with self._lock:
            self.machine.begin_moving()
        self._emit_state()

        def done(fut: Future) -> None:
            with self._lock:
                self.machine.end_mode()
                exc = fut.exception()
                if exc is not None and not isinstance(exc, Cancelled):
                    self._error(f"{task}: {exc}", hint_for(exc))
                self._autosave()
            self._emit_state()

        return self.worker.submit(task, fn, done)

    def _known_checker(self) -> CollisionChecker:
        return CollisionChecker(self.robot, self.cell.collision_objects_in_base())

    def stop(self) -> None:
        """Stop the robot now (from any thread)."""
        link = self._link
        if link is not None:
            link.stop()
        self.worker.cancel()

    def indicate_collision(self) -> None:
        """The operator's Collision! button: stop and record the posture as an obstacle."""
        link = self._link
        if link is not None and self.machine.mode == Mode.MOVING:
            link.indicate_collision()
            return
        # Not moving: record the current posture directly (e.g. after a manual jog).
        q = self.current_joints()
        self._record_collision(q, "operator")

    def _record_collision(self, q: Array, source: str) -> None:
        with self._lock:
            self.recorded_collisions.append(np.asarray(q, float).copy())
            self.counters.collision_indications += 1
            if self._world is not None:
                self._world.add_collision(q)
            self._autosave()
        self.bus.emit(CollisionRecorded(np.asarray(q, float).copy(),
                                        self.counters.collision_indications, source))

    def close(self) -> None:
        """Stop the robot and background work, close the link and the cameras."""
        self.stop()
        self.worker.join(5.0)
        self.stop_pointer()
        with self._lock:
            self._drop_link()

    def cancel(self) -> None:
        self.worker.cancel()
        link = self._link
        if link is not None and self.machine.mode == Mode.MOVING:
            link.stop()

    # ================================================================== 5. explore / world
    def _run_busy(self, task: str, fn: Callable[[Progress], Any],
                  steps: tuple[str, ...] | None = None, *, moving: bool = False) -> Future:
        """Run long work on the worker: the machine is busy (or moving) until it ends."""
        with self._lock:
            if steps is not None:
                self.machine.require(steps, task)
            if moving:
                self.machine.begin_moving()
            else:
                self.machine.begin_busy(task)
        self._emit_state()

        def done(fut: Future) -> None:
            with self._lock:
                self.machine.end_mode()
                exc = fut.exception()
                if exc is not None and not isinstance(exc, Cancelled):
                    self._error(f"{task}: {exc}", hint_for(exc))
                elif isinstance(exc, Cancelled):
                    self.bus.emit(Notice(f"{task} cancelled; nothing was lost"))
                self._autosave()
            self._emit_state()

        try:
            return self.worker.submit(task, fn, done)
        except RuntimeError:
            with self._lock:
                self.machine.end_mode()
            self._emit_state()
            raise

    def start_build_world(self) -> Future:
        """Reachability table (cached on disk), CAD rasterisation and the Voronoi roadmap."""
        return self._run_busy("build the world model", self._build_world,
                              ("explore", "plan", "teach", "place"))

    def build_world(self) -> dict:
        return self.start_build_world().result()

    def _build_world(self, progress: Progress) -> dict:
        from assistant.roadmap.planner import RoadmapPlanner
        from assistant.world.model import WorldConfig, WorldModel

        t0 = time.perf_counter()
        robot = self.robot
        obstacles = self.cell.collision_objects_in_base()
        key = self._obstacles_key()
        world = WorldModel(robot, obstacles, WorldConfig())
        checker = CollisionChecker(robot, obstacles)
        roadmap = RoadmapPlanner(robot, checker, world)
        report = roadmap.build(progress.sub(0.0, 0.9))
        for q in self.recorded_collisions:  # what the operator taught us stays known
            progress.check()
            roadmap.add_collision(q)
        backend = _Backend(world, roadmap, checker)
        with self._lock:
            self._world, self._world_key = backend, key
        self.bus.emit(SceneChanged("world"))
        return {"seconds": time.perf_counter() - t0,
                "table_from_cache": report.world.table_from_cache,
                "road_cells": report.road_cells, "regions": report.regions,
                "free_cells": report.world.leaves_free}

    def _backend(self, progress: Progress | None = None) -> _Backend:
        """The world model for the current obstacles, (re)built if stale."""
        if not self.world_ready:
            self._build_world(progress or Progress())
        assert self._world is not None
        return self._world

    def _mission_planner(self, backend: _Backend) -> Any:
        from assistant.planning import MissionPlanner

        config = self._planner_config()
        if backend.planner is None or backend.planner.config != config:
            backend.planner = MissionPlanner(self.robot, self.cell.collision_objects_in_base(),
                                             backend.world, backend.roadmap, backend.checker,
                                             config)
        return backend.planner

    def _planner_config(self) -> Any:
        """The planner's defaults; Bezier chains become SPLINE moves when the export dialect
        writes splines (KRL SPLINE ... ENDSPLINE), else linear moves within the tolerance."""
        from dataclasses import replace

        from assistant.export import get_dialect
        from assistant.planning.config import MissionPlannerConfig
        from assistant.trajectory.application import BezierMode

        config = MissionPlannerConfig()
        try:
            splines = bool(getattr(get_dialect(self.export_dialect), "spline", False))
        except (KeyError, ValueError):
            splines = False
        if splines:
            config = replace(config, application=replace(config.application,
                                                         bezier_mode=BezierMode.SPLINE))
        return config

    # ================================================================== 6. plan & execute
    def start_plan(self) -> Future:
        """Plan the mission in the known world (CAD + recorded collisions)."""
        return self._run_busy("plan the mission", self._plan, ("plan", "explore", "export"))

    def plan(self) -> dict:
        return self.start_plan().result()

    def _plan(self, progress: Progress) -> dict:
        t0 = time.perf_counter()
        backend = self._backend(progress.sub(0.0, 0.3, "world model"))
        planner = self._mission_planner(backend)
        plan = planner.plan_mission(self.mission, self.T_world_base(), self.current_joints(),
                                    progress.sub(0.3, 1.0, "plan"))
        with self._lock:
            self.counters.planning_time_s += time.perf_counter() - t0
            if not plan.ok:
                self.trajectory, self.plan_report, self.program = None, None, None
                raise SessionError(f"no plan: {plan.reason}")
            self.trajectory = plan.trajectory
            self.plan_report = _report_json(plan.report)
            self.program = None
        self.bus.emit(PlanReady(dict(self.plan_report)))
        return dict(self.plan_report)

    def start_execute(self) -> Future:
        """Drive the mission on the robot; collisions (button or hidden obstacle) are learnt,
        the plan repaired and resumed. Ends with a verified final plan ready to export."""
        return self._run_busy("execute the mission", self._execute, ("plan",), moving=True)

    def execute(self) -> dict:
        return self.start_execute().result()

    def resume_execution(self) -> Future:
        """Continue after a lost link or a stop, re-planning from where the robot is."""
        return self._run_busy("resume the mission", self._resume, ("plan",), moving=True)

    def _executor(self, backend: _Backend, link: RobotLink) -> Any:
        from assistant.planning import MissionExecutor

        ex = backend.executor
        if ex is None or ex.link is not link:
            if ex is not None:
                ex.detach()
            ex = MissionExecutor(self._mission_planner(backend), link)
            backend.executor = ex
        return ex

    def _execute(self, progress: Progress) -> dict:
        backend = self._backend(progress.sub(0.0, 0.1, "world model"))
        link = self.link()
        ex = self._executor(backend, link)
        t0 = time.perf_counter()
        report = ex.run(self.mission, self.T_world_base(), progress.sub(0.1, 1.0, "execute"))
        return self._after_execution(report, time.perf_counter() - t0)

    def _resume(self, progress: Progress) -> dict:
        backend = self._backend(progress.sub(0.0, 0.1, "world model"))
        ex = self._executor(backend, self.link())
        t0 = time.perf_counter()
        report = ex.resume(progress.sub(0.1, 1.0, "resume"))
        return self._after_execution(report, time.perf_counter() - t0)

    def _after_execution(self, report: Any, seconds: float) -> dict:
        with self._lock:
            self.counters.replans += report.replans
            self.counters.replan_times_s += list(report.replan_seconds)
            self.counters.planning_time_s += sum(report.replan_seconds)
            final = report.final_plan
            if report.ok and final is not None and final.ok:
                self.trajectory = final.trajectory
                self.plan_report = _report_json(final.report)
                self.program = None
        summary = {"ok": report.ok, "end": report.end.value if report.end else None,
                   "reason": report.reason, "collision_indications":
                   report.collision_indications, "replans": report.replans,
                   "backoffs": report.backoffs, "executed_tcp_length_m":
                   report.executed_tcp_length, "median_replan_s": report.median_replan_seconds,
                   "seconds": seconds, "resumable": report.resumable}
        self.bus.emit(ExecutionFinished(report.ok, dict(summary), report.resumable))
        if report.ok and self.plan_report is not None:
            self.bus.emit(PlanReady(dict(self.plan_report)))
        elif not report.ok:
            raise SessionError(f"execution ended: {report.reason}" + (
                " - press Resume to continue" if report.resumable else ""))
        return summary

    def start_explore(self, mode: str = "random", moves: int = 5, *, seed: int = 0) -> Future:
        """Explore the workspace with the robot: random moves, replay the plan, or the roads."""
        if mode not in ("random", "replay", "roads"):
            raise SessionError(f"unknown exploration mode {mode!r} (random, replay, roads)")
        return self._run_busy(f"explore ({mode})",
                              lambda p: self._explore(p, mode, moves, seed),
                              ("explore", "plan"), moving=True)

    def explore(self, mode: str = "random", moves: int = 5, *, seed: int = 0) -> dict:
        return self.start_explore(mode, moves, seed=seed).result()

    def _explore(self, progress: Progress, mode: str, moves: int, seed: int) -> dict:
        from assistant.planning import Explorer

        backend = self._backend(progress.sub(0.0, 0.2, "world model"))
        link = self.link()
        if backend.explorer is None or backend.explorer.link is not link:
            if backend.explorer is not None:
                backend.explorer.detach()
            backend.explorer = Explorer(self._mission_planner(backend), link)
        ex = backend.explorer
        sub = progress.sub(0.2, 1.0, "explore")
        if mode == "random":
            rep = ex.random_moves(moves, seed=seed, progress=sub)
        elif mode == "roads":
            rep = ex.follow_roads(max_targets=moves, progress=sub)
        else:
            if self.trajectory is None:
                raise SessionError("nothing to replay: plan the mission first")
            rep = ex.replay(self.trajectory, progress=sub)
        return {"ok": rep.ok, "description": rep.describe()}

    def order_mission(self) -> list[str]:
        """Order the application paths (shortest transfers) - shown, and used by Plan."""
        from dataclasses import replace

        from assistant.trajectory.ordering import order_mission

        with self._action("order the mission", EDIT_MISSION, scene="mission"):
            if self.mission.start is None or self.mission.goal is None:
                raise SessionError("The mission needs a start and a goal")
            ordering = order_mission(self.mission)
            self.mission = replace(self.mission, order=list(ordering.order))
        return [self.mission.paths[i].name for i in ordering.order]

    def occupancy_cells(self, min_p: float = 0.05) -> OccupiedCells | None:
        """Octree leaves with occupancy >= min_p, in the world frame."""
        b = self._world
        if b is None:
            return None
        occ = np.asarray(b.world.occupancy())
        ijk = np.argwhere(occ >= min_p)
        grid = b.world.grid
        centres = grid.centres_of_ijk(ijk)
        T = self.T_world_base()
        return OccupiedCells(centres @ T[:3, :3].T + T[:3, 3], occ[tuple(ijk.T)].astype(float),
                             float(grid.leaf), T[:3, :3].copy())

    def road_cells(self) -> tuple[Array, float] | None:
        """Centres (world frame) of the Voronoi road cells and the leaf size."""
        b = self._world
        if b is None or b.roadmap.voronoi is None:
            return None
        ijk = np.argwhere(b.roadmap.voronoi.roads())
        grid = b.world.grid
        T = self.T_world_base()
        return grid.centres_of_ijk(ijk) @ T[:3, :3].T + T[:3, 3], float(grid.leaf)

    # ================================================================== scene for the UI
    def scene_objects(self) -> list[CellObject]:
        """Placed objects (display mesh in object frame, `T_world_object`, colour, role)."""
        return list(self.cell.objects.values())

    def robot_visuals(self) -> list[tuple[str, Any, tuple[int, int, int]]]:
        """(link name, trimesh in link frame, colour) for every robot link with a visual."""
        return [(lk.name, lk.visual, lk.color) for lk in self.robot.links if lk.visual is not None]

    def link_poses_world(self, q: Array | None = None) -> Array:
        """T_world_link for every robot link at q (default: where the robot is now)."""
        q = self.current_joints() if q is None else np.asarray(q, float)
        return self.T_world_base()[None] @ self.robot.link_poses(q)

    def path_polylines(self, tol: float = 0.0005) -> list[tuple[str, Array]]:
        """Each application path as points (world frame) for drawing."""
        from assistant.export.bezier import CubicBezier, sample_bezier_chain

        out = []
        for p in self.mission.paths:
            pts: list[Array] = []
            for seg in p.segments:
                if seg.kind == SegmentKind.LINE:
                    pts += [seg.start, seg.end]
                elif seg.kind == SegmentKind.ARC:
                    pts += list(_arc_points(*seg.points))
                else:
                    samp = sample_bezier_chain([CubicBezier(*seg.points)], tol)
                    pts += list(samp.points)
            out.append((p.name, np.array(pts)))
        return out

    def plan_polylines(self) -> list[tuple[str, Array]]:
        """The planned trajectory per motion: (kind, TCP points in the world frame)."""
        if self.trajectory is None:
            return []
        T_wb = self.T_world_base()
        out = []
        prev_q = self.trajectory.start.q
        for m in self.trajectory.motions:
            Q = m.joint_path if m.joint_path is not None and len(m.joint_path) else \
                np.array([prev_q, m.target.q])
            P = self.robot.batch_fk(np.asarray(Q, float)).positions
            out.append((m.kind.value, P @ T_wb[:3, :3].T + T_wb[:3, 3]))
            prev_q = m.target.q
        return out

    # ================================================================== 7. export
    def export(self, dialect: str | None = None, *, name: str | None = None,
               frame: str | None = None) -> Any:
        """Write the planned mission as a robot program; returns the files (and a zip).
        With `frame` (a named, e.g. calibrated, frame) the targets are written in that frame
        (KRL $BASE, RAPID wobj, URScript pose_trans, ...) instead of the robot base."""
        from assistant.export import export_files, get_dialect, program_from_trajectory
        from assistant.export.program import Frame

        with self._action("export the program", ("export", "plan"), undoable=False,
                          scene="program"):
            if self.trajectory is None:
                raise SessionError("Plan the mission first: there is no verified trajectory yet")
            d = get_dialect(dialect or self.export_dialect)
            work = None
            if frame is not None:
                self._frame(frame)
                work = Frame(frame, self.cell.T_base_frame(frame))
            program = program_from_trajectory(self.trajectory, self.robot,
                                              name=name or "MISSION", work=work)
            result = export_files(program, d, self.robot)
            self.export_dialect = d.name
            self.program = result
        self.bus.emit(ProgramReady(d.name, tuple(f.name for f in result.files)))
        return result

    def upload_program(self) -> str:
        """Send the exported program to the robot controller; returns its name there."""
        with self._action("upload the program", ("export",), undoable=False):
            if self.program is None:
                raise SessionError("Export the program first")
            files = {f.name: f.data for f in self.program.files}
            name = self.link().upload_program(self.program.files[0].name.split(".")[0], files)
        self.bus.emit(Notice(f"program uploaded to the robot as {name}"))
        return name

    # ================================================================== samples
    @staticmethod
    def from_sample(name_or_path: str | Path = "thesis_rv2aj", folder: str | Path | None = None,
                    *, with_objects: bool = True, with_mission: bool = True,
                    autosave: bool = True) -> Session:
        """A session on a sample cell: its robot, link, cameras and hidden obstacles; with its
        placed objects and taught mission unless told otherwise (the operator then imports
        and teaches them)."""
        import json

        from assistant.samples import SampleError, read_meta, sample_folder

        src = sample_folder(name_or_path)
        meta = read_meta(src)
        s = Session(folder, autosave=False)
        cell = load_cell(src / CELL_DIR)
        cell.robot_spec = sample_robot_spec(cell.robot_spec, src)
        s.cell = cell if with_objects else Cell(cell.robot_spec, cell.T_world_base, {},
                                                dict(cell.frames))
        try:
            hidden_path = src / "hidden.json"
            if hidden_path.exists():
                doc = json.loads(hidden_path.read_text(encoding="utf-8"))
                s.hidden = [HiddenObstacle.from_json(d) for d in doc.get("obstacles", [])]
            if "link" in meta:
                s.link_settings = LinkSettings.from_json(meta["link"])
            s.pointer_config = dict(meta.get("pointer", {}))
            s.export_dialect = str(meta.get("dialect", s.export_dialect))
            mission_path = src / "mission.json"
            if with_mission and mission_path.exists():
                s.mission = Mission.from_json(json.loads(mission_path.read_text("utf-8")))
                for loc in (s.mission.start, s.mission.goal):
                    if loc is not None:
                        s.locations[loc.name] = loc
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise SampleError(f"sample {src.name}: {exc}") from None
        s.sample = src.name
        s.autosave_enabled = autosave and folder is not None
        s._autosave()
        return s

    # ================================================================== persistence
    def _autosave(self) -> None:
        if self.autosave_enabled and self.folder is not None:
            self.save(self.folder)

    def save(self, folder: str | Path) -> Path:
        """Write the whole session (cell with CAD files, mission, world observations, plan)."""
        folder = Path(folder)
        with self._lock:
            save_cell(self.cell, folder / CELL_DIR)
            doc = {
                "schema_version": SESSION_SCHEMA,
                "saved_at": time.time(),
                "machine": self.machine.to_json(),
                "locations": [loc.to_json() for loc in self.locations.values()],
                "mission": self.mission.to_json(),
                "link": self.link_settings.to_json(),
                "hidden_obstacles": [h.to_json() for h in self.hidden],
                "pointer": self.pointer_config,
                "counters": self.counters.to_json(),
                "recorded_collisions": [q.tolist() for q in self.recorded_collisions],
                "robot_joints": self.current_joints().tolist(),
                "trajectory": trajectory_to_json(self.trajectory) if self.trajectory else None,
                "plan_report": self.plan_report,
                "export_dialect": self.export_dialect,
                "sample": self.sample,
            }
            write_json_atomic(folder / SESSION_JSON, doc)
        return folder

    def save_as(self, folder: str | Path) -> Path:
        """Save to a new folder and autosave there from now on."""
        folder = Path(folder)
        with self._lock:
            self.folder = folder
            self.autosave_enabled = True
            return self.save(folder)

    @staticmethod
    def load(folder: str | Path, *, autosave: bool = True) -> Session:
        """Restore a saved session: scene, mission, world observations and plan."""
        folder = Path(folder)
        doc = read_session_json(folder)
        try:
            cell = load_cell(folder / CELL_DIR)
            s = Session(folder, autosave=False)
            s.cell = cell
            s.machine = Machine.from_json(doc.get("machine", {}))
            for d in doc.get("locations", []):
                loc = Location.from_json(d)
                s.locations[loc.name] = loc
            s.mission = Mission.from_json(doc.get("mission", {}))
            s.link_settings = LinkSettings.from_json(doc.get("link", {}))
            s.hidden = [HiddenObstacle.from_json(h) for h in doc.get("hidden_obstacles", [])]
            s.pointer_config = dict(doc.get("pointer", {}))
            s.counters = Counters.from_json(doc.get("counters", {}))
            s.recorded_collisions = [np.asarray(q, float) for q in
                                     doc.get("recorded_collisions", [])]
            q = doc.get("robot_joints")
            if q is not None:
                qa = np.asarray(q, float)
                if qa.shape == (s.robot.dof,) and np.all(np.isfinite(qa)):
                    s._q_sim = qa
            t = doc.get("trajectory")
            s.trajectory = trajectory_from_json(t) if t else None
            s.plan_report = doc.get("plan_report")
            s.export_dialect = str(doc.get("export_dialect", "melfa"))
            s.sample = doc.get("sample")
        except SessionFileError:
            raise
        except (KeyError, TypeError, ValueError) as exc:
            raise SessionFileError(f"{folder / SESSION_JSON}: {exc}") from None
        s.autosave_enabled = autosave
        return s


# ---------------------------------------------------------------------- helpers
@dataclass
class _Backend:
    """The planning back end for one set of obstacles: world model, roadmap, exact checker."""

    world: Any
    roadmap: Any
    checker: CollisionChecker
    planner: Any = None
    executor: Any = None
    explorer: Any = None

    def add_collision(self, q: Array) -> Any:
        return self.roadmap.add_collision(np.asarray(q, float))


def _report_json(rep: Any) -> dict:
    """The figures of a `MissionPlanReport` as plain JSON (saved with the session)."""
    return {"ok": rep.ok, "reason": rep.reason, "min_clearance_m": rep.min_clearance,
            "tcp_path_length_m": rep.tcp_length, "joint_path_length_rad": rep.joint_length,
            "primitives": dict(rep.primitive_counts), "planning_time_s": rep.planning_seconds,
            "order": list(rep.order), "description": rep.describe()}


def _arc_points(a: Array, v: Array, b: Array, n: int = 48) -> Array:
    """Points on the circle through a, v, b from a to b (for drawing)."""
    a, v, b = (np.asarray(x, float) for x in (a, v, b))
    u1, u2 = v - a, b - a
    w = np.cross(u1, u2)
    if np.linalg.norm(w) < 1e-12:
        return np.array([a, b])
    c = a + (np.dot(u1, u1) * np.cross(w, u2) * -1 + np.dot(u2, u2) * np.cross(w, u1)) / \
        (2 * np.dot(w, w)) * -1
    r = np.linalg.norm(a - c)
    e1 = (a - c) / r
    nrm = w / np.linalg.norm(w)
    e2 = np.cross(nrm, e1)
    ang_b = np.arctan2((b - c) @ e2, (b - c) @ e1) % (2 * np.pi)
    t = np.linspace(0, ang_b, n)
    return c + r * (np.outer(np.cos(t), e1) + np.outer(np.sin(t), e2))


def hint_for(exc: BaseException) -> str:
    """What the operator can do about a failed action (shown under the error)."""
    if isinstance(exc, UnreachableError):
        return "Move the point closer to the robot or change the tool orientation."
    if isinstance(exc, CellError):
        return "Check the object name and pose."
    name = type(exc).__name__
    if name == "CadImportError":
        return "Export the part again from the CAD system, or try another format."
    return ""


def _safe_name(base: str) -> str:
    import re

    s = re.sub(r"[^A-Za-z0-9_]+", "_", base).strip("_") or "part"
    return s if not s[0].isdigit() else f"part_{s}"


def _check_identifier(name: str, what: str) -> None:
    import re

    if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,30}", name):
        raise SessionError(f"{what} name {name!r}: use a letter, then letters, digits or _ "
                           "(at most 31 characters) - robot controllers accept nothing else")


def _angle(Ra: Array, Rb: Array) -> float:
    return float(np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1) / 2, -1.0, 1.0)))


def _tool_frame_along(approach: Array) -> Array:
    """A rotation whose z axis (the tool's approach) is `approach`; x chosen stably."""
    z = approach / np.linalg.norm(approach)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    y = np.cross(z, helper)
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    return np.column_stack([x, y, z])


def _segments(kind: SegmentKind, pts: list[Array]) -> list[PathSegment]:
    if kind == SegmentKind.LINE:
        if len(pts) < 2:
            raise SessionError("a line needs 2 points")
        return [PathSegment(kind, (pts[i], pts[i + 1])) for i in range(len(pts) - 1)]
    if kind == SegmentKind.ARC:
        if len(pts) != 3:
            raise SessionError("an arc needs 3 points: start, via, end")
        return [PathSegment(kind, tuple(pts))]
    if len(pts) < 4 or (len(pts) - 1) % 3:
        raise SessionError("a Bezier chain needs 1 + 3k points (start, then control, control, "
                           "end for each segment)")
    return [PathSegment(kind, tuple(pts[i:i + 4])) for i in range(0, len(pts) - 1, 3)]


# ---------------------------------------------------------------------- frames and drawings
#: Three-point calibration: smallest distance between the points (m) and the angle range
#: (deg) between the x axis and the XY-plane point; outside them the frame is ill-defined.
MIN_CALIBRATION_SPAN = 0.02
CALIBRATION_ANGLES_DEG = (15.0, 165.0)


@dataclass(frozen=True)
class FrameCalibration:
    """A frame from the 3-point method (origin, +x point, XY-plane point), world frame."""

    name: str
    T_world_frame: Array
    points: Array  # (3, 3) the measured points
    #: Angle between the frame's z axis and the world z axis (how far the plane is tilted).
    tilt: float
    #: Distance of the XY-plane point from the x axis (m): the lever that fixes the tilt
    #: about x; the frame's rotation error about x is about (point error / this).
    lever_y: float

    def describe(self) -> str:
        o = self.T_world_frame[:3, 3] * 1000.0
        return (f"frame {self.name} calibrated from 3 points: origin ({o[0]:.1f}, {o[1]:.1f}, "
                f"{o[2]:.1f}) mm, tilted {np.degrees(self.tilt):.2f} deg from the world XY "
                f"plane")


def frame_from_three_points(name: str, origin: Array, x_point: Array,
                            xy_point: Array) -> FrameCalibration:
    """x along origin -> x_point; z normal to the plane of the three points with xy_point on
    the +y side; y = z cross x. Refuses points too close or (nearly) on one line."""
    o, px, pxy = (np.asarray(p, dtype=float).reshape(3) for p in (origin, x_point, xy_point))
    ex, ey = px - o, pxy - o
    for v, what in ((ex, "the x point"), (ey, "the XY-plane point")):
        if np.linalg.norm(v) < MIN_CALIBRATION_SPAN:
            raise SessionError(f"frame {name}: {what} is within "
                               f"{MIN_CALIBRATION_SPAN * 1000:.0f} mm of the origin; measure "
                               "points further apart")
    x = ex / np.linalg.norm(ex)
    cos_a = float(np.clip(x @ ey / np.linalg.norm(ey), -1.0, 1.0))
    ang = np.degrees(np.arccos(cos_a))
    lo, hi = CALIBRATION_ANGLES_DEG
    if not lo <= ang <= hi:
        raise SessionError(f"frame {name}: the three points are almost on one line "
                           f"({ang:.1f} deg between the x axis and the XY-plane point; "
                           f"{lo:.0f}-{hi:.0f} deg needed)")
    z = np.cross(x, ey)
    z /= np.linalg.norm(z)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, y, z])
    T[:3, 3] = o
    tilt = float(np.arccos(np.clip(z[2], -1.0, 1.0)))
    return FrameCalibration(name, T, np.array([o, px, pxy]), tilt, float(ey @ y))


def _drawing_control(drawing: int | Array) -> Array:
    """Control points (1 + 3k, 2-D metres) of drawing 1..9 or of the points given."""
    from assistant.export.bezier_drawings import drawing as numbered

    if isinstance(drawing, (int, np.integer)):
        try:
            chain = numbered(int(drawing))
        except ValueError as exc:
            raise SessionError(str(exc)) from None
        segs = [np.asarray(s.control, dtype=float) for s in chain.segments]
        return np.vstack([segs[0][:1]] + [c[1:] for c in segs])
    P = np.asarray(drawing, dtype=float)
    if P.ndim != 2 or P.shape[1] not in (2, 3) or not np.all(np.isfinite(P)):
        raise SessionError("drawing points must be finite (x, y) pairs in the frame")
    if len(P) < 4 or (len(P) - 1) % 3:
        raise SessionError("a Bezier chain needs 1 + 3k points (start, then control, "
                           "control, end for each segment)")
    return P


def drawing_path(name: str, T_world_frame: Array, control: Array, *,
                 at: tuple[float, float] = (0.0, 0.0), angle: float = 0.0, lift: float = 0.03,
                 before: list[ToolAction] = (), after: list[ToolAction] = (),
                 speed: float = 0.05, reversible: bool = False,
                 tool_angle: float = 0.0) -> ApplicationPath:
    """The application path of a pen drawing on a frame's XY plane (see
    `Session.add_drawing`); `control` holds 1 + 3k points, 2-D (or 3-D) metres."""
    if not lift > 0.0:
        raise SessionError("the pen lift above the paper must be > 0")
    P = np.asarray(control, dtype=float)
    if P.shape[1] == 2:
        P = np.column_stack([P, np.zeros(len(P))])
    c, s = np.cos(angle), np.sin(angle)
    T_frame_drawing = np.eye(4)
    T_frame_drawing[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T_frame_drawing[:2, 3] = at
    T = np.asarray(T_world_frame, dtype=float) @ T_frame_drawing
    W = P @ T[:3, :3].T + T[:3, 3]
    up = np.asarray(T_world_frame, dtype=float)[:3, 2] * lift
    segs = [PathSegment(SegmentKind.LINE, (W[0] + up, W[0].copy()))]
    segs += [PathSegment(SegmentKind.BEZIER, tuple(W[i:i + 4])) for i in range(0, len(W) - 1, 3)]
    segs.append(PathSegment(SegmentKind.LINE, (W[-1].copy(), W[-1] + up)))
    # The pen points into the paper: tool z = -frame z, tool x along the drawing's x turned
    # by tool_angle about the pen.
    ct, st = np.cos(tool_angle), np.sin(tool_angle)
    R_turn = np.array([[ct, -st, 0.0], [st, ct, 0.0], [0.0, 0.0, 1.0]])
    R_world_tool = T[:3, :3] @ R_turn @ np.diag([1.0, -1.0, -1.0])
    return ApplicationPath(name, segs, R_world_tool, list(before), list(after), float(speed),
                           bool(reversible))


# ---------------------------------------------------------------------- sample robots
def sample_robot_spec(spec: RobotSpec, folder: Path) -> RobotSpec:
    """A sample cell's URDF robot with its relative path resolved: first against the sample
    folder (a URDF shipped with the sample), then against the installed robot descriptions
    (``example-robot-data/robots/...``), so a committed cell names no machine's paths.
    Absolute paths and built-in robots are returned unchanged."""
    from dataclasses import replace

    if spec.kind != "urdf" or not spec.urdf_path or Path(spec.urdf_path).is_absolute():
        return spec
    rel = Path(spec.urdf_path)
    candidates = [folder / rel] + [d / rel for d in robot_data_dirs()]
    for cand in candidates:
        if cand.is_file():
            return replace(spec, urdf_path=str(cand.resolve()))
    tried = ", ".join(str(c) for c in candidates)
    raise SessionError(f"robot description {spec.urdf_path!r} not found (tried: {tried}); "
                       "example-robot-data comes with the test extra: pip install -e '.[test]'")
