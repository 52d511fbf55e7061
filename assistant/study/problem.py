"""What a study asks of one candidate: the cell and mission with the subject (the robot base,
or one object) moved to the candidate's x, y and yaw.

A `StudyProblem` is plain, picklable data (cell, mission, settings): a local worker inherits
it by fork, a Ray worker receives it once through the object store. The robot is built from
the cell's spec in each process (robots are immutable and cached per spec).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from assistant.cell.model import Cell
from assistant.mission.model import (
    ApplicationPath,
    Location,
    PathSegment,
    ResolvedMission,
    SegmentKind,
)
from assistant.study.region import Candidate
from assistant.transforms import inv_T

Array = np.ndarray

#: Locations within this distance (m) of a moved object's box move with it (taught on it).
CARRY_MARGIN = 0.03


@dataclass(frozen=True)
class Subject:
    """What the study moves: the robot base (`object_name` None) or a named object; `carry`
    moves the taught locations and path points on that object (within its box + 30 mm)
    with it."""

    object_name: str | None = None
    carry: bool = True

    @property
    def is_base(self) -> bool:
        return self.object_name is None

    def describe(self) -> str:
        return "the robot base" if self.is_base else f"object {self.object_name}"


@dataclass(frozen=True)
class StudyCriteria:
    """What a good placement must give: a margin to the joint limits at every location (rad),
    the clearance a transfer should keep (m)."""

    joint_margin: float = math.radians(5.0)
    clearance: float = 0.010

    def __post_init__(self) -> None:
        if not (0.0 <= self.joint_margin < math.pi) or not (0.0 <= self.clearance < 1.0):
            raise ValueError("joint margin must be in [0, 180) deg and clearance in [0, 1000) mm")


@dataclass(frozen=True)
class Target:
    """A pose the robot must take (world frame): a taught location or a path point."""

    name: str
    T_world_tool: Array


@dataclass(frozen=True)
class Leg:
    """A transfer between two targets (indices into the target list), e.g. P1 -> SEAM."""

    a: int
    b: int
    label: str


@dataclass
class StudyProblem:
    """The cell, its mission and the settings every candidate is evaluated with."""

    cell: Cell
    mission: ResolvedMission
    subject: Subject = field(default_factory=Subject)
    criteria: StudyCriteria = field(default_factory=StudyCriteria)
    #: The robot's posture now (IK seed and anchor of the world's joint positions).
    q_seed: Array | None = None
    world_config: Any = None  # WorldConfig (None: WorldConfig.for_robot)
    planner_config: Any = None  # MissionPlannerConfig (None: defaults)
    #: Taught location names by position (world, m): they name the paths' points.
    location_names: dict[str, Array] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.mission.start is None and self.mission.goal is None and not self.mission.paths:
            raise ValueError("the mission is empty: teach the locations and paths first")
        if not self.subject.is_base:
            self.cell.get_object(self.subject.object_name)  # names a missing object clearly

    def robot(self) -> Any:
        return self.cell.robot()

    def current_xy_yaw(self) -> tuple[float, float, float]:
        """Where the subject stands now (x, y, yaw in the world)."""
        T = self._subject_pose()
        return float(T[0, 3]), float(T[1, 3]), float(math.atan2(T[1, 0], T[0, 0]))

    def _subject_pose(self) -> Array:
        if self.subject.is_base:
            return np.asarray(self.cell.T_world_base, dtype=float)
        return np.asarray(self.cell.get_object(self.subject.object_name).T_world_object, float)

    def pose_at(self, c: Candidate) -> Array:
        """The subject's pose at candidate `c`: x, y and yaw replaced, z, roll and pitch kept
        (the subject stays on its floor or table)."""
        T = self._subject_pose().copy()
        cur_yaw = math.atan2(T[1, 0], T[0, 0])
        d = c.yaw - cur_yaw
        Rz = np.array([[math.cos(d), -math.sin(d), 0.0], [math.sin(d), math.cos(d), 0.0],
                       [0.0, 0.0, 1.0]])
        T[:3, :3] = Rz @ T[:3, :3]
        T[0, 3], T[1, 3] = c.x, c.y
        return T

    def variant(self, c: Candidate) -> tuple[Cell, ResolvedMission]:
        """The cell and mission with the subject at candidate `c` (copies; shares meshes)."""
        T_new = self.pose_at(c)
        if self.subject.is_base:
            cell = Cell(self.cell.robot_spec, T_new, dict(self.cell.objects),
                        dict(self.cell.frames))
            return cell, self.mission
        name = self.subject.object_name
        assert name is not None
        obj = self.cell.get_object(name)
        delta = T_new @ inv_T(np.asarray(obj.T_world_object, dtype=float))
        objects = dict(self.cell.objects)
        objects[name] = obj.with_pose(T_new)
        cell = Cell(self.cell.robot_spec, self.cell.T_world_base, objects,
                    dict(self.cell.frames))
        if not self.subject.carry:
            return cell, self.mission
        lo, hi = _object_box(obj)
        return cell, _moved_mission(self.mission, delta, lo, hi)


def targets_and_legs(mission: ResolvedMission, names: dict[str, Array] | None = None,
                     ) -> tuple[list[Target], list[Leg]]:
    """The poses the robot must take, in the mission's order (start, each path's points,
    goal), and the transfers between them (start -> path, path -> path, path -> goal)."""
    named = names or {}
    targets: list[Target] = []
    legs: list[Leg] = []
    prev: tuple[int, str] | None = None
    if mission.start is not None:
        targets.append(Target(mission.start.name, np.asarray(mission.start.T_world_tool, float)))
        prev = (0, mission.start.name)
    order = mission.order if mission.order is not None else range(len(mission.paths))
    for i in order:
        path = mission.paths[i]
        first = len(targets)
        pts = _path_points(path)
        ends = path.name.split("-")
        for k, p in enumerate(pts):
            T = np.eye(4)
            T[:3, :3] = np.asarray(path.R_world_tool, dtype=float)
            T[:3, 3] = p
            name = _name_of(p, named)
            if name is None and len(ends) == 2 and k in (0, len(pts) - 1):
                name = ends[0] if k == 0 else ends[1]
            targets.append(Target(name or f"{path.name} point {k + 1}", T))
        if prev is not None:
            legs.append(Leg(prev[0], first, f"{prev[1]} -> {path.name}"))
        prev = (len(targets) - 1, path.name)
    if mission.goal is not None:
        targets.append(Target(mission.goal.name, np.asarray(mission.goal.T_world_tool, float)))
        if prev is not None:
            legs.append(Leg(prev[0], len(targets) - 1, f"{prev[1]} -> {mission.goal.name}"))
    return targets, legs


def _path_points(path: ApplicationPath) -> list[Array]:
    """The points the tool passes through: every line/arc point, Bezier ends (the control
    points are off the path), consecutive duplicates once."""
    pts: list[Array] = []
    for seg in path.segments:
        sp = [np.asarray(p, float) for p in seg.points]
        if seg.kind == SegmentKind.BEZIER:
            sp = [sp[0], sp[-1]]
        for p in sp:
            if not pts or float(np.linalg.norm(pts[-1] - p)) > 1e-6:
                pts.append(p)
    return pts


def _name_of(p: Array, named: dict[str, Array]) -> str | None:
    for name, q in named.items():
        if float(np.linalg.norm(np.asarray(q, float) - p)) < 5e-4:
            return name
    return None


def _object_box(obj: Any) -> tuple[Array, Array]:
    """The object's axis-aligned box in the world, grown by `CARRY_MARGIN`."""
    pts = []
    for shape in obj.collision:
        m = shape.to_trimesh()
        m.apply_transform(np.asarray(obj.T_world_object, dtype=float))
        pts.append(np.asarray(m.bounds))
    b = np.concatenate(pts) if pts else np.zeros((2, 3))
    return b.min(axis=0) - CARRY_MARGIN, b.max(axis=0) + CARRY_MARGIN


def _moved_mission(mission: ResolvedMission, delta: Array, lo: Array, hi: Array) -> ResolvedMission:
    """The mission with every location and path point inside [lo, hi] (on the moved
    object) moved by `delta`; a path wholly on it also turns its tool orientation."""
    def inside(p: Array) -> bool:
        return bool(np.all(p >= lo) and np.all(p <= hi))

    def moved(p: Array) -> Array:
        p = np.asarray(p, dtype=float)
        return (delta @ np.append(p, 1.0))[:3] if inside(p) else p

    def loc(x: Location | None) -> Location | None:
        if x is None or not inside(x.position):
            return x
        return replace(x, T_world_tool=delta @ x.T_world_tool, q_hint=None)

    paths = []
    for path in mission.paths:
        pts = [np.asarray(p, float) for s in path.segments for p in s.points]
        if any(inside(p) for p in pts):
            segs = [PathSegment(s.kind, tuple(moved(p) for p in s.points))
                    for s in path.segments]
            R = delta[:3, :3] @ path.R_world_tool if all(inside(p) for p in pts) \
                else path.R_world_tool
            path = replace(path, segments=segs, R_world_tool=R)
        paths.append(path)
    return ResolvedMission(loc(mission.start), loc(mission.goal), paths, mission.order)
