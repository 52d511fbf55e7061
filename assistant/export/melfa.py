"""Mitsubishi MELFA BASIC IV (and V): the RV-2AJ's language, as in the thesis (SPEC §7).

Program file ``NAME.MB4`` with step numbers (MOV joint, MVS linear, MVR start,via,end arc,
HOPEN/HCLOSE, OVRD, SPD, CNT, ACCEL, DLY, M_OUT, END) and the positions in ``NAME.POS`` as
COSIROP kept them (the thesis' two files), or positions appended after END in one file.

Positions: ``P1=(X,Y,Z,A,B,C)(FL1,FL2)`` in mm and deg with A, B, C the rotations about X, Y
and Z, R = Rz(C) Ry(B) Rx(A) (Mitsubishi's XYZ-fixed angles; note KUKA's A is about Z).
Joint positions: ``J1=(J1,J2,J3,J4,J5,J6)`` in deg, J4 = 0 for the 5-axis RV-2AJ.

Structure flag FL1 (MELFA manual, "Configuration flag"), computed from the planned joints:

* bit 2 (4) RIGHT/LEFT: the reference point in front of (1) or behind (0) the vertical plane
  through the J1 axis across the arm; the flange centre on 5-axis arms, the J5 centre on
  6-axis arms. For the RV-2AJ: L2 sin J2 + L3 sin(J2+J3) + L6 sin(J2+J3+J5) >= 0.
* bit 1 (2) ABOVE/BELOW: the J5 centre on the upper side of the line through J2 and J3
  (elbow up, 1) or not (0). For the RV-2AJ: J3 >= 0.
* bit 0 (1) NONFLIP/FLIP: 6-axis arms only, NONFLIP when J5 >= 0. A 5-axis arm has no wrist
  flip (J5 follows from the pose), so the bit is 0: the RV-2AJ's usual posture is (6,0), as
  5-axis MELFA arms report it.

FL2 (multi-rotation): one signed 4-bit nibble per axis, axis n in bits 4(n-1)..4n-1, holding
the whole turns beyond (-180, 180] deg (J6 = +190 deg -> 1 in the J6 nibble -> 1048576).

Numbers: mm and deg with two decimals and an explicit sign, as the teaching box shows them.
A step is at most 127 characters; variable names start with a letter, use letters, digits
and "_" (never as the second character: that makes an external variable); BASIC IV names
are kept to 8 characters (BASIC V: 16). Program names: upper-case letters and digits.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from assistant.export.configuration import (
    FLANGE,
    WRIST,
    ArmConfig,
    JointRange,
    arm_configuration,
    axis_slots,
    turn_count,
)
from assistant.export.cycle_time import CycleTime, predict_cycle_time
from assistant.export.dialect import (
    ProgramFile,
    ascii_text,
    base_words,
    check_axis_count,
    comment_lines,
    flatten,
    lower_splines,
    parse_step_comment,
    position_pose,
    split_into_parts,
    step_changes,
    step_line,
    with_arc_start,
    xyz_fixed_angles,
    xyz_fixed_matrix,
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
    euler_deg,
    format_compact,
    format_fixed,
    parse_number,
)
from assistant.robots.model import Robot

Array = np.ndarray

_RESERVED = frozenset({
    "ABS", "ACCEL", "ACT", "AND", "ASC", "ATN", "BASE", "CALLP", "CHR", "CLOSE", "CLR", "CNT",
    "COM", "COS", "CVI", "CVS", "DEF", "DIM", "DLY", "END", "ERROR", "FOR", "GETM", "GOSUB",
    "GOTO", "HCLOSE", "HOPEN", "IF", "INPUT", "JOVRD", "JTOP", "LEN", "LOAD", "MID", "MOD", "MOV",
    "MVA", "MVC", "MVR", "MVR2", "MVR3", "MVS", "NEXT", "NOT", "OADL", "OPEN", "OR", "OVRD", "PI",
    "PLT", "POSCQ", "POSMID", "PREC", "PRINT", "PRIORITY", "PTOJ", "RELM", "REM", "RETURN",
    "SERVO", "SIN", "SKIP", "SPD", "SQR", "STOP", "TAN", "THEN", "TOOL", "WAIT", "WHILE", "WTH",
    "XOR"
})

MAX_STEP_NUMBER = 32767


def melfa_rules(variant: str = "IV", max_positions_per_file: int | None = 500) -> DialectRules:
    n = 8 if variant == "IV" else 16
    return DialectRules(
        dialect=f"MELFA BASIC {variant}",
        identifier=re.compile(r"[A-Z](?:[A-Z0-9][A-Z0-9_]*)?"),
        identifier_hint="upper-case letters, digits and _, starting with a letter, no _ as "
                        "second character",
        max_identifier=n, max_line=127, max_positions_per_file=max_positions_per_file,
        reserved=_RESERVED, case_sensitive=False,
        program_identifier=re.compile(r"[A-Z0-9]+"),
        program_hint="upper-case letters and digits only", max_program_name=8)


#: MELFA (A, B, C) in rad: rotations about X, Y, Z with R = Rz(C) Ry(B) Rx(A).
melfa_abc = xyz_fixed_angles
melfa_matrix = xyz_fixed_matrix


@dataclass
class MelfaDialect:
    """MELFA BASIC IV/V writer and reader."""

    variant: str = "IV"
    single_file: bool = False
    max_positions_per_file: int | None = 500

    name = "melfa"
    title = "Mitsubishi MELFA BASIC"
    file_extensions = (".MB4", ".POS")
    #: MELFA arms: 4-axis RH SCARA, 5-axis RV (RV-2AJ), 6-axis RV; joints J1..J6.
    axis_counts = AXIS_COUNTS["melfa"]
    axis_rule = ("MELFA BASIC runs on 4-, 5- and 6-axis Mitsubishi arms (RH SCARA, 5-axis "
                 "RV such as the RV-2AJ, 6-axis RV)")
    axes_beyond = ""

    @staticmethod
    def position_identifiers(name: str, joint_target: bool = False) -> tuple[str, ...]:
        """The identifier written for a position name: P... (pose) or J... (joints)."""
        up, x = name.upper(), "J" if joint_target else "P"
        return (up if up.startswith(x) else x + up,)

    def __post_init__(self) -> None:
        if self.variant not in ("IV", "V"):
            raise ValueError("variant must be 'IV' or 'V'")
        self.rules = melfa_rules(self.variant, self.max_positions_per_file)
        self.title = f"Mitsubishi MELFA BASIC {self.variant}"
        self.file_extensions = (".MB4", ".POS") if self.variant == "IV" else (".MB5", ".POS")

    # ====================================================================== writing
    def lower(self, program: NeutralProgram) -> NeutralProgram:
        """The program as this dialect can express it (no splines in MELFA BASIC)."""
        return lower_splines(program)

    def write(self, program: NeutralProgram, robot: Robot, *,
              cycle_time: CycleTime | None = None) -> list[ProgramFile]:
        check_axis_count(self, robot)
        program = self.lower(program)
        pname = check_identifier(program.name.upper(), self.rules, what="program name",
                                 program=True)
        names = self._names(program)
        cycle = (cycle_time or predict_cycle_time(program, robot)).header_text()
        parts = split_into_parts(program, self.rules.max_positions_per_file, with_arc_start)
        files: list[ProgramFile] = []
        if len(parts) == 1:
            files += self._program_files(pname, program, parts[0], names, robot,
                                        header=cycle)
        else:
            calls = []
            for part in parts:
                sub = check_identifier(f"{pname}{part.index}", self.rules,
                                       what="part program name", program=True)
                files += self._program_files(sub, program, part, names, robot, header=None)
                calls.append(sub)
            files.insert(0, self._main(pname, program, calls, robot, cycle))
        for f in files:
            check_lines(f.text, self.rules, f.name)
        return files

    def _names(self, program: NeutralProgram) -> dict[str, str]:
        out: dict[str, str] = {}
        back: dict[str, str] = {}
        for m in program.moves():
            for p in m.positions():
                if p.name in out:
                    continue
                prefix = "J" if p.joint_target else "P"
                ident = p.name.upper()
                if not ident.startswith(prefix):
                    ident = prefix + ident
                check_identifier(ident, self.rules, what=f"position {p.name!r} as", step=m.step)
                if ident in back and back[ident] != p.name:
                    raise ExportError(f"positions {back[ident]!r} and {p.name!r} would both be "
                                      f"{ident} (MELFA names are not case-sensitive)",
                                      step=m.step, dialect=self.rules.dialect)
                out[p.name], back[ident] = ident, p.name
        return out

    def _header(self, name: str, program: NeutralProgram, robot: Robot,
                cycle: str) -> list[str]:
        where = "below END" if self.single_file else f"{name}.POS"
        return [f"' {name}: generated by cellteach for {ascii_text(robot.name)}",
                f"' {cycle}",
                f"' positions in {where} (mm, deg); FL1 = 4 RIGHT + 2 ABOVE"
                + (" + 1 NONFLIP" if robot.dof >= 6 else ""),
                f"' {base_words(robot)}"]

    def _main(self, name: str, program: NeutralProgram, calls: list[str],
              robot: Robot, cycle: str) -> ProgramFile:
        lines = self._header(name, program, robot, cycle)[:2]
        lines.append(f"' main: runs {len(calls)} parts (positions per program limited)")
        lines += [f'CALLP "{c}"' for c in calls]
        lines.append("END")
        return ProgramFile(f"{name}{self.file_extensions[0]}", _number(lines), newline="\r\n")

    def _program_files(self, name: str, program: NeutralProgram, part, names: dict[str, str],
                       robot: Robot, *, header: str | None) -> list[ProgramFile]:
        lines = self._header(name, program, robot, header) if header is not None else [
            f"' {name}: part {part.index} of {program.name.upper()}"]
        if not program.tool.is_identity:
            lines.append(f"TOOL {self._pose_text(program.tool.T, 'tool')}")
        state = _State()
        prev: Position | None = part.start
        for ins, step in step_changes(part.instructions):
            if step is not None:
                lines.append(step_line("' ", step, self.rules.max_line - 6))
            if isinstance(ins, Move):
                lines += self._move(ins, prev, names, state)
                prev = ins.target
            elif isinstance(ins, Gripper):
                lines.append(f"{'HCLOSE' if ins.close else 'HOPEN'} {ins.hand}")
            elif isinstance(ins, SetOutput):
                lines.append(f"M_OUT({ins.channel})={1 if ins.value else 0}")
            elif isinstance(ins, Wait):
                lines.append(f"DLY {format_compact(ins.seconds, 2, what='wait', step=ins.step)}")
            elif isinstance(ins, Comment):
                lines += comment_lines("' ", ins.text, self.rules.max_line - 6)
        lines.append("END")
        pos_lines = [self._declaration(p, names[p.name], robot, program) for p in part.positions]
        ext = self.file_extensions[0]
        if self.single_file:
            return [ProgramFile(f"{name}{ext}", _number(lines) + "\n".join(pos_lines) + "\n",
                                newline="\r\n")]
        return [ProgramFile(f"{name}{ext}", _number(lines), newline="\r\n"),
                ProgramFile(f"{name}.POS", "\n".join(pos_lines) + "\n", newline="\r\n")]

    def _move(self, m: Move, prev: Position | None, names: dict[str, str],
              state: _State) -> list[str]:
        out: list[str] = []
        if m.kind == MoveKind.JOINT:
            if m.speed is not None:
                pct = _percent(m.speed, m.step)
                if self.variant == "V":
                    state.set(out, "jovrd", pct, f"JOVRD {pct}")
                else:
                    state.set(out, "ovrd", pct, f"OVRD {pct}")
        else:
            if self.variant == "IV":
                state.set(out, "ovrd", 100, "OVRD 100")
            if m.speed is not None:
                mm_s = int(round(m.speed * 1000.0))
                if mm_s < 1:
                    raise ExportError(f"speed {m.speed * 1000:.2f} mm/s is below MELFA's "
                                      "1 mm/s step", step=m.step)
                state.set(out, "spd", mm_s, f"SPD {mm_s}")
        if m.acceleration is not None:
            pct = _percent(m.acceleration, m.step)
            state.set(out, "accel", pct, f"ACCEL {pct},{pct}")
        if m.blend_radius > 0.0:
            r = format_compact(m.blend_radius * 1000.0, 1, what="blend radius", step=m.step)
            state.set(out, "cnt", r, f"CNT 1,{r},{r}")
        else:
            state.set(out, "cnt", 0, "CNT 0")
        tgt = names[m.target.name]
        if m.kind == MoveKind.JOINT:
            out.append(f"MOV {tgt}")
        elif m.kind == MoveKind.LINEAR:
            out.append(f"MVS {tgt}")
        elif m.kind == MoveKind.CIRCULAR:
            if prev is None:
                raise ExportError("MELFA's MVR needs the arc's start point: a circular move "
                                  "cannot come first", step=m.step)
            assert m.via is not None
            out.append(f"MVR {names[prev.name]},{names[m.via.name]},{tgt}")
        else:  # pragma: no cover - lowered to linear moves before writing
            raise AssertionError("spline moves are lowered before writing")
        return out

    def _declaration(self, p: Position, ident: str, robot: Robot,
                     program: NeutralProgram) -> str:
        if p.joint_target:
            slots = axis_slots(robot)
            vals = np.zeros(6)
            assert p.q is not None
            for j, s in enumerate(slots):
                vals[s - 1] = np.degrees(p.q[j])
            body = ",".join(format_fixed(v, 2, plus=True, what=f"{ident} joint") for v in vals)
            return f"{ident}=({body})"
        T = position_pose(robot, p)
        fl1, fl2 = self.flags(robot, p)
        return f"{ident}={self._pose_text(T, ident)}({fl1},{fl2})"

    def _pose_text(self, T: Array, what: str) -> str:
        A, B, C = melfa_abc(T)
        vals = list(T[:3, 3] * 1000.0) + euler_deg((A, B, C), 2)
        return "(" + ",".join(format_fixed(v, 2, plus=True, what=what) for v in vals) + ")"

    @staticmethod
    def flags(robot: Robot, p: Position) -> tuple[int, int]:
        """(FL1, FL2) from the planned joint solution (see the module docstring)."""
        if p.q is None:
            raise ExportError(f"position {p.name!r} has no joint solution for its flags")
        five = robot.dof < 6
        cfg = arm_configuration(robot, p.q, front_reference=FLANGE if five else WRIST)
        fl1 = (4 if cfg.front else 0) + (2 if cfg.elbow_up else 0)
        if not five and cfg.wrist_negative is not None:
            fl1 += 0 if cfg.wrist_negative else 1
        fl2 = 0
        for j, slot in enumerate(axis_slots(robot)):
            n = turn_count(float(p.q[j]))
            if not -8 <= n <= 7:
                raise ExportError(f"position {p.name!r}: {robot.joint_names[j]} turned "
                                  f"{n} times; FL2 holds -8..7")
            fl2 |= (n & 0xF) << (4 * (slot - 1))
        return fl1, fl2

    # ====================================================================== reading
    def read(self, files: Sequence[ProgramFile], robot: Robot) -> NeutralProgram:
        by_name = {f.name.upper(): f for f in files}
        progs = [f for f in files if f.name.upper().endswith(self.file_extensions[0])]
        if not progs:
            raise ExportError("no MELFA program file (.MB4/.MB5) among the files")
        called: set[str] = set()
        for f in progs:
            called |= {c.upper() for c in re.findall(r'CALLP\s+"([^"]+)"', f.text, re.I)}
        mains = [f for f in progs if f.name.upper().rsplit(".", 1)[0] not in called]
        if len(mains) != 1:
            raise ExportError(f"expected one main program, found {[f.name for f in mains]}")
        main = mains[0]
        name = main.name.rsplit(".", 1)[0]
        return self._read_program(name, by_name, robot, set())

    def _read_program(self, name: str, by_name: dict[str, ProgramFile], robot: Robot,
                      stack: set[str]) -> NeutralProgram:
        if name.upper() in stack:
            raise ExportError(f"program {name} calls itself")
        ext = self.file_extensions[0]
        f = by_name.get(f"{name.upper()}{ext.upper()}")
        if f is None:
            raise ExportError(f"program {name}{ext} is missing")
        body, tail = _split_steps(f.text)
        pos_file = by_name.get(f"{name.upper()}.POS")
        decl_lines = tail + (pos_file.text.splitlines() if pos_file else [])
        positions = self._read_positions(decl_lines, robot)
        prog = NeutralProgram(name)
        parts: list[NeutralProgram] = []
        step = ""
        ovrd: float | None = None
        jovrd: float | None = None
        speed_l: float | None = None
        accel: float | None = None
        blend = 0.0
        for line in body:
            up = line.upper()
            if line.startswith("'") or up.startswith("REM"):
                text = line[1:] if line.startswith("'") else line[3:]
                s = parse_step_comment(text)
                if s is not None:
                    step = s
                continue
            cmd, _, arg = up.partition(" ")
            arg = arg.strip()
            if cmd == "CALLP":
                sub = arg.strip('"')
                parts.append(self._read_program(sub, by_name, robot, stack | {name.upper()}))
            elif cmd == "TOOL":
                prog.tool = Frame("tool", _pose_from_text(arg))
            elif cmd == "OVRD":
                ovrd = parse_number(arg) / 100.0
            elif cmd == "JOVRD":
                jovrd = parse_number(arg) / 100.0
            elif cmd == "SPD":
                speed_l = parse_number(arg) / 1000.0
            elif cmd == "ACCEL":
                accel = parse_number(arg.split(",")[0]) / 100.0
            elif cmd == "CNT":
                vals = [parse_number(v) for v in arg.split(",")]
                blend = vals[1] / 1000.0 if vals[0] != 0 and len(vals) > 1 else 0.0
            elif cmd in ("MOV", "MVS", "MVR"):
                names = [a.strip() for a in arg.split(",")]
                try:
                    pts = [positions[n] for n in names]
                except KeyError as e:
                    raise ExportError(f"{name}: position {e.args[0]} is not declared") from None
                if cmd == "MOV":
                    speed_j = jovrd if self.variant == "V" else ovrd
                    prog.instructions.append(Move(MoveKind.JOINT, pts[0], speed=speed_j,
                                                  acceleration=accel, blend_radius=blend,
                                                  step=step))
                elif cmd == "MVS":
                    prog.instructions.append(Move(MoveKind.LINEAR, pts[0], speed=speed_l,
                                                  acceleration=accel, blend_radius=blend,
                                                  step=step))
                else:
                    prog.instructions.append(Move(MoveKind.CIRCULAR, pts[2], pts[1],
                                                  speed=speed_l, acceleration=accel,
                                                  blend_radius=blend, step=step))
            elif cmd in ("HOPEN", "HCLOSE"):
                prog.instructions.append(Gripper(int(parse_number(arg)), cmd == "HCLOSE", step))
            elif up.startswith("M_OUT("):
                m = re.fullmatch(r"M_OUT\((\d+)\)\s*=\s*([01])", up)
                if not m:
                    raise ExportError(f"{name}: cannot read {line!r}")
                prog.instructions.append(SetOutput(int(m.group(1)), m.group(2) == "1", step))
            elif cmd == "DLY":
                prog.instructions.append(Wait(parse_number(arg), step))
            elif cmd == "END":
                break
            else:
                raise ExportError(f"{name}: cannot read {line!r}")
        if parts:
            return flatten(parts, name)
        return prog

    def _read_positions(self, lines: list[str], robot: Robot) -> dict[str, Position]:
        out: dict[str, Position] = {}
        slots = axis_slots(robot)
        five = robot.dof < 6
        for raw in lines:
            line = raw.strip()
            if not line:
                continue
            m = re.fullmatch(r"(P\w*)=\(([^)]*)\)\((\d+),(\d+)\)", line, re.I)
            if m:
                T = _pose_from_text(f"({m.group(2)})")
                fl1, fl2 = int(m.group(3)), int(m.group(4))
                ranges = []
                for j, slot in enumerate(slots):
                    n = (fl2 >> (4 * (slot - 1))) & 0xF
                    n = n - 16 if n >= 8 else n
                    ranges.append(JointRange(j, (2 * n - 1) * np.pi, (2 * n + 1) * np.pi))
                cfg = ArmConfig(bool(fl1 & 4), bool(fl1 & 2),
                                None if five else not bool(fl1 & 1), tuple(ranges),
                                FLANGE if five else WRIST)
                out[m.group(1).upper()] = Position(m.group(1).upper(), T, None, cfg)
                continue
            m = re.fullmatch(r"(J\w*)=\(([^)]*)\)", line, re.I)
            if m:
                vals = np.radians([parse_number(v) for v in m.group(2).split(",")])
                q = np.array([vals[s - 1] for s in slots])
                out[m.group(1).upper()] = Position(m.group(1).upper(), None, q,
                                                   joint_target=True)
                continue
            raise ExportError(f"cannot read the position line {raw!r}")
        return out


# ------------------------------------------------------------------------------ helpers
class _State:
    """Controller settings already in force, so each is written only when it changes."""

    def __init__(self) -> None:
        self.values: dict[str, object] = {"cnt": 0}

    def set(self, out: list[str], key: str, value: object, text: str) -> None:
        if self.values.get(key) != value:
            self.values[key] = value
            out.append(text)


def _percent(fraction: float, step: str) -> int:
    pct = int(round(fraction * 100.0))
    if not 1 <= pct <= 100:
        raise ExportError(f"{fraction * 100:.1f} % is outside MELFA's 1..100 %", step=step)
    return pct


def _number(lines: list[str]) -> str:
    step = 10 if len(lines) * 10 <= MAX_STEP_NUMBER else 1
    if len(lines) * step > MAX_STEP_NUMBER:
        raise ExportError(f"{len(lines)} steps exceed MELFA's step numbers (1..32767); "
                          "lower max_positions_per_file to split the program")
    return "".join(f"{(k + 1) * step} {line}\n" for k, line in enumerate(lines))


def _split_steps(text: str) -> tuple[list[str], list[str]]:
    """Numbered program steps (numbers stripped) and unnumbered lines after them."""
    body, tail = [], []
    for raw in text.splitlines():
        line = raw.strip()
        if not line:
            continue
        m = re.fullmatch(r"(\d+)\s+(.*)", line)
        if m and not tail:
            body.append(m.group(2).strip())
        else:
            tail.append(line)
    return body, tail


def _pose_from_text(text: str) -> Array:
    vals = [parse_number(v) for v in text.strip().strip("()").split(",")]
    if len(vals) < 6:
        raise ExportError(f"a MELFA pose needs X,Y,Z,A,B,C: {text!r}")
    T = np.eye(4)
    T[:3, :3] = melfa_matrix(*np.radians(vals[3:6]))
    T[:3, 3] = np.array(vals[:3]) / 1000.0
    return T
