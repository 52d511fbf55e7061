"""FANUC TP as ASCII: one ``NAME.LS`` per program (``/PROG``, ``/ATTR``, ``/MN``, ``/POS``,
``/END``), as the controller's ASCII upload option or FANUC's MakeTP (TP conversion) take it.

Motion lines ``J P[1:P1] 50% FINE``, ``L P[2:P2] 100mm/sec CNT4``, ``C P[3:P3]`` continued by
``:  P[4:P4] 100mm/sec FINE`` (start = the previous target, via, end), ``ACCn`` when the
program sets an acceleration. Speeds: joint moves in whole % of the axes' maxima (so never
above the robot's joint speeds), Cartesian moves in whole mm/sec. Blending: FANUC's CNT is a
percentage of corner rounding, not a distance: the blend radius is written as ``CNTn`` with
n = the radius in whole mm (1..100), as RoboDK's FANUC post does, and read back as n mm;
``FINE`` stops at the point. Outputs are ``DO[n]=ON/OFF``; gripper n is output
``gripper_output + n - 1`` (ON = closed) followed by a ``WAIT`` of `gripper_wait_s` for the
fingers, announced by a comment ``!close gripper 1``. Waits are ``WAIT 0.50(sec)``.

Positions ``P[n:NAME]`` carry the operator's name as the position comment (at most 16
characters; `names` renames longer ones once, with a note) and are written in ``/POS``:

* Cartesian ``X, Y, Z`` (mm), ``W, P, R`` (deg, rotations about the fixed X, Y, Z axes: R =
  Rz(R) Ry(P) Rx(W)) in user frame ``UF`` with tool ``UT`` and ``CONFIG : 'F U T, t1, t4,
  t6'`` from the planned joints (`configuration.arm_configuration`): F (flip) when J5 < 0
  else N, U when the elbow is up else D, T when the wrist centre is in front of the J1 axis
  else B (back), and the turn numbers of J1, J4 and J6 (whole turns beyond (-180, 180] deg,
  0 for an axis the arm lacks), the axes RoboDK's FANUC post writes turn numbers for;
* joint values ``J1= .. deg`` (the joints in chain order, four decimals: the controller
  shows three, but 0.0005 deg at a UR10's 1.3 m reach is 11 um) for joint targets and every
  position whose CONFIG cannot tell the planned posture from another: when an axis without a
  turn number (J2, J3, J5) can turn by a full turn within the robot's limits (a UR's
  shoulder, +-360 deg) the same pose and flags have a second solution; the export says so
  in its notes.

Frames: the program selects ``UTOOL_NUM`` (`utool`) and ``UFRAME_NUM`` (0, the world frame =
the robot base, or `uframe` for a work frame); their values are controller data, set on the
teach pendant, and are given in comments at the top (``!UTOOL[1] gripper`` and its X .. R)
where the reader takes them back. Controller limits (conservative where FANUC's manuals for
older controllers are stricter): program names of 8 upper-case letters, digits and _,
comments of 32 characters (longer ones are wrapped), at most 9999 lines per program (line
numbers have 4 digits): a longer program is split into parts a main program CALLs, with a
note. Header and step labels are comments; the predicted cycle time is in the header.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from assistant.export.configuration import (
    ArmConfig,
    JointRange,
    arm_configuration,
    joint_for_slot,
    turn_ambiguous_joints,
    turn_count,
)
from assistant.export.cycle_time import CycleTime, predict_cycle_time
from assistant.export.dialect import (
    Part,
    ProgramFile,
    ascii_text,
    base_words,
    check_axis_count,
    check_output_channels,
    check_position_names,
    flatten,
    lower_splines,
    part_names,
    parts_within,
    pose_in_base,
    pose_in_work,
    position_pose,
    settle_values,
    step_changes,
    step_line,
    xyz_fixed_angles,
    xyz_fixed_matrix,
)
from assistant.export.dialect_names import AXIS_COUNTS
from assistant.export.errors import ExportError
from assistant.export.fanuc_ls import parse_ls
from assistant.export.pendant_notes import COMMENT_LENGTH, frame_comments, short_comments
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
    euler_deg,
    format_fixed,
)
from assistant.robots.model import Robot

Array = np.ndarray

#: Line numbers in an .LS file have four digits.
MAX_LINES = 9999
#: Axes with a turn number in CONFIG (A1, A4, A6 in `configuration.axis_slots` numbering).
TURN_SLOTS = (1, 4, 6)
#: Fixed dates: the same program gives the same bytes (the controller sets its own).
STAMP = "DATE 20-01-01  TIME 00:00:00"


def fanuc_rules(max_positions_per_file: int | None = None) -> DialectRules:
    return DialectRules(
        dialect="FANUC TP", identifier=re.compile(r"[A-Za-z][A-Za-z0-9_]*"),
        identifier_hint="letters, digits and _, starting with a letter (a position comment)",
        max_identifier=16, max_line=255, max_positions_per_file=max_positions_per_file,
        case_sensitive=False, program_identifier=re.compile(r"[A-Z][A-Z0-9_]*"),
        program_hint="upper-case letters, digits and _, starting with a letter",
        max_program_name=8)


@dataclass
class FanucDialect:
    """FANUC TP (.LS) writer and reader."""

    utool: int = 1
    uframe: int = 1
    gripper_output: int = 1
    gripper_wait_s: float = 0.3
    max_positions_per_file: int | None = None
    max_lines: int = MAX_LINES

    name = "fanuc"
    title = "FANUC TP (ASCII .LS)"
    file_extensions = (".LS",)
    #: FANUC arms: 4-axis palletizers and SCARA, 5- and 6-axis articulated arms.
    axis_counts = AXIS_COUNTS["fanuc"]
    axis_rule = "FANUC TP positions hold the joints J1..J6 of 4- to 6-axis FANUC arms"
    axes_beyond = ("a seventh joint would be an extended axis E1 (a rail or positioner) in "
                   "FANUC's positions, not an arm joint, so a 7-axis arm cannot be written")

    @staticmethod
    def position_identifiers(name: str, joint_target: bool = False) -> tuple[str, ...]:
        """The position comment of P[n:NAME]: the name itself."""
        return (name,)

    def __post_init__(self) -> None:
        self.rules = fanuc_rules(self.max_positions_per_file)

    # ====================================================================== writing
    def lower(self, program: NeutralProgram) -> NeutralProgram:
        """No splines on FANUC (lines through their points); settings as written: whole %,
        whole mm/sec, CNT in whole mm, ACC in whole %, waits in 0.01 s."""
        return settle_values(
            lower_splines(program),
            joint_speed=lambda v, m: _whole_percent(v, "joint speed", m.step) / 100.0,
            cartesian_speed=lambda v, m: _mm_per_s(v, m.step) / 1000.0,
            blend=lambda r, m: _cnt(r) / 1000.0,
            acceleration=lambda a, m: _whole_percent(a, "acceleration", m.step) / 100.0,
            wait=lambda s, w: round(s, 2))

    def write(self, program: NeutralProgram, robot: Robot, *,
              cycle_time: CycleTime | None = None) -> list[ProgramFile]:
        return self.write_noted(program, robot, cycle_time=cycle_time)[0]

    def write_noted(self, program: NeutralProgram, robot: Robot, *,
                    cycle_time: CycleTime | None = None
                    ) -> tuple[list[ProgramFile], tuple[str, ...]]:
        """The files and what the operator should know about them (split, joint values)."""
        check_axis_count(self, robot)
        program = self.lower(program)
        name = check_identifier(program.name.upper(), self.rules, what="program name",
                                program=True)
        check_position_names(program, self.rules)
        check_output_channels(program, self.gripper_output, lambda n: f"DO[{n}]")
        cycle = cycle_time or predict_cycle_time(program, robot)
        forms, ambiguous = self._forms(program, robot)
        notes: list[str] = []
        if ambiguous:
            joints = sorted({j for js in ambiguous.values() for j in js})
            notes.append(f"positions {', '.join(ambiguous)} are written as joint values: "
                         f"{', '.join(robot.joint_names[j] for j in joints)} can turn a full "
                         "turn within this arm's limits and CONFIG has no turn number for it")
        head = len(self._header(name, robot, cycle))
        parts = parts_within(program, self.rules.max_positions_per_file, self.max_lines,
                             lambda p: head + len(self._mn(name, program, p, robot, head=True)),
                             what="FANUC TP")
        if len(parts) == 1:
            files = [self._file(name, program, parts[0], robot, forms, cycle=cycle)]
        else:
            subs = part_names(name, len(parts), self.rules.max_program_name or 8)
            files = [self._file(sub, program, part, robot, forms, cycle=None)
                     for sub, part in zip(subs, parts, strict=True)]
            files.insert(0, self._main(name, program, subs, robot, cycle))
            notes.append(f"the program is split into {len(parts)} parts ({', '.join(subs)}) "
                         f"that {name} calls: a FANUC TP program holds at most "
                         f"{self.max_lines} lines"
                         + (f" and here {self.rules.max_positions_per_file} positions"
                            if self.rules.max_positions_per_file else ""))
        for f in files:
            check_lines(f.text, self.rules, f.name)
        return files, tuple(notes)

    def _forms(self, program: NeutralProgram, robot: Robot
               ) -> tuple[dict[str, str], dict[str, list[int]]]:
        """Per position "joint" or "cartesian", and the positions written as joints because
        CONFIG would not tell their posture apart (with the joints it cannot place)."""
        forms: dict[str, str] = {}
        ambiguous: dict[str, list[int]] = {}
        for p in program.positions():
            if p.q is None:
                raise ExportError(f"position {p.name!r} has no joint solution")
            if p.joint_target:
                forms[p.name] = "joint"
                continue
            free = turn_ambiguous_joints(robot, p.q, _flag_function(robot, p.q))
            forms[p.name] = "joint" if free else "cartesian"
            if free:
                ambiguous[p.name] = free
        return forms, ambiguous

    # ------------------------------------------------------------------ files
    def _main(self, name: str, program: NeutralProgram, subs: list[str], robot: Robot,
              cycle: CycleTime) -> ProgramFile:
        mn = self._header(name, robot, cycle) + [f"!main: runs {len(subs)} parts"]
        mn += self._frames(program)
        mn += [f"CALL {s}" for s in subs]
        return self._assemble(name, mn, [])

    def _file(self, name: str, program: NeutralProgram, part: Part, robot: Robot,
              forms: dict[str, str], *, cycle: CycleTime | None) -> ProgramFile:
        mn = self._header(name, robot, cycle) if cycle is not None else [
            f"!{name}: part {part.index} of", f"!{program.name.upper()}"]
        mn += self._mn(name, program, part, robot, head=cycle is not None)
        numbers = {p.name: k for k, p in enumerate(part.positions, start=1)}
        pos = [self._position(numbers[p.name], p, robot, program, forms[p.name])
               for p in part.positions]
        return self._assemble(name, mn, pos)

    def _header(self, name: str, robot: Robot, cycle: CycleTime) -> list[str]:
        predicted, _, caveat = cycle.header_text().partition(" (")
        lines = [f"{name}: generated by cellteach", f"for {ascii_text(robot.name)}",
                 predicted, f"({caveat}", "positions in mm and deg, CONFIG",
                 "from the planned joints", base_words(robot)]
        return [c for text in lines for c in short_comments("!", text)]

    def _frames(self, program: NeutralProgram) -> list[str]:
        out = ["!frames to set on the controller"]
        out += frame_comments("!", f"UTOOL[{self.utool}]", program.tool, ("W", "P", "R"), 3)
        if not program.work.is_identity:
            out += frame_comments("!", f"UFRAME[{self.uframe}]", program.work,
                                   ("W", "P", "R"), 3)
        out += [f"UFRAME_NUM={self._uf(program)}", f"UTOOL_NUM={self.utool}"]
        return out

    def _uf(self, program: NeutralProgram) -> int:
        return 0 if program.work.is_identity else self.uframe

    def _mn(self, name: str, program: NeutralProgram, part: Part, robot: Robot, *,
            head: bool) -> list[str]:
        """The /MN instructions of a part (without line numbers): frames first in a program
        that runs on its own, UFRAME_NUM/UTOOL_NUM in every part."""
        numbers = {p.name: k for k, p in enumerate(part.positions, start=1)}
        out = self._frames(program) if head else [f"UFRAME_NUM={self._uf(program)}",
                                                  f"UTOOL_NUM={self.utool}"]
        for ins, step in step_changes(part.instructions):
            if step is not None:
                out.append(step_line("!", step, 1 + COMMENT_LENGTH).replace(";", ","))
            if isinstance(ins, Move):
                out.append(self._motion(ins, numbers))
            elif isinstance(ins, Gripper):
                word = "close" if ins.close else "open"
                out += [f"!{word} gripper {ins.hand}",
                        f"DO[{self.gripper_output + ins.hand - 1}]={'ON' if ins.close else 'OFF'}",
                        f"WAIT {self.gripper_wait_s:.2f}(sec)"]
            elif isinstance(ins, SetOutput):
                out.append(f"DO[{ins.channel}]={'ON' if ins.value else 'OFF'}")
            elif isinstance(ins, Wait):
                out.append(f"WAIT {ins.seconds:.2f}(sec)")
            elif isinstance(ins, Comment):
                out += short_comments("!", ins.text)
        return out

    def _motion(self, m: Move, numbers: dict[str, int]) -> str:
        def ref(p: Position) -> str:
            return f"P[{numbers[p.name]}:{p.name}]"

        assert m.speed is not None  # settled by `lower`
        speed = (f"{round(m.speed * 100)}%" if m.kind == MoveKind.JOINT
                 else f"{round(m.speed * 1000)}mm/sec")
        term = "FINE" if m.blend_radius <= 0.0 else f"CNT{round(m.blend_radius * 1000)}"
        acc = "" if m.acceleration is None else f" ACC{round(m.acceleration * 100)}"
        tail = f"{ref(m.target)} {speed} {term}{acc}"
        if m.kind == MoveKind.JOINT:
            return f"J {tail}"
        if m.kind == MoveKind.LINEAR:
            return f"L {tail}"
        if m.kind == MoveKind.CIRCULAR:
            assert m.via is not None
            return f"C {ref(m.via)}    \n    :  {tail}"
        raise AssertionError("spline moves are lowered before writing")  # pragma: no cover

    def _position(self, k: int, p: Position, robot: Robot, program: NeutralProgram,
                  form: str) -> str:
        assert p.q is not None
        uf = f"UF : {self._uf(program)}, UT : {self.utool},"
        if form == "joint":
            vals = [f"J{i + 1}={_num(np.degrees(v), p.name, 4)} deg"
                    for i, v in enumerate(p.q)]
            rows = [",\t".join(vals[i:i + 3]) for i in range(0, len(vals), 3)]
            body = [f"\t{uf}"] + [f"\t{r}," if i < len(rows) - 1 else f"\t{r}"
                                  for i, r in enumerate(rows)]
        else:
            T = pose_in_work(program, position_pose(robot, p))
            x, y, z = T[:3, 3] * 1000.0
            w, pp, r = euler_deg(xyz_fixed_angles(T), 3)
            body = [f"\t{uf}\t\tCONFIG : '{config_text(robot, p.q)}',",
                    f"\tX ={_num(x, p.name)}  mm,\tY ={_num(y, p.name)}  mm,"
                    f"\tZ ={_num(z, p.name)}  mm,",
                    f"\tW ={_num(w, p.name)} deg,\tP ={_num(pp, p.name)} deg,"
                    f"\tR ={_num(r, p.name)} deg"]
        return "\n".join([f'P[{k}:"{p.name}"]{{', "   GP1:"] + body + ["};"])

    def _assemble(self, name: str, mn: list[str], pos: list[str]) -> ProgramFile:
        if len(mn) > self.max_lines:
            raise ExportError(f"{name} needs {len(mn)} lines; FANUC TP allows "
                              f"{self.max_lines}")
        attr = ["/ATTR", "OWNER\t\t= MNEDITOR;", 'COMMENT\t\t= "cellteach";',
                "PROG_SIZE\t= 0;", f"CREATE\t\t= {STAMP};", f"MODIFIED\t= {STAMP};",
                "FILE_NAME\t= ;", "VERSION\t\t= 0;", f"LINE_COUNT\t= {len(mn)};",
                "MEMORY_SIZE\t= 0;", "PROTECT\t\t= READ_WRITE;",
                "TCD:  STACK_SIZE\t= 0,", "      TASK_PRIORITY\t= 50,",
                "      TIME_SLICE\t= 0,", "      BUSY_LAMP_OFF\t= 0,",
                "      ABORT_REQUEST\t= 0,", "      PAUSE_REQUEST\t= 0;",
                "DEFAULT_GROUP\t= 1,*,*,*,*;", "CONTROL_CODE\t= 00000000 00000000;"]
        body = []
        for k, text in enumerate(mn, start=1):
            motion = text[:2] in ("J ", "L ", "C ")
            body.append(f"{k:4d}:{text}    ;" if motion else f"{k:4d}:  {text} ;")
        lines = [f"/PROG  {name}"] + attr + ["/MN"] + body + ["/POS"] + pos + ["/END"]
        return ProgramFile(f"{name}.LS", "\n".join(lines) + "\n", newline="\r\n")

    # ====================================================================== reading
    def read(self, files: Sequence[ProgramFile], robot: Robot) -> NeutralProgram:
        progs = {f.name.rsplit(".", 1)[0].upper(): f for f in files
                 if f.name.upper().endswith(".LS")}
        if not progs:
            raise ExportError("no FANUC program (.LS) among the files")
        parsed = {k: parse_ls(k, f.text) for k, f in progs.items()}
        called = {c for p in parsed.values() for c in p.calls}
        mains = [k for k in parsed if k not in called]
        if len(mains) != 1:
            raise ExportError(f"expected one main program, found {mains}")
        frames: dict[tuple[str, int], Frame] = {}
        for p in parsed.values():
            frames.update(p.frames)
        return self._build(mains[0], parsed, frames, robot, set())

    def _build(self, key: str, parsed: dict, frames: dict, robot: Robot,
               stack: set[str]) -> NeutralProgram:
        if key in stack:
            raise ExportError(f"{key} calls itself")
        ls = parsed[key]
        prog = NeutralProgram(ls.name)
        tool = frames.get(("UTOOL", ls.utool))
        if tool is not None:
            prog.tool = tool
        work = frames.get(("UFRAME", ls.uframe))
        if ls.uframe and work is None:
            raise ExportError(f"{key}: UFRAME[{ls.uframe}] is not given in the comments")
        if work is not None:
            prog.work = work
        positions = {n: self._position_back(n, e, frames, robot)
                     for n, e in ls.positions.items()}
        parts: list[NeutralProgram] = []
        for kind, item in ls.body:
            if kind == "call":
                if item not in parsed:
                    raise ExportError(f"{key} calls {item}, which is not among the files")
                parts.append(self._build(item, parsed, frames, robot, stack | {key}))
            elif kind == "move":
                prog.instructions.append(_move_back(item, positions, key))
            else:
                prog.instructions.append(item)
        if parts:
            out = flatten(parts, prog.name)
            out.tool, out.work = prog.tool, prog.work
            return out
        return prog

    def _position_back(self, number: int, entry: dict, frames: dict, robot: Robot) -> Position:
        name = entry["comment"] or f"P{number}"
        if "J" in entry:
            q = np.radians(entry["J"])
            if len(q) != robot.dof:
                raise ExportError(f"P[{number}] has {len(q)} joint values; the robot has "
                                  f"{robot.dof}")
            return Position(name, None, q, joint_target=True)
        v = entry["XYZWPR"]
        T = np.eye(4)
        T[:3, :3] = xyz_fixed_matrix(*np.radians(v[3:]))
        T[:3, 3] = np.asarray(v[:3]) / 1000.0
        if entry["uf"]:
            frame = frames.get(("UFRAME", entry["uf"]))
            if frame is None:
                raise ExportError(f"P[{number}] is in UFRAME[{entry['uf']}], which the "
                                  "comments do not give")
            T = pose_in_base(frame.T, T)
        return Position(name, T, None, config_back(robot, entry["config"], number))


# ---------------------------------------------------------------------------- configuration
def _flag_function(robot: Robot, q: Array):
    """CONFIG as a function of the joints (the geometric letters do not change when a joint
    turns by a full turn; the flip letter and the turn numbers may)."""
    geo = arm_configuration(robot, q)
    j5 = joint_for_slot(robot, 5)
    turns = [joint_for_slot(robot, s) for s in TURN_SLOTS]

    def flags(qq: Array) -> tuple:
        return (geo.front, geo.elbow_up, None if j5 is None else bool(qq[j5] < 0.0),
                tuple(0 if j is None else turn_count(float(qq[j])) for j in turns))

    return flags


def config_text(robot: Robot, q: Array) -> str:
    """``F U T, t1, t4, t6`` for the joint solution (see the module docstring)."""
    cfg = arm_configuration(robot, q)
    flip = "F" if cfg.wrist_negative else "N"
    up = "U" if cfg.elbow_up else "D"
    front = "T" if cfg.front else "B"
    turns = [0 if j is None else turn_count(float(q[j]))
             for j in (joint_for_slot(robot, s) for s in TURN_SLOTS)]
    return f"{flip} {up} {front}, " + ", ".join(str(t) for t in turns)


def config_back(robot: Robot, text: str, number: int) -> ArmConfig:
    m = re.fullmatch(r"\s*([NF])\s+([UD])\s+([TB])\s*,\s*(-?\d+)\s*,\s*(-?\d+)\s*,\s*(-?\d+)\s*",
                     text)
    if not m:
        raise ExportError(f"P[{number}]: cannot read CONFIG {text!r}")
    ranges = []
    for slot, t in zip(TURN_SLOTS, m.group(4, 5, 6), strict=True):
        j = joint_for_slot(robot, slot)
        if j is not None:
            n = int(t)
            ranges.append(JointRange(j, (2 * n - 1) * math.pi, (2 * n + 1) * math.pi))
    has_wrist = joint_for_slot(robot, 5) is not None
    return ArmConfig(m.group(3) == "T", m.group(2) == "U",
                     (m.group(1) == "F") if has_wrist else None, tuple(ranges))


# ---------------------------------------------------------------------------- text
def _num(v: float, what: str, decimals: int = 3) -> str:
    return f"{format_fixed(v, decimals, what=what):>10}"


def _whole_percent(fraction: float, what: str, step: str) -> int:
    pct = round(fraction * 100.0)
    if not 1 <= pct <= 100:
        raise ExportError(f"{what} {fraction * 100:.1f} % is outside FANUC's 1..100 %",
                          step=step)
    return pct


def _mm_per_s(speed: float, step: str) -> int:
    v = round(speed * 1000.0)
    if v < 1:
        raise ExportError(f"speed {speed * 1000:.2f} mm/sec is below FANUC's 1 mm/sec",
                          step=step)
    return v


def _cnt(radius: float) -> int:
    return min(100, max(1, round(radius * 1000.0)))


def _move_back(item, positions: dict[int, Position], key: str) -> Move:
    m, step = item

    def pos(n: str) -> Position:
        try:
            return positions[int(n)]
        except KeyError:
            raise ExportError(f"{key}: P[{n}] is not in /POS") from None

    kind, first, second, value, unit, _, cnt, acc = m.groups()
    speed = int(value) / (100.0 if unit == "%" else 1000.0)
    blend = 0.0 if cnt is None else int(cnt) / 1000.0
    accel = None if acc is None else int(acc) / 100.0
    if kind == "C":
        if second is None:
            raise ExportError(f"{key}: a circular move needs two points")
        return Move(MoveKind.CIRCULAR, pos(second), pos(first), speed=speed,
                    acceleration=accel, blend_radius=blend, step=step)
    return Move(MoveKind.JOINT if kind == "J" else MoveKind.LINEAR, pos(first), speed=speed,
                acceleration=accel, blend_radius=blend, step=step)


