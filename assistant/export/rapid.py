"""ABB RAPID: one module ``NAME.mod`` with tooldata, robtargets/jointtargets and PROC main.

Targets are ``CONST robtarget P7 := [[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[9E+09,...]]``
(mm; quaternion w, x, y, z with q1 >= 0; unused external axes as RAPID's 9E+09 placeholder),
joint targets ``CONST jointtarget`` (deg) moved to with MoveAbsJ. Motion: MoveJ, MoveL,
MoveC CirPoint, ToPoint with speeddata (predefined v100 etc. or declared vCell..) and
zonedata (fine, z5, ... or declared zCell..), tool and work object.

confdata from the planned joint solution:

* cf1, cf4, cf6: quadrant of axes 1, 4, 6, floor(angle / 90 deg) (0 when the axis is absent);
* cfx = 4 (wrist centre behind axis 1) + 2 (wrist centre behind the lower arm, i.e. elbow
  down) + 1 (axis 5 negative): the ABB table, from `configuration.arm_configuration`.

A 7-axis arm (IRB 14000 YuMi convention, `redundant_axis`): its third joint is the external
axis eax_a (deg) of jointtargets and robtargets, the others rax_1..rax_6.

RAPID speeds are TCP speeds, also for MoveJ: a joint move at fraction f of the maximum is
written with f x `joint_move_tcp_speed` (default 1000 mm/s, configurable per robot).
Identifiers: a letter, then letters, digits and _, at most 32 characters, not case-sensitive.
Outputs are signals named by `output_signal` ("do{n}"); gripper n is `gripper_signal`
("doGripper{n}", 1 = closed). Signal names must exist in the controller's I/O configuration.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from assistant.export.configuration import (
    ArmConfig,
    JointRange,
    arm_configuration,
    axis_slots,
    joint_for_slot,
    quadrant,
)
from assistant.export.cycle_time import CycleTime, predict_cycle_time
from assistant.export.dialect import (
    ProgramFile,
    ascii_text,
    base_words,
    check_axis_count,
    comment_lines,
    lower_splines,
    parse_step_comment,
    pose_in_base,
    pose_in_work,
    position_pose,
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
from assistant.export.redundant_axis import axis_values, external_joint, joints_from_axes
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

Array = np.ndarray

PREDEFINED_SPEEDS = (5, 10, 20, 30, 40, 50, 60, 80, 100, 150, 200, 300, 400, 500, 600, 800,
                     1000, 1500, 2000, 2500, 3000, 4000, 5000, 6000, 7000)
PREDEFINED_ZONES = (0, 1, 5, 10, 15, 20, 30, 40, 50, 60, 80, 100, 150, 200)
EXTERNAL = "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]"
NO_AXIS = 9e9

_RESERVED = frozenset({
    "ALIAS", "AND", "BACKWARD", "CASE", "CONNECT", "CONST", "DEFAULT", "DIV", "DO", "ELSE",
    "ELSEIF", "ENDFOR", "ENDFUNC", "ENDIF", "ENDMODULE", "ENDPROC", "ENDRECORD", "ENDTEST",
    "ENDTRAP", "ENDWHILE", "ERROR", "EXIT", "FALSE", "FOR", "FROM", "FUNC", "GOTO", "IF",
    "INOUT", "LOCAL", "MOD", "MODULE", "NOSTEPIN", "NOT", "NOVIEW", "OR", "PERS", "PROC",
    "RAISE", "READONLY", "RECORD", "RETRY", "RETURN", "STEP", "SYSMODULE", "TEST", "THEN",
    "TO", "TRAP", "TRUE", "TRYNEXT", "UNDO", "VAR", "VIEWONLY", "WHILE", "WITH", "XOR",
    "TOOL0", "WOBJ0", "LOAD0", "FINE", "VMAX", "MAIN",
} | {f"V{v}" for v in PREDEFINED_SPEEDS} | {f"Z{z}" for z in PREDEFINED_ZONES})


def rapid_rules(max_positions_per_file: int | None = 1000) -> DialectRules:
    return DialectRules(
        dialect="ABB RAPID",
        identifier=re.compile(r"[A-Za-z][A-Za-z0-9_]*"),
        identifier_hint="a letter, then letters, digits and _",
        max_identifier=32, max_line=255, max_positions_per_file=max_positions_per_file,
        reserved=_RESERVED, case_sensitive=False)


def quaternion_wxyz(R: Array) -> Array:
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    q = np.array([w, x, y, z])
    if round(abs(q[0]), 6) == 0.0:  # a half turn: w's sign is noise, fix the first shown
        return np.array(half_turn_sign(q, 6, skip=1))
    return -q if q[0] < 0.0 else q


def pose_text(T: Array, what: str) -> str:
    pos = ",".join(format_fixed(v, 3, what=what) for v in T[:3, 3] * 1000.0)
    quat = ",".join(format_fixed(v, 6, what=what) for v in quaternion_wxyz(T[:3, :3]))
    return f"[[{pos}],[{quat}]]"


@dataclass
class RapidDialect:
    """RAPID writer and reader (RobotWare 6 syntax)."""

    max_positions_per_file: int | None = 1000
    joint_move_tcp_speed: float = 1.0  # m/s written for a MoveJ at 100 %
    output_signal: str = "do{n}"
    gripper_signal: str = "doGripper{n}"
    default_joint_speed: float = 0.5
    default_linear_speed: float = 0.1

    name = "rapid"
    title = "ABB RAPID"
    file_extensions = (".mod",)
    #: Robot axes rax_1..rax_6; a 7-axis arm's third joint is the external axis eax_a.
    axis_counts = AXIS_COUNTS["rapid"]
    axis_rule = ("RAPID writes the robot axes rax_1..rax_6 of 4- to 6-axis ABB arms and a "
                 "7-axis arm's third joint as eax_a (IRB 14000 YuMi)")
    axes_beyond = ("further axes would be external axes eax_b.., which this exporter does not "
                   "write")

    def __post_init__(self) -> None:
        self.rules = rapid_rules(self.max_positions_per_file)

    # ====================================================================== writing
    def lower(self, program: NeutralProgram) -> NeutralProgram:
        """No spline instruction in RAPID: linear moves through the points, zoned."""
        return lower_splines(program)

    def write(self, program: NeutralProgram, robot: Robot, *,
              cycle_time: CycleTime | None = None) -> list[ProgramFile]:
        check_axis_count(self, robot)
        program = self.lower(program)
        name = check_identifier(program.name, self.rules, what="module name", program=True)
        names = self._names(program)
        cycle = (cycle_time or predict_cycle_time(program, robot)).header_text()
        tool = "tool0" if program.tool.is_identity else self._frame_ident("t", program.tool.name)
        wobj = "wobj0" if program.work.is_identity else self._frame_ident("w", program.work.name)
        parts = split_into_parts(program, self.rules.max_positions_per_file)
        data = _Data(self, tool, wobj)
        bodies = []
        for part in parts:
            bodies.append(self._body(part, names, data))
        head = [f"MODULE {name}",
                f"    ! {name}: generated by cellteach for {ascii_text(robot.name)}",
                f"    ! {cycle}",
                f"    ! {base_words(robot)}",
                f"    ! positions in {wobj} (mm; quaternion w,x,y,z); confdata from the "
                "planned joints"]
        if tool != "tool0":
            head.append(f"    PERS tooldata {tool} := [TRUE,{pose_text(program.tool.T, tool)},"
                        "[1,[0,0,1],[1,0,0,0],0,0,0]];")
            head.append("    ! tool load is a placeholder (1 kg): identify it before production")
        if wobj != "wobj0":
            head.append(f"    TASK PERS wobjdata {wobj} := [FALSE,TRUE,\"\","
                        f"{pose_text(program.work.T, wobj)},[[0,0,0],[1,0,0,0]]];")
        head += data.declarations()
        files = []
        if len(parts) == 1:
            decl = [self._declaration(p, names[p.name], robot, program)
                    for p in parts[0].positions]
            text = "\n".join(head + [f"    {d}" for d in decl] + ["", "    PROC main()"]
                             + bodies[0] + ["    ENDPROC", "ENDMODULE"]) + "\n"
            files.append(ProgramFile(f"{name}.mod", text, newline="\r\n"))
        else:
            subs = []
            for part, body in zip(parts, bodies, strict=True):
                sub = check_identifier(f"{name}_{part.index}", self.rules,
                                       what="part module name", program=True)
                subs.append(sub)
                decl = [self._declaration(p, names[p.name], robot, program)
                        for p in part.positions]
                text = "\n".join([f"MODULE {sub}", f"    ! part {part.index} of {name}"]
                                 + [f"    {d}" for d in decl]
                                 + ["", f"    PROC {sub}()"] + body
                                 + ["    ENDPROC", "ENDMODULE"]) + "\n"
                files.append(ProgramFile(f"{sub}.mod", text, newline="\r\n"))
            text = "\n".join(head + ["", "    PROC main()",
                                     f"        ! runs {len(subs)} parts (positions per module "
                                     "limited)"]
                             + [f"        {s};" for s in subs]
                             + ["    ENDPROC", "ENDMODULE"]) + "\n"
            files.insert(0, ProgramFile(f"{name}.mod", text, newline="\r\n"))
        for f in files:
            check_lines(f.text, self.rules, f.name)
        return files

    def _frame_ident(self, prefix: str, name: str) -> str:
        word = re.sub(r"[^A-Za-z0-9]+", "_", name).strip("_") or "cell"
        ident = prefix + word[:1].upper() + word[1:]
        return check_identifier(ident[: self.rules.max_identifier], self.rules, what="frame")

    def _names(self, program: NeutralProgram) -> dict[str, str]:
        out: dict[str, str] = {}
        back: dict[str, str] = {}
        for m in program.moves():
            for p in m.positions():
                if p.name in out:
                    continue
                ident = check_identifier(p.name, self.rules, what="position", step=m.step)
                key = ident.upper()
                if key in back and back[key] != p.name:
                    raise ExportError(f"positions {back[key]!r} and {p.name!r} differ only in "
                                      "case (RAPID names are not case-sensitive)", step=m.step)
                out[p.name], back[key] = ident, p.name
        return out

    def _body(self, part, names: dict[str, str], data: _Data) -> list[str]:
        lines: list[str] = []
        hands = {i.hand for i in part.instructions if isinstance(i, Gripper)}
        for ins, step in step_changes(part.instructions):
            if step is not None:
                lines.append(step_line("        ! ", step, self.rules.max_line))
            if isinstance(ins, Move):
                lines.append("        " + self._motion(ins, names, data))
            elif isinstance(ins, Gripper):
                sig = self.gripper_signal.format(n=ins.hand)
                lines.append(f"        SetDO {sig}, {1 if ins.close else 0};")
            elif isinstance(ins, SetOutput):
                sig = self.output_signal.format(n=ins.channel)
                if any(sig == self.gripper_signal.format(n=h) for h in hands):
                    raise ExportError(f"output {sig} is the gripper's signal", step=ins.step)
                lines.append(f"        SetDO {sig}, {1 if ins.value else 0};")
            elif isinstance(ins, Wait):
                lines.append(f"        WaitTime {format_compact(ins.seconds, 3, step=ins.step)};")
            elif isinstance(ins, Comment):
                lines += comment_lines("        ! ", ins.text, self.rules.max_line)
        return lines

    def _motion(self, m: Move, names: dict[str, str], data: _Data) -> str:
        speed = data.speed(m)
        zone = data.zone(m)
        tail = f"{speed}, {zone}, {data.tool}\\WObj:={data.wobj};"
        tgt = names[m.target.name]
        if m.kind == MoveKind.JOINT:
            if m.target.joint_target:
                return f"MoveAbsJ {tgt}\\NoEOffs, {tail}"
            return f"MoveJ {tgt}, {tail}"
        if m.kind == MoveKind.LINEAR:
            return f"MoveL {tgt}, {tail}"
        assert m.via is not None
        return f"MoveC {names[m.via.name]}, {tgt}, {tail}"

    def _declaration(self, p: Position, ident: str, robot: Robot,
                     program: NeutralProgram) -> str:
        if p.q is None:
            raise ExportError(f"position {p.name!r} has no joint solution")
        vals, eax_a = axis_values(axis_slots(robot), np.degrees(p.q))
        ext = EXTERNAL if eax_a is None else \
            f"[{format_fixed(eax_a, 3, what=ident)}{EXTERNAL[6:]}"
        if p.joint_target:
            axes = ",".join(format_fixed(v, 3, what=ident) for v in vals)
            return f"CONST jointtarget {ident} := [[{axes}],{ext}];"
        T = pose_in_work(program, position_pose(robot, p))
        conf = ",".join(str(v) for v in self.confdata(robot, p))
        return f"CONST robtarget {ident} := [{pose_text(T, ident)[1:-1]},[{conf}],{ext}];"

    @staticmethod
    def confdata(robot: Robot, p: Position) -> tuple[int, int, int, int]:
        """[cf1, cf4, cf6, cfx] from the planned joint solution (see the module docstring)."""
        if p.q is None:
            raise ExportError(f"position {p.name!r} has no joint solution for its confdata")
        cfg = arm_configuration(robot, p.q)
        cf = []
        for slot in (1, 4, 6):
            j = joint_for_slot(robot, slot)
            cf.append(0 if j is None else quadrant(float(p.q[j])))
        cfx = (0 if cfg.front else 4) + (0 if cfg.elbow_up else 2) + (
            1 if cfg.wrist_negative else 0)
        return cf[0], cf[1], cf[2], cfx

    # ====================================================================== reading
    def read(self, files: Sequence[ProgramFile], robot: Robot) -> NeutralProgram:
        decls: dict[str, Position] = {}
        speeds: dict[str, float] = {}
        zones: dict[str, float] = {}
        frames: dict[str, Frame] = {"TOOL0": Frame("tool0"), "WOBJ0": Frame("wobj0")}
        procs: dict[str, list[str]] = {}
        main_module = None
        for f in files:
            mod = re.search(r"^\s*MODULE\s+(\w+)", f.text, re.M | re.I)
            cur: str | None = None
            for raw in f.text.splitlines():
                line = raw.strip()
                if not line:
                    continue
                up = line.upper()
                if mm := re.fullmatch(r"PROC\s+(\w+)\s*\(\s*\)", line, re.I):
                    cur = mm.group(1).upper()
                    procs[cur] = []
                    if cur == "MAIN":
                        main_module = mod.group(1) if mod else f.name
                    continue
                if up == "ENDPROC":
                    cur = None
                    continue
                if cur is not None:
                    procs[cur].append(line)
                    continue
                self._read_declaration(line, decls, speeds, zones, frames, robot)
        if "MAIN" not in procs:
            raise ExportError("no PROC main() among the modules")
        prog = NeutralProgram(main_module or "main")
        self._read_proc("MAIN", procs, decls, speeds, zones, frames, prog, set())
        return prog

    def _read_declaration(self, line: str, decls, speeds, zones, frames, robot: Robot) -> None:
        if line.startswith("!") or line.upper().startswith(("MODULE", "ENDMODULE")):
            return
        mm = re.fullmatch(r"(?:TASK\s+)?(CONST|PERS)\s+(\w+)\s+(\w+)\s*:=\s*(.*);", line, re.I)
        if not mm:
            raise ExportError(f"cannot read {line!r}")
        typ, name, val = mm.group(2).lower(), mm.group(3).upper(), mm.group(4)
        nums = [parse_number(v) for v in re.findall(r"[-+]?[\d.]+(?:E[+-]?\d+)?", val, re.I)]
        if typ == "robtarget":
            T = _pose(nums[0:7])
            cf1, cf4, cf6, cfx = (int(v) for v in nums[7:11])
            ranges = []
            for slot, cf in ((1, cf1), (4, cf4), (6, cf6)):
                j = joint_for_slot(robot, slot)
                if j is not None:
                    ranges.append(JointRange(j, cf * np.pi / 2, (cf + 1) * np.pi / 2))
            has5 = joint_for_slot(robot, 5) is not None
            eax_a = _eax_a(robot, nums[11], name)
            cfg = ArmConfig(not cfx & 4, not cfx & 2, bool(cfx & 1) if has5 else None,
                            tuple(ranges), redundant=eax_a)
            decls[name] = Position(name, T, None, cfg)
        elif typ == "jointtarget":
            eax_a = _eax_a(robot, nums[6], name)
            q = joints_from_axes(axis_slots(robot), np.radians(nums[0:6]),
                                 None if eax_a is None else eax_a[1])
            decls[name] = Position(name, None, q, joint_target=True)
        elif typ == "speeddata":
            speeds[name] = nums[0] / 1000.0
        elif typ == "zonedata":
            zones[name] = nums[0] / 1000.0
        elif typ in ("tooldata", "wobjdata"):
            frames[name] = Frame(name, _pose(nums[0:7]))
        else:
            raise ExportError(f"cannot read declarations of type {typ}")

    def _read_proc(self, proc: str, procs, decls, speeds, zones, frames,
                   prog: NeutralProgram, stack: set[str]) -> None:
        if proc in stack:
            raise ExportError(f"PROC {proc} calls itself")
        step = ""
        for line in procs[proc]:
            up = line.upper()
            if line.startswith("!"):
                s = parse_step_comment(line[1:])
                if s is not None:
                    step = s
                continue
            if mm := re.fullmatch(r"(MoveJ|MoveL|MoveC|MoveAbsJ)\s+(.*);", line, re.I):
                kind = mm.group(1).upper()
                args = [a.strip() for a in mm.group(2).split(",")]
                npos = 2 if kind == "MOVEC" else 1
                pos_names = [a.split("\\")[0].upper() for a in args[:npos]]
                speed_name, zone_name = args[npos].upper(), args[npos + 1].upper()
                tool_name, _, wobj_name = args[npos + 2].upper().partition("\\WOBJ:=")
                prog.tool = frames[tool_name]
                prog.work = frames[wobj_name or "WOBJ0"]
                try:
                    pts = [decls[n] for n in pos_names]
                except KeyError as e:
                    raise ExportError(f"position {e.args[0]} is not declared") from None
                v = _speed(speed_name, speeds)
                blend = _zone(zone_name, zones)
                if kind in ("MOVEJ", "MOVEABSJ"):
                    mv = Move(MoveKind.JOINT, pts[0], speed=v / self.joint_move_tcp_speed,
                              blend_radius=blend, step=step)
                elif kind == "MOVEL":
                    mv = Move(MoveKind.LINEAR, pts[0], speed=v, blend_radius=blend, step=step)
                else:
                    mv = Move(MoveKind.CIRCULAR, pts[1], pts[0], speed=v, blend_radius=blend,
                              step=step)
                prog.instructions.append(mv)
            elif mm := re.fullmatch(r"SetDO\s+(\w+)\s*,\s*([01])\s*;", line, re.I):
                sig, val = mm.group(1), mm.group(2) == "1"
                g = _match_signal(self.gripper_signal, sig)
                o = _match_signal(self.output_signal, sig)
                if g is not None:
                    prog.instructions.append(Gripper(g, val, step))
                elif o is not None:
                    prog.instructions.append(SetOutput(o, val, step))
                else:
                    raise ExportError(f"unknown signal {sig}")
            elif up.startswith("WAITTIME"):
                prog.instructions.append(Wait(parse_number(line[8:].rstrip(";")), step))
            elif mm := re.fullmatch(r"(\w+)\s*;", line):
                self._read_proc(mm.group(1).upper(), procs, decls, speeds, zones, frames,
                                prog, stack | {proc})
            else:
                raise ExportError(f"cannot read {line!r}")
        if proc == "MAIN":
            self._to_base(prog)

    @staticmethod
    def _to_base(prog: NeutralProgram) -> None:
        if prog.work.is_identity:
            return
        cache: dict[int, Position] = {}

        def conv(p: Position | None) -> Position | None:
            if p is None or p.T_base_tool is None:
                return p
            if id(p) not in cache:
                cache[id(p)] = replace(p, T_base_tool=pose_in_base(prog.work.T, p.T_base_tool))
            return cache[id(p)]

        prog.instructions = [replace(i, target=conv(i.target), via=conv(i.via))
                             if isinstance(i, Move) else i for i in prog.instructions]


class _Data:
    """speeddata / zonedata used by the program: predefined names or declared ones."""

    def __init__(self, dialect: RapidDialect, tool: str, wobj: str):
        self.d = dialect
        self.tool, self.wobj = tool, wobj
        self.speeds: dict[str, str] = {}
        self.zones: dict[str, str] = {}
        self.last_joint: float | None = None
        self.last_linear: float | None = None

    def speed(self, m: Move) -> str:
        if m.kind == MoveKind.JOINT:
            f = m.speed if m.speed is not None else (self.last_joint or self.d.default_joint_speed)
            self.last_joint = f
            mm_s = f * self.d.joint_move_tcp_speed * 1000.0
        else:
            v = m.speed if m.speed is not None else (
                self.last_linear or self.d.default_linear_speed)
            self.last_linear = v
            mm_s = v * 1000.0
        text = format_compact(mm_s, 1, what="speed", step=m.step)
        if float(text) <= 0.0:
            raise ExportError(f"speed {mm_s:.3f} mm/s rounds to 0", step=m.step)
        if float(text) in PREDEFINED_SPEEDS:
            return f"v{text}"
        name = "vCell" + text.replace(".", "_")
        self.speeds[name] = f"CONST speeddata {name} := [{text},500,5000,1000];"
        return name

    def zone(self, m: Move) -> str:
        if m.blend_radius <= 0.0:
            return "fine"
        r = float(format_compact(m.blend_radius * 1000.0, 1, what="zone", step=m.step))
        text = format_compact(r, 1)
        if r in PREDEFINED_ZONES:
            return f"z{text}"
        name = "zCell" + text.replace(".", "_")
        ori, ang = format_compact(1.5 * r, 2), format_compact(0.15 * r, 3)
        self.zones[name] = (f"CONST zonedata {name} := [FALSE,{text},{ori},{ori},{ang},{ori},"
                            f"{ang}];")
        return name

    def declarations(self) -> list[str]:
        return [f"    {v}" for v in list(self.speeds.values()) + list(self.zones.values())]


def _eax_a(robot: Robot, deg: float, name: str) -> tuple[int, float] | None:
    """(joint, value rad) a target's eax_a (deg) holds on a 7-axis arm; None for others."""
    j = external_joint(axis_slots(robot))
    if j is not None and deg >= NO_AXIS:
        raise ExportError(f"{name}: the 7-axis arm's external axis eax_a is 9E9")
    return None if j is None else (j, float(np.radians(deg)))


def _pose(v: list[float]) -> Array:
    T = np.eye(4)
    T[:3, 3] = np.array(v[0:3]) / 1000.0
    w, x, y, z = v[3:7]
    q = np.array([x, y, z, w])
    T[:3, :3] = Rotation.from_quat(q / np.linalg.norm(q)).as_matrix()
    return T


def _speed(name: str, declared: dict[str, float]) -> float:
    if name in declared:
        return declared[name]
    mm = re.fullmatch(r"V(\d+)", name)
    if not mm:
        raise ExportError(f"unknown speeddata {name}")
    return int(mm.group(1)) / 1000.0


def _zone(name: str, declared: dict[str, float]) -> float:
    if name == "FINE":
        return 0.0
    if name in declared:
        return declared[name]
    mm = re.fullmatch(r"Z(\d+)", name)
    if not mm:
        raise ExportError(f"unknown zonedata {name}")
    return int(mm.group(1)) / 1000.0


def _match_signal(pattern: str, sig: str) -> int | None:
    rx = re.escape(pattern).replace(re.escape("{n}"), r"(\d+)")
    mm = re.fullmatch(rx, sig, re.I)
    return int(mm.group(1)) if mm else None
