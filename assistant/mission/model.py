"""What the operator teaches: named locations, application paths with tool actions, a mission.

Positions are in the cell (world) frame in metres; the planner maps them into the robot base
frame. An application path is where the tool does its work (a seam, a drawing, a pick); the
planner plans the transfers between paths and may order them (SPEC §6 mission ordering).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from assistant.mission.motion import ToolAction

Array = np.ndarray


class LocationSource(str, Enum):
    TYPED = "typed"
    CAD_CLICK = "cad_click"
    ROBOT_POSE = "robot_pose"
    POINTER = "pointer"
    CAD_FILE = "cad_file"  # labelled in a cell-layout drawing


@dataclass(frozen=True, eq=False)
class Location:
    """A taught TCP pose (world frame), where it came from, and its uncertainty if measured.

    Equal when every field is (arrays element-wise): documents are compared to tell whether
    an action changed anything, and a location taught again under its name must compare."""

    name: str
    T_world_tool: Array
    source: LocationSource = LocationSource.TYPED
    #: Joint configuration it was taught with (robot-pose teaching), to keep that arm branch.
    q_hint: Array | None = None
    uncertainty_m: float = 0.0

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Location):
            return NotImplemented
        if (self.q_hint is None) != (other.q_hint is None):
            return False
        return (self.name == other.name and self.source == other.source
                and self.uncertainty_m == other.uncertainty_m
                and np.array_equal(self.T_world_tool, other.T_world_tool)
                and (self.q_hint is None or np.array_equal(self.q_hint, other.q_hint)))

    __hash__ = None  # type: ignore[assignment]  # mutable arrays inside: not a dict key

    @property
    def position(self) -> Array:
        return self.T_world_tool[:3, 3]

    def to_json(self) -> dict:
        return {"name": self.name, "T_world_tool": np.asarray(self.T_world_tool).tolist(),
                "source": self.source.value,
                "q_hint": None if self.q_hint is None else np.asarray(self.q_hint).tolist(),
                "uncertainty_m": self.uncertainty_m}

    @staticmethod
    def from_json(d: dict) -> Location:
        T = np.asarray(d["T_world_tool"], dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"location {d.get('name')!r}: T_world_tool must be a finite 4x4")
        q = d.get("q_hint")
        return Location(str(d["name"]), T, LocationSource(d.get("source", "typed")),
                        None if q is None else np.asarray(q, dtype=float),
                        float(d.get("uncertainty_m", 0.0)))


class SegmentKind(str, Enum):
    LINE = "line"  # points: (start, end)
    ARC = "arc"  # points: (start, via, end)
    BEZIER = "bezier"  # points: (p0, c1, c2, p3), a cubic Bezier


_N_POINTS = {SegmentKind.LINE: 2, SegmentKind.ARC: 3, SegmentKind.BEZIER: 4}


@dataclass(frozen=True)
class PathSegment:
    kind: SegmentKind
    points: tuple[Array, ...]
    #: The taught location each point came from ("" for a typed point), parallel to
    #: `points`: the program names its positions after them (a seam P7 -> P8 stays P7, P8).
    names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if len(self.points) != _N_POINTS[self.kind]:
            raise ValueError(f"a {self.kind.value} segment needs {_N_POINTS[self.kind]} points, "
                             f"got {len(self.points)}")
        if self.names and len(self.names) != len(self.points):
            raise ValueError(f"a {self.kind.value} segment has {len(self.points)} points but "
                             f"{len(self.names)} point names")
        for p in self.points:
            if np.asarray(p).shape != (3,) or not np.all(np.isfinite(p)):
                raise ValueError(f"{self.kind.value} segment: points must be finite (x, y, z)")

    @property
    def start(self) -> Array:
        return np.asarray(self.points[0], dtype=float)

    @property
    def end(self) -> Array:
        return np.asarray(self.points[-1], dtype=float)

    def point_name(self, i: int) -> str:
        """Name of point `i` ("" when it was typed or the segment has no names)."""
        return self.names[i] if self.names else ""

    def reversed(self) -> PathSegment:
        return PathSegment(self.kind, tuple(reversed(self.points)), tuple(reversed(self.names)))

    def to_json(self) -> dict:
        out: dict = {"kind": self.kind.value,
                     "points": [np.asarray(p).tolist() for p in self.points]}
        if any(self.names):
            out["names"] = list(self.names)
        return out

    @staticmethod
    def from_json(d: dict) -> PathSegment:
        names = d.get("names") or ()
        if not isinstance(names, (list, tuple)) or not all(isinstance(n, str) for n in names):
            raise ValueError("a path segment's names must be a list of strings")
        return PathSegment(SegmentKind(d["kind"]),
                           tuple(np.asarray(p, dtype=float) for p in d["points"]), tuple(names))


@dataclass
class ApplicationPath:
    """A chain of segments the tool follows at a fixed orientation, with tool actions."""

    name: str
    segments: list[PathSegment]
    #: Tool orientation held along the path (world frame).
    R_world_tool: Array = field(default_factory=lambda: np.diag([1.0, -1.0, -1.0]))
    actions_before: list[ToolAction] = field(default_factory=list)
    actions_after: list[ToolAction] = field(default_factory=list)
    speed: float = 0.05  # m/s along the path
    #: The planner may run the path backwards when ordering the mission.
    reversible: bool = False
    #: Approach / depart as a programmer writes them (m, along the tool's -Z, 0: none): a
    #: straight line from this far back onto the path's start, and back off its end.
    approach: float = 0.0
    depart: float = 0.0

    @property
    def start(self) -> Array:
        return self.segments[0].start

    @property
    def end(self) -> Array:
        return self.segments[-1].end

    def to_json(self) -> dict:
        return {"name": self.name, "segments": [s.to_json() for s in self.segments],
                "R_world_tool": np.asarray(self.R_world_tool).tolist(),
                "actions_before": [a.to_json() for a in self.actions_before],
                "actions_after": [a.to_json() for a in self.actions_after],
                "speed": self.speed, "reversible": self.reversible,
                **({"approach": self.approach} if self.approach else {}),
                **({"depart": self.depart} if self.depart else {})}

    @staticmethod
    def from_json(d: dict) -> ApplicationPath:
        return ApplicationPath(
            str(d["name"]), [PathSegment.from_json(s) for s in d["segments"]],
            np.asarray(d.get("R_world_tool", np.diag([1.0, -1.0, -1.0])), dtype=float),
            [ToolAction.from_json(a) for a in d.get("actions_before", [])],
            [ToolAction.from_json(a) for a in d.get("actions_after", [])],
            float(d.get("speed", 0.05)), bool(d.get("reversible", False)),
            float(d.get("approach", 0.0)), float(d.get("depart", 0.0)))


@dataclass
class Mission:
    """Start, goal and the application paths between them (in the order the operator gave).

    The start and goal are the *names* of taught locations: the session's `locations` is
    their one store, so a location taught again moves the mission with it. The planner takes
    the mission with them looked up (`resolve`)."""

    start: str | None = None
    goal: str | None = None
    paths: list[ApplicationPath] = field(default_factory=list)
    #: Order chosen by the mission planner (indices into `paths`), None until planned.
    order: list[int] | None = None

    def resolve(self, locations: Mapping[str, Location]) -> ResolvedMission:
        """The mission with its start and goal looked up in `locations` (raises
        `ValueError` naming a start or goal that is not there)."""
        def look_up(role: str, name: str | None) -> Location | None:
            if name is None:
                return None
            if name not in locations:
                raise ValueError(f"the mission {role} {name!r} is not a taught location")
            return locations[name]

        return ResolvedMission(look_up("start", self.start), look_up("goal", self.goal),
                               list(self.paths), self.order)

    def to_json(self) -> dict:
        return {"start": self.start, "goal": self.goal,
                "paths": [p.to_json() for p in self.paths], "order": self.order}

    @staticmethod
    def from_json(d: dict) -> Mission:
        """Either form: start and goal as names, or (the samples' `mission.json`, sessions
        saved before missions named their locations) as whole locations, whose names are
        taken (`inline_locations` gives the locations themselves)."""
        return Mission(_location_name(d.get("start"), "start"),
                       _location_name(d.get("goal"), "goal"),
                       [ApplicationPath.from_json(p) for p in d.get("paths", [])],
                       list(d["order"]) if d.get("order") is not None else None)


@dataclass
class ResolvedMission:
    """A mission with its start and goal locations looked up (`Mission.resolve`): what the
    planner, the ordering and a placement study take. Made where the mission is handed to
    planning and never kept as the document, so it cannot fall behind a re-taught location.
    Its JSON holds the locations whole: the samples' `mission.json`."""

    start: Location | None = None
    goal: Location | None = None
    paths: list[ApplicationPath] = field(default_factory=list)
    order: list[int] | None = None

    def to_json(self) -> dict:
        return {"start": self.start.to_json() if self.start else None,
                "goal": self.goal.to_json() if self.goal else None,
                "paths": [p.to_json() for p in self.paths], "order": self.order}

    @staticmethod
    def from_json(d: dict) -> ResolvedMission:
        return ResolvedMission(Location.from_json(d["start"]) if d.get("start") else None,
                               Location.from_json(d["goal"]) if d.get("goal") else None,
                               [ApplicationPath.from_json(p) for p in d.get("paths", [])],
                               list(d["order"]) if d.get("order") is not None else None)


def inline_locations(d: dict) -> list[Location]:
    """The start and goal a mission's JSON holds whole (the older form `Mission.from_json`
    reads too); none when it names them."""
    return [Location.from_json(d[role]) for role in ("start", "goal")
            if isinstance(d.get(role), dict)]


def _location_name(v: object, role: str) -> str | None:
    if v is None or v in ("", {}):
        return None
    if isinstance(v, dict):
        v = v.get("name")
    if not isinstance(v, str) or not v:
        raise ValueError(f"the mission {role} must name a location")
    return v
