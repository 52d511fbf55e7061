"""Range checks on a loaded session: every value a `session.json` gives must be one the session
can work with, or loading stops with one sentence naming the field (the CLI exits with 2).

The JSON itself is bounded before this runs (`store.py`: nesting depth, no infinities, no
numbers beyond float range). Here:

- what the operator made (locations, the mission, recorded collisions, where the robot stood)
  must be finite, inside the cell (`MAX_COORD_M`) and inside the robot's joint limits -
  anything else is refused, since teaching from it would teach a wrong point;
- what was derived from it (the plan) is dropped with a note when it does not fit the robot:
  planning again loses nothing;
- what only lives while the program runs (a task running, the robot moving) opens idle with a
  note: whatever ran is gone after a restart, and a session stuck in "moving" would refuse
  Stop, Cancel and Load alike.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from assistant.session.store import SessionFileError
from workflow.machine import Mode

if TYPE_CHECKING:
    from assistant.session.contract import PartContract

Array = np.ndarray

#: A saved joint reading may sit this far past a model limit: controllers report joints
#: rounded to 0.01-0.05 deg and limits are written in degrees (1e-3 rad = 0.057 deg).
JOINT_TOL_RAD = 1e-3
#: A cell is metres across; a coordinate beyond 100 m is a typo or a forged file.
MAX_COORD_M = 100.0
#: Rotations as saved are orthonormal to ~1e-15; one typed with 4 decimals to ~1e-4. 1e-3
#: is an orientation error below 0.06 deg, which IK and the planner absorb.
ROT_TOL = 1e-3
#: Locations, paths, collisions, replans: far beyond any real session, small enough to load.
MAX_ITEMS = 100_000
#: Location and path names.
MAX_NAME = 64
#: No industrial arm moves its tool faster than ~10 m/s.
MAX_SPEED_M_S = 10.0
#: Approach/depart and pointer uncertainty: a couple of metres at most.
MAX_OFFSET_M = 2.0
#: The link's timing fields (s) and the simulated robot's pace (as `set_simulation_speed`).
LINK_BOUNDS: dict[str, tuple[float, float]] = {
    "connect_timeout_s": (0.0, 600.0), "timeout_s": (0.0, 600.0),
    "stream_cycle_s": (0.0, 1.0), "decimation_tol_m": (0.0, 0.1),
    "time_scale": (0.01, 100.0), "event_period_s": (0.0, 10.0), "stream_window": (1, 1000)}

TRANSIENT_NOTE = ("{path}: saved while {what}; it opens idle - whatever ran then is gone. "
                  "Check where the robot stands before you move it.")


def reset_transient(s: PartContract, path: Any) -> list[str]:
    """Busy or moving do not survive a restart: open idle, and say so."""
    mode = s.machine.mode
    if mode not in (Mode.BUSY, Mode.MOVING):
        return []
    s.machine.end_mode()
    what = "the robot was moving" if mode == Mode.MOVING else "a task was running"
    return [TRANSIENT_NOTE.format(path=path, what=what)]


def check_session(s: PartContract, path: Any) -> list[str]:
    """Refuse (SessionFileError) what is out of range; return notes for what was dropped."""
    c = _Checker(s, path)
    c.locations()
    c.mission()
    c.hidden()
    c.counters()
    c.collisions()
    c.robot_joints()
    c.link()
    c.pointer()
    c.misc()
    return c.plan()


class _Checker:
    def __init__(self, s: PartContract, path: Any):
        self.s = s
        self.path = path
        robot = s.robot
        self.dof = robot.dof
        self.lower = np.asarray(robot.limits.lower, float) - JOINT_TOL_RAD
        self.upper = np.asarray(robot.limits.upper, float) + JOINT_TOL_RAD
        self.robot_name = robot.name

    def fail(self, what: str, why: str) -> SessionFileError:
        return SessionFileError(f"{self.path}: {what}: {why}")

    # ------------------------------------------------------------------ values
    def count(self, items: Any, what: str) -> None:
        if len(items) > MAX_ITEMS:
            raise self.fail(what, f"{len(items)} entries (at most {MAX_ITEMS})")

    def number(self, v: Any, what: str, lo: float, hi: float, *, lo_open: bool = False
               ) -> None:
        ok = v is not None and np.isfinite(v) and (v > lo if lo_open else v >= lo) and v <= hi
        if not ok:
            low = f"above {lo:g}" if lo_open else f"from {lo:g}"
            raise self.fail(what, f"{v!r} is out of range ({low} to {hi:g})")

    def point(self, p: Any, what: str) -> None:
        a = np.asarray(p, float)
        if a.shape != (3,) or not np.all(np.isfinite(a)):
            raise self.fail(what, "expected 3 finite coordinates")
        if np.max(np.abs(a)) > MAX_COORD_M:
            raise self.fail(what, f"{np.max(np.abs(a)):.3g} m from the origin (the cell ends "
                            f"within {MAX_COORD_M:g} m)")

    def rotation(self, R: Any, what: str) -> None:
        R = np.asarray(R, float)
        if R.shape != (3, 3) or not np.all(np.isfinite(R)):
            raise self.fail(what, "expected a finite 3x3 rotation")
        if np.max(np.abs(R.T @ R - np.eye(3))) > ROT_TOL or np.linalg.det(R) <= 0:
            raise self.fail(what, "not a rotation (its axes must be unit length and at right "
                            "angles, right-handed)")

    def pose(self, T: Any, what: str) -> None:
        T = np.asarray(T, float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise self.fail(what, "expected a finite 4x4 pose")
        if np.max(np.abs(T[3] - (0.0, 0.0, 0.0, 1.0))) > 1e-9:
            raise self.fail(what, "the last row of a pose must be 0 0 0 1")
        self.rotation(T[:3, :3], what)
        self.point(T[:3, 3], what)

    def joints(self, q: Any, what: str) -> None:
        a = np.asarray(q, float)
        if a.shape != (self.dof,) or not np.all(np.isfinite(a)):
            raise self.fail(what, f"expected {self.dof} finite joint angles for the "
                            f"{self.robot_name}, got {a.shape}")
        bad = np.flatnonzero((a < self.lower) | (a > self.upper))
        if bad.size:
            i = int(bad[0])
            raise self.fail(what, f"joint {i + 1} at {_deg(a[i])} is beyond the "
                            f"{self.robot_name}'s limits [{np.degrees(self.lower[i]):.1f}, "
                            f"{np.degrees(self.upper[i]):.1f}] deg")

    def name(self, name: Any, what: str) -> None:
        """Names reach program text and the page: short, printable, one line. (Not the strict
        identifier rule of new names: sample missions name paths like P7-P8.)"""
        if not isinstance(name, str) or not 0 < len(name) <= MAX_NAME or \
                not name.isprintable():
            raise self.fail(what, f"the name {str(name)[:40]!r} must be 1-{MAX_NAME} printable "
                            "characters")

    def location(self, loc: Any, what: str) -> None:
        self.name(loc.name, what)
        self.pose(loc.T_world_tool, f"{what} {loc.name}")
        if loc.q_hint is not None:
            self.joints(loc.q_hint, f"{what} {loc.name} joints")
        self.number(loc.uncertainty_m, f"{what} {loc.name} uncertainty (m)", 0.0,
                    MAX_OFFSET_M)

    # ------------------------------------------------------------------ fields
    def locations(self) -> None:
        self.count(self.s.locations, "locations")
        for loc in self.s.locations.values():
            self.location(loc, "location")

    def mission(self) -> None:
        m = self.s.mission
        for role, name in (("start", m.start), ("goal", m.goal)):
            if name is not None:
                self.name(name, f"mission {role}")
                if name not in self.s.locations:
                    raise self.fail(f"mission {role}", f"{name!r} is not a taught location")
        self.count(m.paths, "mission paths")
        for p in m.paths:
            self.name(p.name, "mission path")
            what = f"mission path {p.name}"
            self.rotation(p.R_world_tool, f"{what} tool orientation")
            self.number(p.speed, f"{what} speed (m/s)", 0.0, MAX_SPEED_M_S, lo_open=True)
            self.number(p.approach, f"{what} approach (m)", 0.0, MAX_OFFSET_M)
            self.number(p.depart, f"{what} depart (m)", 0.0, MAX_OFFSET_M)
            self.count(p.segments, f"{what} segments")
            for k, seg in enumerate(p.segments):
                for j, pt in enumerate(seg.points):
                    self.point(pt, f"{what} segment {k + 1} point {j + 1}")
        if m.order is not None and sorted(m.order) != list(range(len(m.paths))):
            raise self.fail("mission order", f"{m.order!r} is not an order of the "
                            f"{len(m.paths)} paths")

    def hidden(self) -> None:
        self.count(self.s.hidden, "hidden obstacles")
        for h in self.s.hidden:
            self.name(h.name, "hidden obstacle")
            for v in h.size:
                self.number(v, f"hidden obstacle {h.name} size (m)", 0.0, MAX_COORD_M,
                            lo_open=True)
            self.pose(h.T_world_object, f"hidden obstacle {h.name}")

    def counters(self) -> None:
        c = self.s.counters
        for name in ("operator_actions", "collision_indications", "replans"):
            self.number(getattr(c, name), f"counters {name}", 0, 10**12)
        self.number(c.planning_time_s, "counters planning_time_s", 0.0, 1e9)
        self.count(c.replan_times_s, "counters replan_times_s")
        for v in c.replan_times_s:
            self.number(v, "counters replan_times_s", 0.0, 1e9)

    def collisions(self) -> None:
        self.count(self.s.planning.recorded_collisions, "recorded collisions")
        for i, q in enumerate(self.s.planning.recorded_collisions):
            self.joints(q, f"recorded collision {i + 1}")

    def robot_joints(self) -> None:
        q = self.s.setup.q_sim  # the posture as loaded, before any link
        if q is not None:
            self.joints(q, "robot_joints")

    def link(self) -> None:
        ls = self.s.link_settings
        for name, (lo, hi) in LINK_BOUNDS.items():
            self.number(getattr(ls, name), f"link {name}", lo, hi, lo_open=lo == 0.0)
        for name in ("host", "kuka_base_path", "rws_user"):
            if len(getattr(ls, name)) > 255:
                raise self.fail(f"link {name}", "longer than 255 characters")

    def pointer(self) -> None:
        from vision.camera_model import CameraModel
        from vision.color import ColorProfile

        cfg = self.s.pointer_config
        try:
            if "seed" in cfg:
                self.number(int(cfg["seed"]), "pointer seed", 0, 2**31 - 1)
            cams = cfg.get("cameras") or []
            if len(cams) > 16:
                raise self.fail("pointer cameras", f"{len(cams)} cameras (at most 16)")
            for i, cam in enumerate(cams):
                model = CameraModel.from_dict(cam)
                self.pose(model.T_world_camera, f"pointer camera {i + 1}")
                if not (0 < model.width <= 16384 and 0 < model.height <= 16384):
                    raise self.fail(f"pointer camera {i + 1}", "image size out of range")
            if cfg.get("profile"):
                ColorProfile.from_dict(cfg["profile"])
        except SessionFileError:
            raise
        except (KeyError, TypeError, ValueError) as exc:
            raise self.fail("pointer", str(exc)) from None

    def misc(self) -> None:
        from assistant.export.registry import DIALECT_NAMES

        s = self.s
        if s.export_dialect not in DIALECT_NAMES:
            raise self.fail("export_dialect", f"{s.export_dialect!r} is not one of "
                            + ", ".join(DIALECT_NAMES))
        if s.sample is not None and len(s.sample) > 200:
            raise self.fail("sample", "longer than 200 characters")

    def plan(self) -> list[str]:
        """The plan is derived data: one that does not fit is dropped (plan again)."""
        t = self.s.trajectory
        if t is None:
            return []
        try:
            self.count(t.motions, "plan motions")
            for w in t.waypoints():
                self.pose(w.T_base_tool, "plan waypoint")
                self.joints(w.q, "plan waypoint")
            for m in t.motions:
                if m.joint_path is not None:
                    path = np.asarray(m.joint_path, float)
                    if path.ndim != 2 or len(path) > 10**6:
                        raise self.fail("plan joint path", f"shape {path.shape}")
                    for q in path:
                        self.joints(q, "plan joint path")
                if m.speed is not None:
                    self.number(m.speed, "plan speed", 0.0, MAX_SPEED_M_S, lo_open=True)
        except SessionFileError as exc:
            self.s.trajectory = None
            self.s.plan_report = None
            return [f"{exc}; the plan was dropped - plan the mission again"]
        return []


def _deg(rad: float) -> str:
    """An angle for a message: degrees, or radians where degrees would overflow."""
    return f"{np.degrees(rad):.6g} deg" if abs(rad) < 1e300 else f"{rad:.3g} rad"
