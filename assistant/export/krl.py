"""KUKA Robot Language (KRL): a ``NAME.src`` / ``NAME.dat`` pair, as written on the KRC.

The .src holds the motion (PTP, LIN, CIRC aux, target, optional SPLINE ... SPL ... ENDSPLINE
for free shapes, $VEL.CP, BAS (#VEL_PTP, n), $APO.CDIS with C_DIS, $BASE, $TOOL, $OUT[n],
WAIT SEC); the .dat declares the positions as E6POS {X,Y,Z,A,B,C,S,T,E1..E6} and joint
targets as E6AXIS, named X<name> as KUKA's inline forms do (point P7 -> XP7).

A, B, C are KUKA's Z-Y'-X'' angles (R = Rz(A) Ry(B) Rx(C)). Status S and Turn T come from the
planned joint solution (`configuration.arm_configuration`):

* S bit 0: wrist root point behind the A1 axis (overhead area) -> 1, in front -> 0;
* S bit 1: A3 >= phi, i.e. the wrist lies on the elbow-up side of the A2-A3 line -> 1;
* S bit 2: A5 < 0 -> 1;
* T bit n-1: axis An < 0 -> 1 (A1..A6; a 5-axis arm like the RV-2AJ has no A4).

A 7-axis arm (KUKA LBR convention, `redundant_axis`): its third joint is the external axis E1
of E6AXIS and E6POS (A1, A2, E1, A3, A4, A5, A6 along the chain), the others A1..A6.

LIN and CIRC ignore S and T on the controller (they keep the current branch); PTP uses them,
as the round-trip simulation does. Names: letters, digits and _, not starting with a digit,
at most 24 characters, not case-sensitive. Gripper n is output $OUT[gripper_output + n - 1]
(closed = TRUE); a plain output on that channel is refused.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from assistant.export import redundant_axis as ra
from assistant.export.configuration import ArmConfig, JointRange, arm_configuration, axis_slots
from assistant.export.cycle_time import CycleTime, predict_cycle_time
from assistant.export.dialect import (
    ProgramFile,
    ascii_text,
    base_words,
    check_axis_count,
    comment_lines,
    cut_long_splines,
    flatten,
    lower_splines,
    merge_smooth_splines,
    parse_step_comment,
    pose_in_work,
    position_pose,
    positions_to_base,
    split_into_parts,
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
    euler_deg,
    format_compact,
    format_fixed,
    parse_number,
)
from assistant.robots.model import Robot
from assistant.transforms import matrix_to_rpy, rpy_to_matrix

Array = np.ndarray

_RESERVED = frozenset({
    "AND", "ANIN", "ANOUT", "B_AND", "B_EXOR", "B_NOT", "B_OR", "BOOL", "BRAKE", "C_DIS",
    "C_ORI", "C_PTP", "C_SPL", "C_VEL", "CASE", "CAST_FROM", "CAST_TO", "CHAR", "CIRC",
    "CIRC_REL", "CONST", "CONTINUE", "DECL", "DEF", "DEFAULT", "DEFDAT", "DEFFCT", "DELAY",
    "DO", "ELSE", "END", "ENDDAT", "ENDFCT", "ENDFOR", "ENDIF", "ENDLOOP", "ENDSPLINE",
    "ENDSWITCH", "ENDWHILE", "ENUM", "EXIT", "EXT", "EXTFCT", "FALSE", "FOR", "GLOBAL", "GOTO",
    "HALT", "IF", "IMPORT", "INT", "INTERRUPT", "IS", "LIN", "LIN_REL", "LOOP", "MAXIMUM",
    "MINIMUM", "NOT", "OR", "PRIO", "PTP", "PTP_REL", "PUBLIC", "REAL", "REPEAT", "RESUME",
    "RETURN", "SEC", "SIGNAL", "SLIN", "SCIRC", "SPL", "SPLINE", "SPTP", "STEP", "STRUC",
    "SWITCH", "THEN", "TO", "TRIGGER", "TRUE", "UNTIL", "WAIT", "WHEN", "WHILE", "EXOR",
})


def krl_rules(max_positions_per_file: int | None = 500) -> DialectRules:
    return DialectRules(
        dialect="KUKA KRL",
        identifier=re.compile(r"[A-Za-z_][A-Za-z0-9_]*"),
        identifier_hint="letters, digits and _, not starting with a digit",
        max_identifier=24, max_line=255, max_positions_per_file=max_positions_per_file,
        reserved=_RESERVED, case_sensitive=False)


def kuka_abc(T: Array) -> tuple[float, float, float]:
    """KUKA (A, B, C) in rad: R = Rz(A) Ry(B) Rx(C)."""
    return matrix_to_rpy(T[:3, :3])


def frame_text(T: Array, what: str = "frame", step: str = "") -> str:
    a, b, c = euler_deg(kuka_abc(T), 3)
    x, y, z = T[:3, 3] * 1000.0
    f = [format_fixed(v, 3, what=what, step=step) for v in (x, y, z, a, b, c)]
    return f"X {f[0]},Y {f[1]},Z {f[2]},A {f[3]},B {f[4]},C {f[5]}"


@dataclass
class KrlDialect:
    """KRL writer and reader (KSS 8 syntax)."""

    spline: bool = True
    max_positions_per_file: int | None = 500
    gripper_output: int = 1

    name = "krl"
    title = "KUKA KRL"
    file_extensions = (".src", ".dat")
    #: Main axes A1..A6; a 7-axis arm's third joint is the external axis E1 (KUKA LBR).
    axis_counts = AXIS_COUNTS["krl"]
    axis_rule = ("KRL writes the main axes A1..A6 of 4- to 6-axis KUKA arms and a 7-axis "
                 "arm's third joint as E1 (KUKA LBR)")
    axes_beyond = "further axes would be external axes E2.., which this exporter does not write"

    @staticmethod
    def position_identifiers(name: str, joint_target: bool = False) -> tuple[str, ...]:
        """KUKA's convention: position P7 is the variable XP7 in the .dat file."""
        return ("X" + name,)

    def __post_init__(self) -> None:
        self.rules = krl_rules(self.max_positions_per_file)

    # ====================================================================== writing
    def lower(self, program: NeutralProgram) -> NeutralProgram:
        """Splines stay SPLINE blocks unless `spline` is off: segments that join tangentially
        are one block (no stop between them), a block ends with an exact stop and is cut into
        several when longer than a file may be."""
        if not self.spline:
            return lower_splines(program)
        program = merge_smooth_splines(program)
        program = cut_long_splines(program, self.rules.max_positions_per_file)
        out = [replace(i, blend_radius=0.0) if isinstance(i, Move) and i.kind == MoveKind.SPLINE
               else i for i in program.instructions]
        return replace(program, instructions=out)

    def write(self, program: NeutralProgram, robot: Robot, *,
              cycle_time: CycleTime | None = None) -> list[ProgramFile]:
        check_axis_count(self, robot)
        program = self.lower(program)
        name = check_identifier(program.name, self.rules, what="program name", program=True)
        names = self._names(program)
        self._check_outputs(program)
        cycle = (cycle_time or predict_cycle_time(program, robot)).header_text()
        parts = split_into_parts(program, self.rules.max_positions_per_file)
        files: list[ProgramFile] = []
        if len(parts) == 1:
            files += self._module(name, program, parts[0], names, robot, main=cycle)
        else:
            subs = []
            for part in parts:
                sub = check_identifier(f"{name}_{part.index}", self.rules,
                                       what="part program name", program=True)
                files += self._module(sub, program, part, names, robot, main=None)
                subs.append(sub)
            files.insert(0, self._main(name, program, subs, robot, cycle))
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
                ident = check_identifier("X" + p.name, self.rules,
                                         what=f"position {p.name!r} as", step=m.step)
                key = ident.upper()
                if key in back and back[key] != p.name:
                    raise ExportError(f"positions {back[key]!r} and {p.name!r} would both be "
                                      f"{ident} (KRL names are not case-sensitive)", step=m.step)
                out[p.name], back[key] = ident, p.name
        return out

    def _check_outputs(self, program: NeutralProgram) -> None:
        hands = {i.hand for i in program.instructions if isinstance(i, Gripper)}
        outs = {self.gripper_output + h - 1 for h in hands}
        for i in program.instructions:
            if isinstance(i, SetOutput) and i.channel in outs:
                raise ExportError(f"output $OUT[{i.channel}] is the gripper's output on this "
                                  "controller", step=i.step)

    def _head(self, name: str, robot: Robot, lines: list[str]) -> str:
        return "\n".join(["&ACCESS RVP", "&REL 1", f"DEF {name}( )"] + lines + ["END"]) + "\n"

    def _main(self, name: str, program: NeutralProgram, subs: list[str],
              robot: Robot, cycle: str) -> ProgramFile:
        lines = [f"; {name}: generated by cellteach for {ascii_text(robot.name)}",
                 f"; {cycle}",
                 f"; {base_words(robot)}",
                 f"; main: runs {len(subs)} parts (positions per file limited)",
                 ";FOLD INI", "  BAS (#INITMOV,0 )", ";ENDFOLD (INI)"]
        lines += self._frames(program)
        lines += [f"  {s}( )" for s in subs]
        return ProgramFile(f"{name}.src", self._head(name, robot, lines), newline="\r\n")

    def _frames(self, program: NeutralProgram) -> list[str]:
        tool = "$NULLFRAME" if program.tool.is_identity else (
            "{" + frame_text(program.tool.T, "tool") + "}")
        base = "$NULLFRAME" if program.work.is_identity else (
            "{" + frame_text(program.work.T, "base") + "}")
        return [f"  $TOOL = {tool}  ; {ascii_text(program.tool.name)}",
                f"  $BASE = {base}  ; {ascii_text(program.work.name)}"]

    def _module(self, name: str, program: NeutralProgram, part, names: dict[str, str],
                robot: Robot, *, main: str | None) -> list[ProgramFile]:
        """`main`: the predicted cycle time line of the main module, None for a part."""
        if main is not None:
            lines = [f"; {name}: generated by cellteach for {ascii_text(robot.name)}",
                     f"; {main}",
                     f"; {base_words(robot)}",
                     f"; positions in {name}.dat (mm, deg); S and T from the planned joints",
                     ";FOLD INI", "  BAS (#INITMOV,0 )", ";ENDFOLD (INI)"]
            lines += self._frames(program)
        else:
            lines = [f"; {name}: part {part.index} of {program.name}"]
        state: dict[str, object] = {}
        for ins, step in step_changes(part.instructions):
            if step is not None:
                lines.append(step_line("  ; ", step, self.rules.max_line))
            if isinstance(ins, Move):
                lines += self._settings(ins, state)
                if ins.kind == MoveKind.SPLINE:  # one block per (merged) spline move
                    lines.append("  SPLINE")
                    lines += [f"    SPL {names[p.name]}" for p in ins.positions()]
                    lines.append("  ENDSPLINE")
                else:
                    lines.append("  " + self._motion(ins, names))
            elif isinstance(ins, Gripper):
                out = self.gripper_output + ins.hand - 1
                word = "close" if ins.close else "open"
                lines.append(f"  $OUT[{out}] = {'TRUE' if ins.close else 'FALSE'}  "
                             f"; {word} gripper {ins.hand}")
            elif isinstance(ins, SetOutput):
                lines.append(f"  $OUT[{ins.channel}] = {'TRUE' if ins.value else 'FALSE'}")
            elif isinstance(ins, Wait):
                lines.append(f"  WAIT SEC {format_compact(ins.seconds, 3, step=ins.step)}")
            elif isinstance(ins, Comment):
                lines += comment_lines("  ; ", ins.text, self.rules.max_line)
        src = ProgramFile(f"{name}.src", self._head(name, robot, lines), newline="\r\n")
        decls = [self._declaration(p, names[p.name], robot, program) for p in part.positions]
        dat = ["&ACCESS RVP", "&REL 1", f"DEFDAT {name}",
               "; positions in $BASE: X, Y, Z mm; A, B, C deg (Z, Y', X''); S, T from joints"]
        dat += [f"  {d}" for d in decls] + ["ENDDAT"]
        return [src, ProgramFile(f"{name}.dat", "\n".join(dat) + "\n", newline="\r\n")]

    def _settings(self, m: Move, state: dict[str, object]) -> list[str]:
        out = []

        def put(key: str, value: object, text: str) -> None:
            if state.get(key) != value:
                state[key] = value
                out.append("  " + text)

        if m.kind == MoveKind.JOINT:
            if m.speed is not None:
                pct = _percent(m.speed, m.step)
                put("vel_ptp", pct, f"BAS (#VEL_PTP,{pct})")
            if m.acceleration is not None:
                pct = _percent(m.acceleration, m.step)
                put("acc_ptp", pct, f"BAS (#ACC_PTP,{pct})")
        else:
            if m.speed is not None:
                v = format_compact(m.speed, 4, what="speed", step=m.step)
                if float(v) <= 0.0:
                    raise ExportError(f"speed {m.speed} m/s rounds to 0", step=m.step)
                put("vel_cp", v, f"$VEL.CP = {v}")
            if m.acceleration is not None:
                pct = _percent(m.acceleration, m.step)
                put("acc_cp", pct, f"BAS (#ACC_CP,{pct})")
        if m.blend_radius > 0.0:
            r = format_compact(m.blend_radius * 1000.0, 1, what="blend", step=m.step)
            put("cdis", r, f"$APO.CDIS = {r}")
        return out

    def _motion(self, m: Move, names: dict[str, str]) -> str:
        approx = " C_DIS" if m.blend_radius > 0.0 else ""
        tgt = names[m.target.name]
        if m.kind == MoveKind.JOINT:
            return f"PTP {tgt}{approx}"
        if m.kind == MoveKind.LINEAR:
            return f"LIN {tgt}{approx}"
        assert m.via is not None
        return f"CIRC {names[m.via.name]}, {tgt}{approx}"

    def _declaration(self, p: Position, ident: str, robot: Robot,
                     program: NeutralProgram) -> str:
        if p.q is None:
            raise ExportError(f"position {p.name!r} has no joint solution")
        vals, e1 = ra.axis_values(axis_slots(robot), np.degrees(p.q))
        e1_text = "0.0" if e1 is None else format_fixed(e1, 3, what=ident)
        ext = f",E1 {e1_text},E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0"
        if p.joint_target:
            axes = ",".join(f"A{i + 1} {format_fixed(v, 3, what=ident)}"
                            for i, v in enumerate(vals))
            return f"DECL E6AXIS {ident}={{{axes}{ext}}}"
        T = pose_in_work(program, position_pose(robot, p))
        s, t = self.status_turn(robot, p)
        return f"DECL E6POS {ident}={{{frame_text(T, ident)},S {s},T {t}{ext}}}"

    @staticmethod
    def status_turn(robot: Robot, p: Position) -> tuple[int, int]:
        """(S, T) from the planned joint solution (see the module docstring)."""
        if p.q is None:
            raise ExportError(f"position {p.name!r} has no joint solution for S and T")
        cfg = arm_configuration(robot, p.q)
        s = (0 if cfg.front else 1) + (2 if cfg.elbow_up else 0) + (4 if cfg.wrist_negative
                                                                      else 0)
        t = 0
        for j, slot in enumerate(axis_slots(robot)):
            if p.q[j] < 0.0 and slot != ra.EXTERNAL_SLOT:
                t |= 1 << (slot - 1)
        return s, t

    # ====================================================================== reading
    def read(self, files: Sequence[ProgramFile], robot: Robot) -> NeutralProgram:
        srcs = {f.name.rsplit(".", 1)[0].upper(): f for f in files
                if f.name.lower().endswith(".src")}
        dats = {f.name.rsplit(".", 1)[0].upper(): f for f in files
                if f.name.lower().endswith(".dat")}
        if not srcs:
            raise ExportError("no .src file among the files")
        called = set()
        for f in srcs.values():
            called |= {c.upper() for c in re.findall(r"^\s*(\w+)\s*\(\s*\)\s*$", f.text, re.M)}
        mains = [k for k in srcs if k not in called]
        if len(mains) != 1:
            raise ExportError(f"expected one main .src, found {mains}")
        return positions_to_base(self._read_module(mains[0], srcs, dats, robot, set()))

    def _read_module(self, key: str, srcs: dict[str, ProgramFile], dats: dict[str, ProgramFile],
                     robot: Robot, stack: set[str]) -> NeutralProgram:
        if key in stack:
            raise ExportError(f"{key} calls itself")
        src = srcs[key]
        positions = self._read_dat(dats[key].text, robot) if key in dats else {}
        m = re.search(r"^\s*DEF\s+(\w+)\s*\(", src.text, re.M | re.I)
        prog = NeutralProgram(m.group(1) if m else key)
        parts: list[NeutralProgram] = []
        step = ""
        vel_ptp = vel_cp = acc_ptp = acc_cp = None
        cdis = 0.0
        in_spline = False
        spline_pts: list[Position] = []
        for raw in src.text.splitlines():
            line = raw.strip()
            if not line or line.startswith("&"):
                continue
            code, _, comment = line.partition(";")
            code = code.strip()
            if not code:
                s = parse_step_comment(comment)
                if s is not None:
                    step = s
                continue
            up = code.upper()

            def pos(n: str) -> Position:
                try:
                    return positions[n.strip().upper()]
                except KeyError:
                    raise ExportError(f"{key}: position {n.strip()} is not declared") from None

            if up.startswith("DEF ") or up == "END" or up.startswith("BAS (#INITMOV"):
                continue
            if up.startswith("$TOOL"):
                prog.tool = Frame(comment.strip() or "tool", _frame(code.split("=", 1)[1]))
            elif up.startswith("$BASE"):
                prog.work = Frame(comment.strip() or "base", _frame(code.split("=", 1)[1]))
            elif mm := re.fullmatch(r"BAS\s*\(#(VEL_PTP|ACC_PTP|ACC_CP),\s*([\d.]+)\s*\)", up):
                v = float(mm.group(2)) / 100.0
                if mm.group(1) == "VEL_PTP":
                    vel_ptp = v
                elif mm.group(1) == "ACC_PTP":
                    acc_ptp = v
                else:
                    acc_cp = v
            elif up.startswith("$VEL.CP"):
                vel_cp = parse_number(code.split("=", 1)[1])
            elif up.startswith("$APO.CDIS"):
                cdis = parse_number(code.split("=", 1)[1]) / 1000.0
            elif mm := re.fullmatch(r"(PTP|LIN|CIRC)\s+(.+?)(\s+C_DIS)?", code, re.I):
                kind = mm.group(1).upper()
                blend = cdis if mm.group(3) else 0.0
                args = [a for a in mm.group(2).split(",")]
                if kind == "PTP":
                    mv = Move(MoveKind.JOINT, pos(args[0]), speed=vel_ptp, acceleration=acc_ptp,
                              blend_radius=blend, step=step)
                elif kind == "LIN":
                    mv = Move(MoveKind.LINEAR, pos(args[0]), speed=vel_cp, acceleration=acc_cp,
                              blend_radius=blend, step=step)
                else:
                    mv = Move(MoveKind.CIRCULAR, pos(args[1]), pos(args[0]), speed=vel_cp,
                              acceleration=acc_cp, blend_radius=blend, step=step)
                prog.instructions.append(mv)
            elif up == "SPLINE":
                in_spline, spline_pts = True, []
            elif up.startswith("SPL "):
                if not in_spline:
                    raise ExportError(f"{key}: SPL outside a SPLINE block")
                spline_pts.append(pos(code[4:]))
            elif up == "ENDSPLINE":
                if not spline_pts:
                    raise ExportError(f"{key}: empty SPLINE block")
                prog.instructions.append(Move(MoveKind.SPLINE, spline_pts[-1],
                                              through=tuple(spline_pts[:-1]), speed=vel_cp,
                                              acceleration=acc_cp, step=step))
                in_spline = False
            elif mm := re.fullmatch(r"\$OUT\[(\d+)\]\s*=\s*(TRUE|FALSE)", up):
                ch, val = int(mm.group(1)), mm.group(2) == "TRUE"
                g = re.search(r"(open|close) gripper (\d+)", comment)
                if g:
                    prog.instructions.append(Gripper(int(g.group(2)), g.group(1) == "close",
                                                     step))
                else:
                    prog.instructions.append(SetOutput(ch, val, step))
            elif up.startswith("WAIT SEC"):
                prog.instructions.append(Wait(parse_number(code[8:]), step))
            elif mm := re.fullmatch(r"(\w+)\s*\(\s*\)", code):
                sub = mm.group(1).upper()
                if sub not in srcs:
                    raise ExportError(f"{key} calls {mm.group(1)}, which is not among the files")
                parts.append(self._read_module(sub, srcs, dats, robot, stack | {key}))
            else:
                raise ExportError(f"{key}.src: cannot read {line!r}")
        if parts:
            out = flatten(parts, prog.name)
            out.tool, out.work = prog.tool, prog.work
            return out
        return prog

    def _read_dat(self, text: str, robot: Robot) -> dict[str, Position]:
        out: dict[str, Position] = {}
        slots = axis_slots(robot)
        ext = ra.external_joint(slots)
        for raw in text.splitlines():
            line = raw.split(";", 1)[0].strip()
            mm = re.fullmatch(r"DECL\s+(E6POS|E6AXIS)\s+(\w+)\s*=\s*\{(.*)\}", line, re.I)
            if not mm:
                continue
            vals = {k.upper(): v for k, v in (
                item.strip().split(None, 1) for item in mm.group(3).split(","))}
            name = mm.group(2).upper()
            if ext is not None and "E1" not in vals:
                raise ExportError(f"{name}: the 7-axis arm's external axis E1 is missing")
            e1 = None if ext is None else (ext, np.radians(parse_number(vals["E1"])))
            if mm.group(1).upper() == "E6AXIS":
                main = np.radians([parse_number(vals.get(f"A{k}", "0")) for k in range(1, 7)])
                q = ra.joints_from_axes(slots, main, None if e1 is None else e1[1])
                out[name] = Position(name, None, q, joint_target=True)
                continue
            T = _frame("{" + ",".join(f"{k} {vals[k]}" for k in "XYZABC") + "}")
            s, t = int(parse_number(vals["S"])), int(parse_number(vals["T"]))
            ranges = tuple(JointRange(j, -1e9, 0.0) if t >> (slot - 1) & 1
                           else JointRange(j, 0.0, 1e9) for j, slot in enumerate(slots)
                           if slot != ra.EXTERNAL_SLOT)
            cfg = ArmConfig(not s & 1, bool(s & 2), bool(s & 4) if 5 in slots else None,
                            ranges, redundant=e1)
            out[name] = Position(name, T, None, cfg)
        return out


def _frame(text: str) -> Array:
    text = text.strip()
    if text.upper() == "$NULLFRAME":
        return np.eye(4)
    body = text.strip().strip("{}")
    if ":" in body:
        body = body.split(":", 1)[1]
    vals = {k.upper(): parse_number(v) for k, v in (
        item.strip().split(None, 1) for item in body.split(","))}
    T = np.eye(4)
    T[:3, :3] = rpy_to_matrix(*np.radians([vals.get("A", 0.0), vals.get("B", 0.0),
                                           vals.get("C", 0.0)]))
    T[:3, 3] = np.array([vals.get("X", 0.0), vals.get("Y", 0.0), vals.get("Z", 0.0)]) / 1000.0
    return T


def _percent(fraction: float, step: str) -> int:
    pct = int(round(fraction * 100.0))
    if not 1 <= pct <= 100:
        raise ExportError(f"{fraction * 100:.1f} % is outside 1..100 %", step=step)
    return pct
