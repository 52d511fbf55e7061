"""The Session's plain data and small rules: errors, counters, hidden obstacles, the
planning back end, names and hints."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from assistant.cell.model import CellError, PrimitiveKind, PrimitiveSpec
from assistant.collision.checker import CollisionChecker
from assistant.mission.model import (
    PathSegment,
    SegmentKind,
)
from assistant.robots.catalog import RobotSpec, robot_data_dirs
from assistant.robots.model import UnreachableError
from assistant.transforms import rotation_angle

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
    return rotation_angle(Ra.T @ Rb)


def _tool_frame_along(approach: Array) -> Array:
    """A rotation whose z axis (the tool's approach) is `approach`; x chosen stably."""
    z = approach / np.linalg.norm(approach)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    y = np.cross(z, helper)
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    return np.column_stack([x, y, z])


def _segments(kind: SegmentKind, pts: list[Array], names: list[str] | None = None,
              ) -> list[PathSegment]:
    """Segments through the points; `names` (parallel, "" for a typed point) name them."""
    nm = list(names) if names and any(names) else []

    def seg(idx: range | list[int]) -> PathSegment:
        return PathSegment(kind, tuple(pts[i] for i in idx),
                           tuple(nm[i] for i in idx) if nm else ())

    if kind == SegmentKind.LINE:
        if len(pts) < 2:
            raise SessionError("a line needs 2 points")
        return [seg([i, i + 1]) for i in range(len(pts) - 1)]
    if kind == SegmentKind.ARC:
        if len(pts) != 3:
            raise SessionError("an arc needs 3 points: start, via, end")
        return [seg(range(3))]
    if len(pts) < 4 or (len(pts) - 1) % 3:
        raise SessionError("a Bezier chain needs 1 + 3k points (start, then control, control, "
                           "end for each segment)")
    return [seg(range(i, i + 4)) for i in range(0, len(pts) - 1, 3)]


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
