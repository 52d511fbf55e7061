"""Universal Robots URScript: one ``name.script`` with a function that is called at the end.

Poses are ``p[x, y, z, rx, ry, rz]`` in metres with the orientation as a rotation vector
(axis x angle, rad); joints are lists in rad. Joint moves go to the planned joint solution
(``movej(P2_q, ...)``), so the arm configuration is exactly the planned one and needs no flags;
linear and circular moves (``movel``, ``movec(via, to, ..., mode=0)``) keep the branch they
start in, as on the controller. Speeds: movej's v is the leading joint's speed in rad/s, so
100 % is the robot's slowest joint limit (its URDF's, `cycle_limits`): no joint is ever
commanded above its own limit, and the cycle time is predicted with every joint at that
speed, as the controller runs it. movel/movec v in m/s (within the joints' limits:
`speed_limits`); blending r in m; accelerations as fractions of `joint_accel_max` /
`tool_accel_max` (the script manual's defaults, 1.4 rad/s^2 and 1.2 m/s^2; omitted when they
are the controller's defaults).

Outputs are ``set_standard_digital_out(n, b)``; gripper n is tool output n - 1
(``set_tool_digital_out``, True = closed). A work frame is a pose variable the targets are
composed with (``pose_trans(WORK, p[...])``); the tool is ``set_tcp``.

Poses are written in the robot's program frame (`Robot.program_frame`), named in the
header: the ROS-Industrial UR descriptions (example-robot-data's too) turn ``base_link`` 180
deg about z against the controller's base, which they carry as the fixed leaf link ``base``
under ``base_link``; every pose and work frame is re-expressed in it (and read back out of
it). A link that is merely called "base" (Kinova's mounting block) is not that frame: such
robots are written in their mounting frame unless their RobotSpec names another link.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from assistant.export.cycle_time import CycleTime, CycleTimeLimits, predict_cycle_time
from assistant.export.dialect import (
    ProgramFile,
    ascii_text,
    check_axis_count,
    comment_lines,
    lower_splines,
    parse_step_comment,
    pose_in_work,
    position_pose,
    step_changes,
    step_line,
)
from assistant.export.dialect_names import AXIS_COUNTS
from assistant.export.errors import ExportError
from assistant.export.program import (
    Comment,
    Frame,
    Gripper,
    Move,
    MoveKind,
    NeutralProgram,
    Position,
    SetOutput,
    Wait,
)
from assistant.export.rules import (
    DialectRules,
    check_identifier,
    check_lines,
    format_compact,
    format_fixed,
    half_turn_sign,
    parse_number,
)
from assistant.robots.model import Robot
from assistant.transforms import rotation_vector

Array = np.ndarray

_RESERVED = frozenset({
    "and", "break", "continue", "def", "elif", "else", "end", "enter_critical",
    "exit_critical", "False", "for", "global", "halt", "if", "in", "join", "kill", "local",
    "not", "or", "pass", "return", "run", "sec", "thread", "True", "while", "xor", "p",
    "movej", "movel", "movec", "movep", "sleep", "set_tcp", "pose_trans",
    "set_standard_digital_out", "set_tool_digital_out", "get_inverse_kin",
})


def ur_rules() -> DialectRules:
    return DialectRules(
        dialect="URScript", identifier=re.compile(r"[A-Za-z_][A-Za-z0-9_]*"),
        identifier_hint="letters, digits and _, not starting with a digit",
        max_identifier=64, max_line=1000, max_positions_per_file=None,
        reserved=_RESERVED, case_sensitive=True)


#: movej's and movel's accelerations when a program gives none (URScript manual).
CONTROLLER_JOINT_ACCEL = 1.4
CONTROLLER_TOOL_ACCEL = 1.2


def controller_base(robot: Robot) -> tuple[Array, str]:
    """Pose of the frame the program's poses are in, in the model base, and its name: the
    robot's program frame (`Robot.program_frame`: a setting, the controller's base of a
    ROS-Industrial description, else the mounting frame)."""
    T, words = robot.program_frame()
    return np.asarray(T, dtype=float), words


def pose_literal(T: Array, what: str = "pose") -> str:
    rv = rotation_vector(T[:3, :3])
    if abs(float(np.linalg.norm(rv)) - np.pi) < 1e-6:  # a half turn: +-axis is one turn
        rv = np.array(half_turn_sign(rv, 6))
    vals = list(T[:3, 3]) + list(rv)
    return "p[" + ", ".join(format_fixed(v, 6, what=what) for v in vals) + "]"


@dataclass
class URScriptDialect:
    """URScript writer and reader."""

    #: rad/s of the leading joint at 100 %, at most the robot's slowest joint limit (None:
    #: that limit)
    joint_speed_max: float | None = None
    #: rad/s^2 (movej) and m/s^2 (movel, movec) at 100 %: the script manual's defaults,
    #: lowered to the cycle time's own where those are lower
    joint_accel_max: float = CONTROLLER_JOINT_ACCEL
    tool_accel_max: float = CONTROLLER_TOOL_ACCEL

    name = "urscript"
    title = "Universal Robots URScript"
    file_extensions = (".script",)
    #: UR arms have six axes: joint lists and get_inverse_kin are 6-vectors.
    axis_counts = AXIS_COUNTS["urscript"]
    axis_rule = "URScript runs on 6-axis UR arms"
    axes_beyond = ""

    @staticmethod
    def position_identifiers(name: str, joint_target: bool = False) -> tuple[str, ...]:
        """A pose variable and, for joint moves, the joint list <name>_q."""
        return (name, name + "_q")

    def __post_init__(self) -> None:
        self.rules = ur_rules()

    def lower(self, program: NeutralProgram) -> NeutralProgram:
        """movep exists but blends with circles; splines are written as blended movel."""
        return lower_splines(program)

    def cycle_limits(self, robot: Robot, base: CycleTimeLimits) -> CycleTimeLimits:
        """The limits the controller runs this program under: every joint at most the
        leading joint's speed (the robot's slowest limit) and acceleration; the TCP at most
        `tool_accel_max`. The writer turns fractions into these numbers and the cycle time
        is predicted on them."""
        v = base.joint_limits(robot)[0]
        a = base.joint_limits(robot)[1]
        v_lead = float(v.min()) if self.joint_speed_max is None else \
            min(float(v.min()), float(self.joint_speed_max))
        lead = replace(base, velocity=(v_lead,) * robot.dof)
        a_lead = min(float(lead.joint_limits(robot)[1].min()), float(a.min()),
                     float(self.joint_accel_max))
        return replace(lead, acceleration=(a_lead,) * robot.dof,
                       tcp_acceleration=min(base.tcp_acceleration, float(self.tool_accel_max)))

    def _leads(self, robot: Robot, limits: CycleTimeLimits | None) -> tuple[float, float, float]:
        """(leading joint speed rad/s, its acceleration rad/s^2, TCP acceleration m/s^2) at
        100 %."""
        lim = self.cycle_limits(robot, limits or CycleTimeLimits())
        v, a, _ = lim.joint_limits(robot)
        return float(v.min()), float(a.min()), float(lim.tcp_acceleration)

    # ====================================================================== writing
    def write(self, program: NeutralProgram, robot: Robot, *,
              cycle_time: CycleTime | None = None) -> list[ProgramFile]:
        check_axis_count(self, robot)
        program = self.lower(program)
        name = check_identifier(program.name, self.rules, what="program name", program=True)
        limits = self.cycle_limits(robot, cycle_time.limits if cycle_time is not None
                                   else CycleTimeLimits())
        cycle = (cycle_time or predict_cycle_time(program, robot, limits)).header_text()
        leads = self._leads(robot, limits)
        work = None if program.work.is_identity else self._ident(program.work.name, "work")
        T_model_ctrl, frame = controller_base(robot)
        T_ctrl_model = np.linalg.inv(T_model_ctrl)
        lines = [f"def {name}():",
                 f"  # {name}: generated by cellteach for {ascii_text(robot.name)}",
                 f"  # {cycle}",
                 "  # poses p[x, y, z, rx, ry, rz] in m and rad (rotation vector); joints in rad",
                 f"  # poses in {frame}",
                 f"  # movej v is the leading joint's speed, at most {format_compact(leads[0], 4)}"
                 " rad/s: the robot's slowest joint limit"]
        lines.append(f"  set_tcp({pose_literal(program.tool.T, 'tool')})  "
                     f"# {ascii_text(program.tool.name)}")
        if work:
            lines.append(f"  {work} = "
                         f"{pose_literal(T_ctrl_model @ program.work.T, 'work frame')}")
        decl, names = self._declarations(program, robot, work, T_ctrl_model)
        lines += decl
        modal = _Modal()
        for ins, step in step_changes(program.instructions):
            if step is not None:
                lines.append(step_line("  # ", step, self.rules.max_line))
            if isinstance(ins, Move):
                lines.append("  " + self._motion(ins, names, leads, modal))
            elif isinstance(ins, Gripper):
                word = "close" if ins.close else "open"
                lines.append(f"  set_tool_digital_out({ins.hand - 1}, {ins.close})  "
                             f"# {word} gripper {ins.hand}")
            elif isinstance(ins, SetOutput):
                lines.append(f"  set_standard_digital_out({ins.channel}, {ins.value})")
            elif isinstance(ins, Wait):
                lines.append(f"  sleep({format_compact(ins.seconds, 3, step=ins.step)})")
            elif isinstance(ins, Comment):
                lines += comment_lines("  # ", ins.text, self.rules.max_line)
        lines += ["end", f"{name}()"]
        f = ProgramFile(f"{name}.script", "\n".join(lines) + "\n")
        check_lines(f.text, self.rules, f.name)
        return [f]

    def _ident(self, name: str, what: str) -> str:
        word = re.sub(r"[^A-Za-z0-9_]+", "_", name).strip("_") or what
        if word[0].isdigit():
            word = "_" + word
        return check_identifier(word.upper(), self.rules, what=what)

    def _declarations(self, program: NeutralProgram, robot: Robot, work: str | None,
                      T_ctrl_model: Array) -> tuple[list[str], dict[tuple[str, bool], str]]:
        """Poses for Cartesian moves, joint lists (<name>_q) for joint moves."""
        names: dict[tuple[str, bool], str] = {}
        lines: list[str] = []
        for m in program.moves():
            for p in m.positions():
                as_joints = m.kind == MoveKind.JOINT and p is m.target
                key = (p.name, as_joints)
                if key in names:
                    continue
                if as_joints:
                    ident = check_identifier(p.name if p.joint_target else f"{p.name}_q",
                                             self.rules, what="position", step=m.step)
                    if p.q is None:
                        raise ExportError(f"position {p.name!r} has no joint solution",
                                          step=m.step)
                    vals = ", ".join(format_fixed(v, 6, what=ident) for v in p.q)
                    lines.append(f"  {ident} = [{vals}]")
                else:
                    if p.joint_target:
                        raise ExportError(f"joint target {p.name!r} used by a "
                                          f"{m.kind.value} move", step=m.step)
                    ident = check_identifier(p.name, self.rules, what="position", step=m.step)
                    T = position_pose(robot, p)
                    if work:
                        lit = pose_literal(pose_in_work(program, T), ident)
                        lines.append(f"  {ident} = pose_trans({work}, {lit})")
                    else:
                        lines.append(f"  {ident} = {pose_literal(T_ctrl_model @ T, ident)}")
                if ident in names.values():
                    raise ExportError(f"two positions would both be named {ident}",
                                      step=m.step)
                names[key] = ident
        return lines, names

    def _motion(self, m: Move, names: dict[tuple[str, bool], str],
                leads: tuple[float, float, float], modal: _Modal) -> str:
        """One motion with the speed and acceleration the cycle time runs it at: a move
        without them keeps the last given (as the cycle time does); the controller's own
        defaults would be other numbers, so they are written whenever they differ."""
        joint = m.kind == MoveKind.JOINT
        modal.take(m)
        opts = []
        frac = modal.accel
        amax = leads[1] if joint else leads[2]
        default = CONTROLLER_JOINT_ACCEL if joint else CONTROLLER_TOOL_ACCEL
        if m.acceleration is not None or abs(frac * amax - default) > 1e-9:
            opts.append(f"a={_down(frac * amax, m.step)}")
        speed = modal.joint if joint else modal.linear
        if speed is not None:
            v = speed * leads[0] if joint else speed
            opts.append(f"v={_down(v, m.step, 'speed')}")
        if m.blend_radius > 0.0:
            opts.append(f"r={format_compact(m.blend_radius, 4, what='blend', step=m.step)}")
        tail = "".join(", " + o for o in opts)
        if m.kind == MoveKind.JOINT:
            return f"movej({names[(m.target.name, True)]}{tail})"
        tgt = names[(m.target.name, False)]
        if m.kind == MoveKind.LINEAR:
            return f"movel({tgt}{tail})"
        assert m.via is not None
        return f"movec({names[(m.via.name, False)]}, {tgt}{tail}, mode=0)"

    # ====================================================================== reading
    def read(self, files: Sequence[ProgramFile], robot: Robot) -> NeutralProgram:
        if len(files) != 1:
            raise ExportError("a URScript program is one file")
        text = files[0].text
        mm = re.search(r"^def\s+(\w+)\s*\(\s*\)\s*:", text, re.M)
        if not mm:
            raise ExportError("no 'def name():' in the script")
        prog = NeutralProgram(mm.group(1))
        T_model_ctrl, _ = controller_base(robot)
        v_lead, a_lead, tcp_a = self._leads(robot, None)
        poses: dict[str, Array] = {}  # in the controller's frame, as written
        joints: dict[str, Array] = {}
        cache: dict[tuple[str, str], Position] = {}
        step = ""
        body = False
        for raw in text.splitlines():
            line, _, comment = raw.strip().partition("#")
            line = line.strip()
            if raw.strip().startswith("def "):
                body = True
                continue
            if not body:
                continue
            if not line:
                s = parse_step_comment(comment)
                if s is not None:
                    step = s
                continue
            if line == "end":
                break
            if m := re.fullmatch(r"set_tcp\((p\[.*\])\)", line):
                prog.tool = Frame(comment.strip() or "tool", _pose(m.group(1)))
            elif m := re.fullmatch(r"(\w+)\s*=\s*pose_trans\((\w+),\s*(p\[.*\])\)", line):
                if m.group(2) not in poses:
                    raise ExportError(f"work frame {m.group(2)} is not declared")
                poses[m.group(1)] = poses[m.group(2)] @ _pose(m.group(3))
                prog.work = Frame(m.group(2), T_model_ctrl @ poses[m.group(2)])
            elif m := re.fullmatch(r"(\w+)\s*=\s*(p\[.*\])", line):
                poses[m.group(1)] = _pose(m.group(2))
            elif m := re.fullmatch(r"(\w+)\s*=\s*\[(.*)\]", line):
                joints[m.group(1)] = np.array([parse_number(v) for v in m.group(2).split(",")])
            elif m := re.fullmatch(r"(movej|movel|movec)\((.*)\)", line):
                kind = m.group(1)
                args = [a.strip() for a in m.group(2).split(",")]
                kw = dict(a.split("=", 1) for a in args if "=" in a)
                pos = [a for a in args if "=" not in a]
                acc = float(kw["a"]) if "a" in kw else None
                v = float(kw["v"]) if "v" in kw else None
                r = float(kw.get("r", 0.0))

                def position(n: str, as_joint: bool) -> Position:
                    key = (n, "j" if as_joint else "p")
                    if key not in cache:
                        if as_joint:
                            if n not in joints:
                                raise ExportError(f"joint list {n} is not declared")
                            base = n[:-2] if n.endswith("_q") else n
                            cache[key] = Position(base, None, joints[n],
                                                  joint_target=not n.endswith("_q"))
                        else:
                            if n not in poses:
                                raise ExportError(f"pose {n} is not declared")
                            cache[key] = Position(n, T_model_ctrl @ poses[n])
                    return cache[key]

                if kind == "movej":
                    mv = Move(MoveKind.JOINT, position(pos[0], True),
                              speed=None if v is None else v / v_lead,
                              acceleration=None if acc is None else acc / a_lead,
                              blend_radius=r, step=step)
                elif kind == "movel":
                    mv = Move(MoveKind.LINEAR, position(pos[0], False), speed=v,
                              acceleration=None if acc is None else acc / tcp_a,
                              blend_radius=r, step=step)
                else:
                    mv = Move(MoveKind.CIRCULAR, position(pos[1], False),
                              position(pos[0], False), speed=v,
                              acceleration=None if acc is None else acc / tcp_a,
                              blend_radius=r, step=step)
                prog.instructions.append(mv)
            elif m := re.fullmatch(r"set_tool_digital_out\((\d+),\s*(True|False)\)", line):
                prog.instructions.append(Gripper(int(m.group(1)) + 1, m.group(2) == "True", step))
            elif m := re.fullmatch(r"set_standard_digital_out\((\d+),\s*(True|False)\)", line):
                prog.instructions.append(SetOutput(int(m.group(1)), m.group(2) == "True", step))
            elif m := re.fullmatch(r"sleep\((.*)\)", line):
                prog.instructions.append(Wait(parse_number(m.group(1)), step))
            else:
                raise ExportError(f"cannot read {raw.strip()!r}")
        return prog


class _Modal:
    """The speeds and acceleration in force (a move without one keeps the last given)."""

    def __init__(self) -> None:
        self.joint: float | None = 1.0  # the cycle time's first joint move: full speed
        self.linear: float | None = None
        self.accel = 1.0

    def take(self, m: Move) -> None:
        if m.acceleration is not None:
            self.accel = m.acceleration
        if m.speed is not None:
            if m.kind == MoveKind.JOINT:
                self.joint = m.speed
            else:
                self.linear = m.speed


def _down(x: float, step: str, what: str = "acceleration") -> str:
    """Four decimals, rounded down: never a hair above the limit the value came from."""
    return format_compact(math.floor(x * 1e4 * (1.0 + 1e-12)) / 1e4, 4, what=what, step=step)


def _pose(text: str) -> Array:
    vals = [parse_number(v) for v in text.strip()[2:-1].split(",")]
    if len(vals) != 6:
        raise ExportError(f"a pose needs 6 numbers: {text!r}")
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(vals[3:]).as_matrix()
    T[:3, 3] = vals[:3]
    return T
