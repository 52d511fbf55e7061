"""Step 4: locations (typed, robot, CAD click, marker pointer), start/goal, application paths.

A part of the `Session`, composed (`Session.teaching`): it owns the live pointer and the point
its last dwell measured; it reaches the rest of the session only through the parts' contract
(`PartContract`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from assistant.mission.model import (
    ApplicationPath,
    Location,
    LocationSource,
    ResolvedMission,
    SegmentKind,
)
from assistant.mission.motion import ToolAction
from assistant.robots.model import IKResult, UnreachableError
from assistant.robots.reach import reach_note
from assistant.session.contract import PartContract
from assistant.session.events import (
    Notice,
    PointerUpdated,
)
from assistant.session.frames import (
    _drawing_control,
    drawing_path,
)
from assistant.session.types import (
    EDIT_MISSION,
    TEACH_STEPS,
    SessionError,
    _angle,
    _check_identifier,
    _segments,
    _tool_frame_along,
)
from assistant.transforms import inv_T

if TYPE_CHECKING:
    from assistant.session.pointer_live import LivePointer

Array = np.ndarray


class TeachPart:
    """Step 4: locations (typed, robot, CAD click, marker pointer), start/goal, paths."""

    def __init__(self, core: PartContract) -> None:
        self._core = core
        #: The live pointer while the camera step is open (None otherwise).
        self.pointer: LivePointer | None = None
        #: The last point a pointer dwell measured (`TaughtPoint`), waiting for a name.
        self.pending_point: Any = None
        #: The cameras and the pointer's colour (saved with the session).
        self.pointer_config: dict[str, Any] = {}

    # ================================================================== 4. teach
    def teach(self, name: str, T_world_tool: Array, *,
              source: LocationSource = LocationSource.TYPED, q_hint: Array | None = None,
              uncertainty_m: float = 0.0, replace_existing: bool = True) -> Location:
        """Store a location. Out-of-reach poses are refused, and poses the arm reaches only
        touching itself; one inside a cell object is kept with a warning (`_free_solution`).
        A 5-axis robot's orientation is projected into its arm plane (the operator is told
        by how much)."""
        with self._core.action(f"teach {name}", TEACH_STEPS, scene="locations"):
            loc = self.make_location(name, np.asarray(T_world_tool, float), source, q_hint,
                                     uncertainty_m)
            if name in self._core.locations and not replace_existing:
                raise SessionError(f"a location named {name!r} exists already")
            self._core.locations[name] = loc  # the mission names it: nothing else to update
        return self._core.locations[name]

    def make_location(self, name: str, T_world_tool: Array, source: LocationSource,
                      q_hint: Array | None, uncertainty_m: float) -> Location:
        _check_identifier(name, "location")
        T_base_world = inv_T(self._core.T_world_base())
        T_base = T_base_world @ T_world_tool
        seed = q_hint if q_hint is not None else self._core.current_joints()
        res: IKResult = self._core.robot.ik(T_base, seed=seed)
        if not res.ok and res.nearest_T_base_tool is not None and \
                res.failure is not None and res.failure.value == "orientation":
            near = res.nearest_T_base_tool
            res2 = self._core.robot.ik(near, seed=seed)
            if res2.ok:
                ang = np.degrees(_angle(near[:3, :3], T_base[:3, :3]))
                self._core.bus.emit(Notice(f"{name}: {res.message}; the orientation was turned by "
                                           f"{ang:.1f} deg into the arm plane"))
                T_base, res = near, res2
        if not res.ok:
            note = reach_note(self._core.robot, T_base[:3, 3])
            raise UnreachableError(res.message + (f"; {note}" if note else ""), res)
        q = self._free_solution(name, res, seed)
        return Location(name, self._core.T_world_base() @ T_base, source, q, uncertainty_m)

    def _free_solution(self, name: str, res: IKResult, seed: Array) -> Array:
        """The IK solution nearest `seed` that the planner's check accepts (the same rule,
        the same cell objects: `planning.locations.first_free`). A pose whose every posture
        has the arm touching itself is refused; one whose every posture touches a cell
        object is kept with a warning (the object may be about to move) - the planner
        refuses it until the cell changes."""
        from assistant.planning.locations import LocationProblem, first_free

        sols = sorted((np.asarray(q, dtype=float) for q in res.solutions),
                      key=lambda q: float(np.linalg.norm(q - seed)))
        k, problem = first_free(self._core.known_checker(), name, sols)
        if problem is not None and problem.problem == LocationProblem.SELF_COLLISION:
            raise SessionError(str(problem))
        if problem is not None:
            self._core.bus.emit(Notice(f"{problem}: planning refuses it until the cell changes"))
        return sols[k]

    def teach_from_robot(self, name: str) -> Location:
        q = self._core.current_joints()
        return self.teach(name, self._core.tcp_world(q), source=LocationSource.ROBOT_POSE, q_hint=q)

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
        real vision pipeline measures it. Returns the taught point (measured, not the truth).
        Each frame's ball and dwell progress are announced (`PointerUpdated`) for the page."""
        from vision.pointer import PointerSystem
        from vision.scripted import simulate_dwell

        models = self.camera_models()

        def system(scene: Any) -> _AnnouncedDwell:
            # 30 frames a second, a common camera's rate: half the rendering of 60
            return _AnnouncedDwell(PointerSystem.synthetic(models, scene, seed=seed, fps=30.0),
                                   self._core.bus)

        try:
            # _AnnouncedDwell is a PointerSystem that also reports each state (duck-typed)
            return simulate_dwell(system, np.asarray(point_world, float),  # type: ignore[arg-type]
                                  seed=seed)
        finally:
            self._core.bus.emit(PointerUpdated(None))

    # -- live pointer (UI) ------------------------------------------------------------------
    def start_pointer(self) -> None:
        """Run the pointer pipeline in the background (synthetic cameras by default)."""
        from assistant.session.pointer_live import LivePointer
        from vision.color import ColorProfile

        with self._core.lock:
            if self.pointer is not None and self.pointer.running:
                return
            self.pointer = LivePointer(self.camera_models(), on_state=self._on_pointer,
                                       seed=int(self.pointer_config.get("seed", 0)))
            prof = self.pointer_config.get("profile")
            if prof:
                self.pointer.system.profile = ColorProfile.from_dict(prof)
            self.pointer.start()

    def stop_pointer(self) -> None:
        with self._core.lock:
            p, self.pointer = self.pointer, None
        if p is not None:
            p.stop()

    def pointer_move_to(self, point_world: Array | None) -> None:
        """Synthetic camera only: the simulated hand brings the ball to a point (None: away)."""
        if self.pointer is None:
            self.start_pointer()
        assert self.pointer is not None
        self.pointer.hand.move_to(None if point_world is None else np.asarray(point_world, float))

    def _on_pointer(self, state: Any) -> None:
        from assistant.session.events import PointerUpdated

        pos = None if state.position_world is None else np.asarray(state.position_world)
        std = float(np.sqrt(np.trace(state.covariance))) if pos is not None else 0.0
        live = self.pointer
        dwell_s = float(live.system.params.dwell.dwell_s) if live is not None else 0.0
        self._core.bus.emit(PointerUpdated(pos, std, state.mode, float(state.dwell_progress),
                                           dwell_s))
        if state.taught is not None:
            self.pending_point = state.taught
            p = np.asarray(state.taught.position_world) * 1000
            self._core.bus.emit(Notice(f"pointer held still: point measured at "
                                       f"({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm "
                                       f"+- {state.taught.uncertainty * 1000:.1f} mm"))

    def pointer_state(self) -> Any:
        """The last `vision.PointerState` of the live pointer (None when it is not running):
        camera views with frames and detections for the UI."""
        p = self.pointer
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
        from vision.color_calibration import calibrate_from_ellipse

        with self._core.action("calibrate the pointer colour", None, undoable=False):
            if self.pointer is None or self.pointer.last_state is None:
                raise SessionError("start the cameras first (the live view needs a frame)")
            views = list(self.pointer.last_state.cameras.values())
            frame = views[camera_index].frame if 0 <= camera_index < len(views) else None
            if frame is None:
                raise SessionError(f"no live frame from camera {camera_index}")
            prof = calibrate_from_ellipse(frame.image, center_px, axes_px, angle_deg)
            self.pointer.system.profile = prof
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
        with self._core.action(f"delete {name}", TEACH_STEPS, scene="locations"):
            if name not in self._core.locations:
                raise SessionError(f"no location named {name!r}")
            used = self._location_uses(name)
            if used:
                raise SessionError(f"{name} is used by {', '.join(used)}; change that first")
            del self._core.locations[name]

    def _location_uses(self, name: str) -> list[str]:
        uses = []
        m = self._core.mission
        if m.start == name:
            uses.append("the mission start")
        if m.goal == name:
            uses.append("the mission goal")
        return uses

    def set_start(self, name: str) -> None:
        from dataclasses import replace

        with self._core.action("set the mission start", EDIT_MISSION, scene="mission"):
            self._core.mission = replace(self._core.mission, start=self.location(name).name,
                                         order=None)

    def set_goal(self, name: str) -> None:
        from dataclasses import replace

        with self._core.action("set the mission goal", EDIT_MISSION, scene="mission"):
            self._core.mission = replace(self._core.mission, goal=self.location(name).name,
                                         order=None)

    def resolved_mission(self) -> ResolvedMission:
        """The mission with its start and goal looked up in the session's locations, as they
        are now: what planning, the ordering and a study take (`Mission.resolve`)."""
        try:
            return self._core.mission.resolve(self._core.locations)
        except ValueError as exc:
            raise SessionError(str(exc)) from None

    def location(self, name: str) -> Location:
        if name not in self._core.locations:
            known = ", ".join(self._core.locations) or "none yet"
            raise SessionError(f"no location named {name!r} (taught: {known})")
        return self._core.locations[name]

    def add_path(self, name: str, kind: str, points: Sequence[str | Array], *,
                 before: Sequence[ToolAction] = (), after: Sequence[ToolAction] = (),
                 speed: float = 0.05, reversible: bool = False,
                 R_world_tool: Array | None = None, approach: float = 0.0,
                 depart: float = 0.0) -> ApplicationPath:
        """An application path: a line (2 points), arc (3) or Bezier chain (1 + 3k control
        points) through taught locations (by name) or points; the tool orientation is that of
        the first named location unless given. `approach`/`depart` (m): straight lines onto
        the start and off the end along the tool axis, as a programmer writes them."""
        from dataclasses import replace

        with self._core.action(f"add the path {name}", EDIT_MISSION, scene="mission"):
            _check_identifier(name, "path")
            if any(p.name == name for p in self._core.mission.paths):
                raise SessionError(f"a path named {name!r} exists already")
            pts, R = self._path_points(points)
            names = [p if isinstance(p, str) else "" for p in points]
            segs = _segments(SegmentKind(kind), pts, names)
            R_tool = np.asarray(R_world_tool, float) if R_world_tool is not None else (
                R if R is not None else _tool_frame_along(np.array([0.0, 0.0, -1.0])))
            for what, v in (("approach", approach), ("depart", depart)):
                if not np.isfinite(v) or not 0.0 <= v <= 0.5:
                    raise SessionError(f"the {what} distance must be 0 to 500 mm")
            path = ApplicationPath(name, segs, R_tool, list(before), list(after), float(speed),
                                   bool(reversible), float(approach), float(depart))
            m = self._core.mission
            self._core.mission = replace(m, paths=[*m.paths, path], order=None)
        return path

    def _path_points(self, points: Sequence[str | Array]) -> tuple[list[Array], Array | None]:
        out: list[Array] = []
        R: Array | None = None
        for p in points:
            if isinstance(p, str):
                loc = self.location(p)
                out.append(loc.position.copy())
                if R is None:
                    R = loc.T_world_tool[:3, :3]
            else:
                out.append(np.asarray(p, float))
        return out, R

    def remove_path(self, name: str) -> None:
        from dataclasses import replace

        with self._core.action(f"delete the path {name}", EDIT_MISSION, scene="mission"):
            paths = [p for p in self._core.mission.paths if p.name != name]
            if len(paths) == len(self._core.mission.paths):
                raise SessionError(f"no path named {name!r}")
            self._core.mission = replace(self._core.mission, paths=paths, order=None)

    def move_path(self, name: str, index: int) -> None:
        """Reorder the mission's paths (the operator's order; the planner may reorder)."""
        from dataclasses import replace

        with self._core.action(f"move the path {name}", EDIT_MISSION, scene="mission"):
            paths = list(self._core.mission.paths)
            i = next((k for k, p in enumerate(paths) if p.name == name), None)
            if i is None:
                raise SessionError(f"no path named {name!r}")
            p = paths.pop(i)
            paths.insert(max(0, min(index, len(paths))), p)
            self._core.mission = replace(self._core.mission, paths=paths, order=None)

    def add_drawing(self, name: str, frame: str, drawing: int | Array, *,
                    at: tuple[float, float] = (0.0, 0.0), angle: float = 0.0,
                    lift: float = 0.03, before: Sequence[ToolAction] = (),
                    after: Sequence[ToolAction] = (), speed: float = 0.05,
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

        with self._core.action(f"add the drawing {name}", EDIT_MISSION, scene="mission"):
            _check_identifier(name, "path")
            if any(p.name == name for p in self._core.mission.paths):
                raise SessionError(f"a path named {name!r} exists already")
            path = drawing_path(name, self._core.objects.frame(frame), _drawing_control(drawing),
                                at=at, angle=angle, lift=lift, before=before, after=after,
                                speed=speed, reversible=reversible, tool_angle=tool_angle)
            m = self._core.mission
            self._core.mission = replace(m, paths=[*m.paths, path], order=None)
        return path

    def set_path_actions(self, name: str, before: list[ToolAction],
                         after: list[ToolAction]) -> None:
        from dataclasses import replace

        with self._core.action(f"change the tool actions of {name}", EDIT_MISSION, scene="mission"):
            paths = []
            found = False
            for p in self._core.mission.paths:
                if p.name == name:
                    p = replace(p, actions_before=list(before), actions_after=list(after))
                    found = True
                paths.append(p)
            if not found:
                raise SessionError(f"no path named {name!r}")
            self._core.mission = replace(self._core.mission, paths=paths)


class _AnnouncedDwell:
    """A pointer system whose every frame is announced on the bus (the ball, the dwell)."""

    def __init__(self, system: Any, bus: Any):
        self.system = system
        self.bus = bus

    @property
    def params(self) -> Any:
        return self.system.params

    def step(self) -> Any:
        state = self.system.step()
        pos = None if state.position_world is None else np.asarray(state.position_world)
        std = float(np.sqrt(np.nanmax([np.trace(state.covariance), 0.0]))) \
            if pos is not None else 0.0
        self.bus.emit(PointerUpdated(pos, std, state.mode, float(state.dwell_progress),
                                     float(self.system.params.dwell.dwell_s)))
        return state

    def close(self) -> None:
        self.system.close()
