"""The robot-neutral program: what every dialect writes and every reader gives back.

Two steps, as in the thesis (SPEC §7): a planned `Trajectory` (+ the mission's labels and tool
actions) becomes a `NeutralProgram` here, then a dialect module turns it into controller text.
The neutral program is also what scripts build by hand and what `read()` returns, so the round
trip (write -> read -> simulate) compares like with like.

Targets are always kept in the robot base frame in metres/radians (`T_base_tool`) together
with the joint solution `q` that reaches them; dialects re-express them in the program's work
frame and convert units only when they write text.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from assistant.export.configuration import ArmConfig
from assistant.export.errors import ExportError
from assistant.mission.motion import MotionKind, ToolAction, ToolActionKind, Trajectory, Waypoint
from assistant.robots.model import Robot

Array = np.ndarray


class MoveKind(str, Enum):
    JOINT = "joint"  # PTP / MOV / MoveJ / movej: interpolated in joint space
    LINEAR = "linear"  # LIN / MVS / MoveL / movel: straight TCP line
    CIRCULAR = "circular"  # CIRC / MVR / MoveC / movec: start (previous target), via, end
    SPLINE = "spline"  # SPL block: smooth curve through `through` points to the target


@dataclass(frozen=True)
class Position:
    """A named target: TCP pose in the base frame and the joint solution that reaches it.

    `q` is required for writing (configuration flags come from it). Readers fill `config`
    from the flags instead; a joint target read back may have no pose (`T_base_tool` None).
    """

    name: str
    T_base_tool: Array | None
    q: Array | None = None
    config: ArmConfig | None = None
    #: Written as an axis target (E6AXIS, jointtarget, J variable, movej joint list).
    joint_target: bool = False

    def same_as(self, other: Position, tol: float = 1e-9) -> bool:
        if self.joint_target != other.joint_target:
            return False
        for a, b in ((self.T_base_tool, other.T_base_tool), (self.q, other.q)):
            if (a is None) != (b is None):
                return False
            if a is not None and not np.allclose(a, b, atol=tol):
                return False
        return True


@dataclass(frozen=True)
class Move:
    """One motion primitive to `target`, starting where the previous move ended."""

    kind: MoveKind
    target: Position
    via: Position | None = None  # CIRCULAR only
    through: tuple[Position, ...] = ()  # SPLINE only
    #: Cartesian moves: TCP speed (m/s). Joint moves: fraction (0, 1] of the maximum.
    speed: float | None = None
    #: Fraction (0, 1] of the controller's maximum acceleration; None keeps the current one.
    acceleration: float | None = None
    #: Blend into the next move within this distance (m); 0 stops exactly at the target.
    blend_radius: float = 0.0
    #: Mission step this move belongs to (comments, error messages).
    step: str = ""

    def positions(self) -> list[Position]:
        out = list(self.through)
        if self.via is not None:
            out.append(self.via)
        out.append(self.target)
        return out


@dataclass(frozen=True)
class SetOutput:
    channel: int
    value: bool
    step: str = ""


@dataclass(frozen=True)
class Gripper:
    """Open or close hand `hand` (MELFA HOPEN/HCLOSE n; an output on other controllers)."""

    hand: int
    close: bool
    step: str = ""


@dataclass(frozen=True)
class Wait:
    seconds: float
    step: str = ""


@dataclass(frozen=True)
class Comment:
    text: str


Instruction = Move | SetOutput | Gripper | Wait | Comment


@dataclass(frozen=True)
class Frame:
    """A named frame: the tool (T_flange_tool) or the work frame targets are taught in."""

    name: str
    T: Array = field(default_factory=lambda: np.eye(4))

    @property
    def is_identity(self) -> bool:
        return bool(np.allclose(self.T, np.eye(4), atol=1e-12))


@dataclass
class NeutralProgram:
    """Instructions plus the frames they refer to; positions are reached through moves."""

    name: str
    instructions: list[Instruction] = field(default_factory=list)
    tool: Frame = field(default_factory=lambda: Frame("flange"))
    #: Work frame (KUKA $BASE, ABB wobj, MELFA BASE): T_base_work. Identity = robot base.
    work: Frame = field(default_factory=lambda: Frame("robot_base"))
    #: Joint configuration the program starts from (round-trip simulation; not written).
    q_start: Array | None = None

    def moves(self) -> list[Move]:
        return [i for i in self.instructions if isinstance(i, Move)]

    def positions(self) -> list[Position]:
        """Distinct positions in order of first use."""
        seen: dict[str, Position] = {}
        for m in self.moves():
            for p in m.positions():
                seen.setdefault(p.name, p)
        return list(seen.values())

    def primitive_count(self) -> int:
        return len(self.moves())

    def primitive_counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for m in self.moves():
            out[m.kind.value] = out.get(m.kind.value, 0) + 1
        return out


# ====================================================================== from a trajectory
@dataclass(frozen=True)
class ProgramDefaults:
    """Speeds and blending used where the planner left them open."""

    joint_speed: float = 0.5  # fraction of the maximum
    linear_speed: float = 0.1  # m/s
    #: A planned joint path may not leave the straight joint interpolation by more than this
    #: (m at any point of the arm); otherwise intermediate joint targets are inserted.
    joint_path_tolerance: float = 0.002


def program_from_trajectory(traj: Trajectory, robot: Robot, *, name: str,
                            defaults: ProgramDefaults | None = None,
                            work: Frame | None = None, tool_name: str | None = None,
                            move_to_start: bool = True,
                            start_name: str | None = None) -> NeutralProgram:
    """The neutral program for a planned trajectory.

    Args:
        traj: the planner's result; every waypoint carries its joint solution.
        robot: the robot it was planned for (tool from `robot.T_flange_tool`).
        name: program name (checked by each dialect).
        defaults: speeds for motions without one, joint-path tolerance.
        work: work frame the dialects express targets in (default: the robot base).
        tool_name: name of the tool frame (default: the robot's tool name or "tool").
        move_to_start: begin with a joint move to the start waypoint, so the program does
            not depend on where the robot happens to be (the thesis listing omits it).
        start_name: name for the start position when the waypoint has none.
    Returns:
        The program; positions are named after their waypoints (the operator's names), a
        generated point after the named position its step is heading for: `P7_V1`, `P7_V2`
        are the first and second via points on the way to P7 (never a taught name); P1,
        P2, ... only where nothing named follows.
    Raises:
        ExportError naming the step for a waypoint without a joint solution or two different
        positions with the same name.
    """
    d = defaults or ProgramDefaults()
    namer = _Namer(traj)
    tool = Frame(tool_name or getattr(getattr(robot, "tool", None), "name", None) or "tool",
                 np.asarray(robot.T_flange_tool, dtype=float))
    prog = NeutralProgram(name, [], tool, work or Frame("robot_base"),
                          q_start=None if traj.start.q is None else np.asarray(traj.start.q,
                                                                               float))
    start = namer.position(traj.start, "start", preferred=start_name)
    if move_to_start:
        prog.instructions.append(Move(MoveKind.JOINT, start, speed=d.joint_speed,
                                      step="move to the start posture"))
    prog.instructions += _actions(traj.actions_at_start, "start")
    prev = traj.start
    heading = _heading_for(traj)
    for k, m in enumerate(traj.motions):
        step = m.label or f"motion {k + 1}"
        blend = float(m.blend_radius)
        dest = heading[k]
        if m.kind == MotionKind.JOINT:
            speed = d.joint_speed if m.speed is None else float(m.speed)
            for mid in _joint_path_splits(robot, prev, m, d.joint_path_tolerance):
                pos = namer.position(mid, step, joint_target=True, dest=dest)
                prog.instructions.append(Move(MoveKind.JOINT, pos, speed=speed, step=step))
            target = namer.position(m.target, step, dest=dest)
            prog.instructions.append(Move(MoveKind.JOINT, target, speed=speed,
                                          blend_radius=blend, step=step))
        else:
            speed = d.linear_speed if m.speed is None else float(m.speed)
            via = None
            through: tuple[Position, ...] = ()
            if m.kind == MotionKind.CIRCULAR:
                if m.via is None:
                    raise ExportError("a circular motion needs a via point", step=step)
                via = namer.position(m.via, step, dest=dest)
            elif m.kind == MotionKind.SPLINE:
                through = tuple(namer.position(w, step, dest=dest) for w in m.through)
            target = namer.position(m.target, step, dest=dest)
            kind = {MotionKind.LINEAR: MoveKind.LINEAR, MotionKind.CIRCULAR: MoveKind.CIRCULAR,
                    MotionKind.SPLINE: MoveKind.SPLINE}[m.kind]
            prog.instructions.append(Move(kind, target, via, through, speed=speed,
                                          blend_radius=blend, step=step))
        prog.instructions += _actions(m.actions_after, step)
        prev = m.target
    return prog


def _heading_for(traj: Trajectory) -> list[str]:
    """For each motion, the name of the first named target at or after it ("" if none):
    generated points are named after where their step is heading."""
    out = [""] * len(traj.motions)
    nxt = ""
    for k in range(len(traj.motions) - 1, -1, -1):
        nxt = traj.motions[k].target.name or nxt
        out[k] = nxt
    return out


def _actions(actions: tuple[ToolAction, ...], step: str) -> list[Instruction]:
    out: list[Instruction] = []
    for a in actions:
        if a.kind == ToolActionKind.GRIPPER_OPEN:
            out.append(Gripper(int(a.channel), False, step))
        elif a.kind == ToolActionKind.GRIPPER_CLOSE:
            out.append(Gripper(int(a.channel), True, step))
        elif a.kind == ToolActionKind.OUTPUT:
            out.append(SetOutput(int(a.channel), bool(a.value), step))
        elif a.kind == ToolActionKind.WAIT:
            out.append(Wait(float(a.seconds), step))
    return out


class _Namer:
    """Names positions: the waypoint's own name, else the next free P<k>."""

    def __init__(self, traj: Trajectory):
        self.taken = {w.name for w in traj.waypoints() if w.name}
        for m in traj.motions:
            self.taken |= {w.name for w in ((m.via,) if m.via else ()) + m.through if w.name}
        self.by_name: dict[str, tuple[Position, str]] = {}
        self.by_id: dict[int, Position] = {}
        self.k = 0
        self.vias: dict[str, int] = {}
        # Names differing only in case are one name to most controllers.
        self._folded = {n.upper() for n in self.taken}

    def _free(self, cand: str) -> bool:
        if cand in self.taken or cand.upper() in self._folded:
            return False
        self.taken.add(cand)
        self._folded.add(cand.upper())
        return True

    def _next(self, dest: str = "") -> str:
        if dest:  # the k-th via point on the way to `dest`
            while True:
                self.vias[dest] = self.vias.get(dest, 0) + 1
                cand = f"{dest}_V{self.vias[dest]}"
                if self._free(cand):
                    return cand
        while True:
            self.k += 1
            cand = f"P{self.k}"
            if self._free(cand):
                return cand

    def position(self, w: Waypoint, step: str, *, joint_target: bool = False,
                 preferred: str | None = None, dest: str = "") -> Position:
        if id(w) in self.by_id and self.by_id[id(w)].joint_target == joint_target:
            return self.by_id[id(w)]
        if w.q is None:
            raise ExportError(f"position {w.name or '(unnamed)'} has no joint solution; the "
                              "configuration flags cannot be derived", step=step)
        name = w.name or preferred or self._next(dest)
        q = np.asarray(w.q, dtype=float)
        pos = Position(name, np.asarray(w.T_base_tool, dtype=float), q, None, joint_target)
        if name in self.by_name:
            old, old_step = self.by_name[name]
            if not old.same_as(pos, 1e-9):
                raise ExportError(f"the name {name!r} is used for two different positions "
                                  f"(also in step {old_step!r})", step=step)
            pos = old
        else:
            self.by_name[name] = (pos, step)
        self.by_id[id(w)] = pos
        return pos


def _joint_path_splits(robot: Robot, prev: Waypoint, m, tol: float) -> list[Waypoint]:
    """Intermediate postures so that straight joint moves stay near the planned joint path.

    A controller's joint move interpolates joints linearly; the planner's collision-free
    joint path may bend. Douglas-Peucker in joint space with the arm radii as weights: a
    joint step dq moves no point of the arm more than sum(r_i |dq_i|).
    """
    path = m.joint_path
    if path is None or len(path) < 3:
        return []
    path = np.asarray(path, dtype=float)
    radii = robot.arm_radii()
    keep = _douglas_peucker(path, radii, tol)
    out = []
    for i in keep[1:-1]:
        q = path[i]
        out.append(Waypoint(robot.fk(q), q, ""))
    return out


def _douglas_peucker(path: Array, w: Array, tol: float) -> list[int]:
    seg = np.r_[0.0, np.cumsum(np.abs(np.diff(path, axis=0)) @ w)]

    def dev(a: int, b: int) -> tuple[float, int]:
        if b - a < 2:
            return 0.0, a
        s = (seg[a + 1:b] - seg[a]) / max(seg[b] - seg[a], 1e-15)
        line = path[a] + s[:, None] * (path[b] - path[a])
        e = np.abs(path[a + 1:b] - line) @ w
        i = int(np.argmax(e))
        return float(e[i]), a + 1 + i

    keep = {0, len(path) - 1}
    stack = [(0, len(path) - 1)]
    while stack:
        a, b = stack.pop()
        e, i = dev(a, b)
        if e > tol:
            keep.add(i)
            stack += [(a, i), (i, b)]
    return sorted(keep)


def renamed(program: NeutralProgram, mapping: dict[str, str]) -> NeutralProgram:
    """A copy with positions renamed (e.g. to satisfy a stricter controller)."""
    cache: dict[int, Position] = {}

    def rp(p: Position | None) -> Position | None:
        if p is None:
            return None
        if id(p) not in cache:
            cache[id(p)] = replace(p, name=mapping.get(p.name, p.name))
        return cache[id(p)]

    out = []
    for ins in program.instructions:
        if isinstance(ins, Move):
            ins = replace(ins, target=rp(ins.target), via=rp(ins.via),
                          through=tuple(rp(t) for t in ins.through))
        out.append(ins)
    return replace(program, instructions=out)
