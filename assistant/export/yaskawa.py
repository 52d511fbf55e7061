"""Yaskawa Motoman INFORM: one job ``NAME.JBI`` per program, as a YRC1000 loads it.

A job is ``/JOB``, ``//NAME``, ``//POS`` (``///NPOS``, ``///TOOL``, ``///USER``,
``///POSTYPE``, ``///RECTAN``, ``///RCONF`` and the teaching positions ``C00000=...``),
``//INST`` (``///DATE``, ``///COMM``, ``///ATTR``, ``///GROUP1``), then the instructions
from ``NOP`` to ``END``. Motions: ``MOVJ C00000 VJ=50.00`` (joint speed in % of the axes'
maxima, so never above the robot's joint speeds), ``MOVL C00001 V=100.0`` (mm/s) and circular
arcs as three ``MOVC`` steps - start (the previous target again, a zero-length step), via,
end; when the next motion step is an arc too, its end gets ``FPT`` and the next arc starts
there without repeating it. ``ACC=`` (20..100 %) where the program sets an acceleration.

Blending: ``PL=n`` (0..8) rounds a corner within the positioning zone of level n, which is
a controller parameter (S1CxG033..040), not part of the job. Unless `position_levels_mm`
gives those zones (mm, PL=1..8), every move ends exactly at its point (no PL tag) - the
strictest reading of a controller whose zones are unknown - and the export says so once; with
them, a blend of radius r is written as the highest level whose zone is at most r.

Positions are Cartesian (``///RECTAN``, ``///POSTYPE BASE``, or ``USER`` with ``///USER n``
for a work frame): X, Y, Z in mm and Rx, Ry, Rz in deg about the fixed X, Y, Z axes (R =
Rz Ry Rx), with the manipulator type ``///RCONF l,m,n,o,p,q,0..`` from the planned joints
(NX100/DX100 manuals, "Manipulator Types"; the last 18 are unused): l 0 Flip / 1 No-flip
by the R axis (Flip: -90 < R <= 90 deg, or beyond +-270), m 0 upper arm (elbow up) / 1 lower
arm, n 0 front / 1 rear (wrist centre and the S axis), o, p, q: R, T, S >= 180 deg (1) or
not (-180 < angle <= 180). Axes the arm lacks count as 0. Pulse positions need each axis'
pulses per degree, a controller parameter that is not public per model: none are written.
RCONF has no flag for the L, U and B axes; where one of them could turn a full turn inside
the robot's limits (a UR's shoulder, +-360 deg; no Motoman arm's) the controller has to
take the posture nearest the current one, as the read-back does - the export says so.

INFORM has no names for positions: the operator's name is a comment before each motion
(``'to P7``, ``'via P6``, ``'from P5``), where the reader takes it back. Outputs are
``DOUT OT#(n) ON``; gripper n is output ``gripper_output + n - 1`` (ON = closed), announced
by ``'close gripper 1`` and followed by ``TIMER T=`` `gripper_wait_s`; waits are ``TIMER
T=0.50``. The tool and user frame are controller data (``///TOOL``, ``///USER`` select them
by number); their values are given in comments. YRC1000 limits: job names of 32 characters
(letters, digits, _), comments of 32 characters (wrapped), and jobs of at most `max_lines`
instructions (2000, RoboDK's Motoman post's page: the YRC1000 limit depends on its memory),
a longer program is split into jobs a main job CALLs, with a note. A 7-axis (SIA/SDA) arm's
Cartesian positions carry its elbow angle Re, which Yaskawa does not define publicly: refused.
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
    with_arc_start,
    xyz_fixed_angles,
    xyz_fixed_matrix,
)
from assistant.export.dialect_names import AXIS_COUNTS
from assistant.export.errors import ExportError
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
from assistant.export.yaskawa_jbi import parse_jbi
from assistant.robots.model import Robot

Array = np.ndarray

#: RCONF values after the six types (unused, written as 0 as the DX100/YRC1000 format has it).
RCONF_UNUSED = 18
#: Fixed date: the same program gives the same bytes.
DATE = "2020/01/01 00:00"


def yaskawa_rules(max_positions_per_file: int | None = None) -> DialectRules:
    return DialectRules(
        dialect="Yaskawa INFORM", identifier=re.compile(r"[A-Za-z][A-Za-z0-9_]*"),
        identifier_hint="letters, digits and _, starting with a letter (a name comment)",
        max_identifier=COMMENT_LENGTH - len("from "), max_line=255,
        max_positions_per_file=max_positions_per_file, case_sensitive=False,
        program_identifier=re.compile(r"[A-Z][A-Z0-9_]*"),
        program_hint="upper-case letters, digits and _, starting with a letter",
        max_program_name=32)


@dataclass
class YaskawaDialect:
    """Yaskawa INFORM (.JBI) writer and reader."""

    tool: int = 1
    user_frame: int = 1
    gripper_output: int = 1
    gripper_wait_s: float = 0.3
    #: Positioning zones of PL=1..8 in mm as set on the controller; None: unknown.
    position_levels_mm: tuple[float, ...] | None = None
    max_positions_per_file: int | None = None
    max_lines: int = 2000

    name = "yaskawa"
    title = "Yaskawa INFORM (.JBI)"
    file_extensions = (".JBI",)
    #: Motoman arms: 4-axis palletizers, 5- and 6-axis arms (7-axis SIA/SDA: see below).
    axis_counts = AXIS_COUNTS["yaskawa"]
    axis_rule = "INFORM Cartesian positions are written here for 4- to 6-axis Motoman arms"
    axes_beyond = ("a 7-axis arm's (SIA, SDA) Cartesian positions carry its elbow angle Re, "
                   "which Yaskawa does not define publicly, and pulse positions need the "
                   "controller's pulses per degree")

    @staticmethod
    def position_identifiers(name: str, joint_target: bool = False) -> tuple[str, ...]:
        """The name comment before a motion step: the name itself."""
        return (name,)

    def __post_init__(self) -> None:
        self.rules = yaskawa_rules(self.max_positions_per_file)
        zones = self.position_levels_mm
        if zones is not None and (len(zones) != 8 or list(zones) != sorted(zones)
                                  or min(zones) <= 0.0):
            raise ValueError("position_levels_mm: eight increasing zones (mm) for PL=1..8")

    # ====================================================================== writing
    def lower(self, program: NeutralProgram) -> NeutralProgram:
        """No splines in INFORM here (lines through their points); settings as written:
        VJ in 0.01 %, V in 0.1 mm/s, ACC in whole %, blends as the PL zones allow, waits in
        0.01 s (a zero wait is no instruction)."""
        program = settle_values(
            lower_splines(program),
            joint_speed=lambda v, m: _vj(v, m.step) / 100.0,
            cartesian_speed=lambda v, m: _v(v, m.step) / 1000.0,
            blend=lambda r, m: self._zone(self._level(r)),
            acceleration=lambda a, m: _acc(a, m.step) / 100.0,
            wait=lambda s, w: round(s, 2))
        program.instructions = [i for i in program.instructions
                                if not (isinstance(i, Wait) and i.seconds <= 0.0)]
        return program

    def _level(self, radius: float) -> int:
        zones = self.position_levels_mm
        if zones is None:
            return 0
        return max((k for k, z in enumerate(zones, start=1) if z <= radius * 1000.0 + 1e-9),
                   default=0)

    def _zone(self, level: int) -> float:
        if level == 0:
            return 0.0
        if self.position_levels_mm is None:
            raise ExportError(f"PL={level}: the positioning zones are not known "
                              "(position_levels_mm)")
        return self.position_levels_mm[level - 1] / 1000.0

    def write(self, program: NeutralProgram, robot: Robot, *,
              cycle_time: CycleTime | None = None) -> list[ProgramFile]:
        return self.write_noted(program, robot, cycle_time=cycle_time)[0]

    def write_noted(self, program: NeutralProgram, robot: Robot, *,
                    cycle_time: CycleTime | None = None
                    ) -> tuple[list[ProgramFile], tuple[str, ...]]:
        """The job files and what the operator should know (split, blends, postures)."""
        check_axis_count(self, robot)
        blended = any(m.blend_radius > 0.0 for m in lower_splines(program).moves())
        program = self.lower(program)
        name = check_identifier(program.name.upper(), self.rules, what="job name",
                                program=True)
        check_position_names(program, self.rules)
        check_output_channels(program, self.gripper_output, lambda n: f"OT#({n})")
        cycle = cycle_time or predict_cycle_time(program, robot)
        notes: list[str] = []
        if blended and self.position_levels_mm is None:
            notes.append("blends are written as exact stops (no PL): the positioning zones "
                         "of PL=1..8 are controller parameters (S1CxG033..040) not known here")
        free = self._turn_notes(program, robot)
        if free:
            notes.append(free)
        head = len(self._header(name, robot, cycle)) + 2  # and NOP, END
        parts = parts_within(program, self.rules.max_positions_per_file, self.max_lines,
                             lambda p: head + len(self._inst(program, p, head=True)),
                             with_arc_start, what="a Yaskawa job")
        if len(parts) == 1:
            files = [self._job(name, program, parts[0], robot, cycle=cycle)]
        else:
            subs = part_names(name, len(parts), self.rules.max_program_name or 32)
            files = [self._job(sub, program, part, robot, cycle=None)
                     for sub, part in zip(subs, parts, strict=True)]
            files.insert(0, self._main(name, program, subs, robot, cycle))
            notes.append(f"the program is split into {len(parts)} jobs ({', '.join(subs)}) "
                         f"that {name} calls: a job holds at most {self.max_lines} "
                         "instructions here"
                         + (f" and {self.rules.max_positions_per_file} positions"
                            if self.rules.max_positions_per_file else ""))
        for f in files:
            check_lines(f.text, self.rules, f.name)
        return files, tuple(notes)

    def _turn_notes(self, program: NeutralProgram, robot: Robot) -> str:
        names, joints = [], set()
        for p in program.positions():
            if p.q is None:
                raise ExportError(f"position {p.name!r} has no joint solution")
            free = turn_ambiguous_joints(robot, p.q, _flag_function(robot, p.q))
            if free:
                names.append(p.name)
                joints |= set(free)
        if not names:
            return ""
        return (f"{', '.join(robot.joint_names[j] for j in sorted(joints))} can turn a full "
                f"turn within this arm's limits and RCONF has no flag for it: at "
                f"{', '.join(names)} the controller must take the posture nearest the "
                "current one (no Motoman arm's L, U or B axis turns that far)")

    # ------------------------------------------------------------------ jobs
    def _main(self, name: str, program: NeutralProgram, subs: list[str], robot: Robot,
              cycle: CycleTime) -> ProgramFile:
        inst = self._header(name, robot, cycle) + [f"'main: runs {len(subs)} jobs"]
        inst += self._frames(program)
        inst += [f"CALL JOB:{s}" for s in subs]
        return self._assemble(name, program, [], inst, robot, cycle)

    def _job(self, name: str, program: NeutralProgram, part: Part, robot: Robot, *,
             cycle: CycleTime | None) -> ProgramFile:
        head = self._header(name, robot, cycle) if cycle is not None else [
            f"'{name}: part {part.index} of"[:COMMENT_LENGTH + 1],
            f"'{program.name.upper()}"[:COMMENT_LENGTH + 1]]
        inst = head + self._inst(program, part, head=cycle is not None)
        return self._assemble(name, program, part.positions, inst, robot, cycle)

    def _header(self, name: str, robot: Robot, cycle: CycleTime) -> list[str]:
        predicted, _, caveat = cycle.header_text().partition(" (")
        lines = [f"{name}: generated by cellteach", f"for {ascii_text(robot.name)}",
                 predicted, f"({caveat}", "positions in mm and deg, RCONF",
                 "from the planned joints", base_words(robot)]
        return [c for text in lines for c in short_comments("'", text)]

    def _frames(self, program: NeutralProgram) -> list[str]:
        out = ["'frames to set on the controller"]
        out += frame_comments("'", f"TOOL {self.tool}", program.tool, ("Rx", "Ry", "Rz"), 4)
        if not program.work.is_identity:
            out += frame_comments("'", f"USER {self.user_frame}", program.work,
                                   ("Rx", "Ry", "Rz"), 4)
        return out

    def _inst(self, program: NeutralProgram, part: Part, *, head: bool) -> list[str]:
        """The instructions of a job between NOP and END (frames in a job that runs alone)."""
        numbers = {p.name: k for k, p in enumerate(part.positions)}
        moves = [i for i in part.instructions if isinstance(i, Move)]
        chained = {id(a) for a, b in zip(moves, moves[1:], strict=False)
                   if b.kind == MoveKind.CIRCULAR and a.kind == MoveKind.CIRCULAR}
        out = self._frames(program) if head else []
        prev: Move | None = None
        start: Position | None = part.start
        for ins, step in step_changes(part.instructions):
            if step is not None:
                out.append(step_line("'", step, 1 + COMMENT_LENGTH).replace(";", ","))
            if isinstance(ins, Move):
                out += self._motion(ins, numbers, start, prev, id(ins) in chained)
                prev, start = ins, ins.target
            elif isinstance(ins, Gripper):
                word = "close" if ins.close else "open"
                out += [f"'{word} gripper {ins.hand}",
                        f"DOUT OT#({self.gripper_output + ins.hand - 1}) "
                        f"{'ON' if ins.close else 'OFF'}",
                        f"TIMER T={self.gripper_wait_s:.2f}"]
            elif isinstance(ins, SetOutput):
                out.append(f"DOUT OT#({ins.channel}) {'ON' if ins.value else 'OFF'}")
            elif isinstance(ins, Wait):
                out.append(f"TIMER T={ins.seconds:.2f}")
            elif isinstance(ins, Comment):
                out += short_comments("'", ins.text)
        return out

    def _motion(self, m: Move, numbers: dict[str, int], start: Position | None,
                prev: Move | None, chained: bool) -> list[str]:
        assert m.speed is not None  # settled by `lower`
        if m.kind == MoveKind.JOINT:
            tags = f"VJ={m.speed * 100:.2f}"
        else:
            tags = f"V={m.speed * 1000:.1f}"
        level = self._level(m.blend_radius)
        if level:
            tags += f" PL={level}"
        if m.acceleration is not None:
            tags += f" ACC={round(m.acceleration * 100)}"

        def step(role: str, p: Position, word: str, extra: str = "") -> list[str]:
            return [f"'{role} {p.name}", f"{word} C{numbers[p.name]:05d}{extra} {tags}"]

        if m.kind == MoveKind.JOINT:
            return step("to", m.target, "MOVJ")
        if m.kind == MoveKind.LINEAR:
            return step("to", m.target, "MOVL")
        if m.kind != MoveKind.CIRCULAR:  # pragma: no cover - lowered before writing
            raise AssertionError("spline moves are lowered before writing")
        assert m.via is not None
        out: list[str] = []
        if prev is None or prev.kind != MoveKind.CIRCULAR:
            if start is None:
                raise ExportError("INFORM's MOVC starts at the previous point: a circular "
                                  "move cannot come first", step=m.step)
            out += step("from", start, "MOVC")
        out += step("via", m.via, "MOVC")
        out += step("to", m.target, "MOVC", " FPT" if chained else "")
        return out

    def _assemble(self, name: str, program: NeutralProgram, positions: list[Position],
                  inst: list[str], robot: Robot,
                  cycle: CycleTime | None) -> ProgramFile:
        if len(inst) + 2 > self.max_lines:
            raise ExportError(f"{name} needs {len(inst) + 2} instructions; the limit here is "
                              f"{self.max_lines}")
        pos = [f"///NPOS {len(positions)},0,0,0,0,0"]
        if positions:
            pos.append(f"///TOOL {self.tool}")
            if program.work.is_identity:
                pos.append("///POSTYPE BASE")
            else:
                pos += [f"///USER {self.user_frame}", "///POSTYPE USER"]
            pos.append("///RECTAN")
            rconf = None
            for k, p in enumerate(positions):
                assert p.q is not None
                flags = rconf_text(robot, p.q)
                if flags != rconf:
                    pos.append(f"///RCONF {flags}")
                    rconf = flags
                T = pose_in_work(program, position_pose(robot, p))
                x, y, z = (format_fixed(v, 3, what=p.name) for v in T[:3, 3] * 1000.0)
                rx, ry, rz = (format_fixed(v, 4, what=p.name)
                              for v in euler_deg(xyz_fixed_angles(T), 4))
                pos.append(f"C{k:05d}={x},{y},{z},{rx},{ry},{rz}")
        comm = "cellteach" if cycle is None else cycle.header_text().partition(" (")[0]
        lines = (["/JOB", f"//NAME {name}", "//POS"] + pos
                 + ["//INST", f"///DATE {DATE}", f"///COMM {comm[:COMMENT_LENGTH]}",
                    "///ATTR SC,RW", "///GROUP1 RB1", "NOP"] + inst + ["END"])
        return ProgramFile(f"{name}.JBI", "\n".join(lines) + "\n", newline="\r\n")

    # ====================================================================== reading
    def read(self, files: Sequence[ProgramFile], robot: Robot) -> NeutralProgram:
        jobs = {f.name.rsplit(".", 1)[0].upper(): f for f in files
                if f.name.upper().endswith(".JBI")}
        if not jobs:
            raise ExportError("no INFORM job (.JBI) among the files")
        parsed = {k: parse_jbi(k, f.text) for k, f in jobs.items()}
        called = {c for j in parsed.values() for c in j.calls}
        mains = [k for k in parsed if k not in called]
        if len(mains) != 1:
            raise ExportError(f"expected one main job, found {mains}")
        frames: dict[tuple[str, int], Frame] = {}
        for j in parsed.values():
            frames.update(j.frames)
        return self._build(mains[0], parsed, frames, robot, set())

    def _build(self, key: str, parsed: dict, frames: dict, robot: Robot,
               stack: set[str]) -> NeutralProgram:
        if key in stack:
            raise ExportError(f"{key} calls itself")
        job = parsed[key]
        prog = NeutralProgram(job.name)
        if ("TOOL", job.tool) in frames:
            prog.tool = frames[("TOOL", job.tool)]
        if job.user is not None:
            if ("USER", job.user) not in frames:
                raise ExportError(f"{key}: user frame {job.user} is not given in the comments")
            prog.work = frames[("USER", job.user)]
        cache: dict[int, Position] = {}

        def position(c: int, name: str) -> Position:
            if c not in cache:
                if c not in job.positions:
                    raise ExportError(f"{key}: C{c:05d} is not in //POS")
                values, rconf = job.positions[c]
                T = np.eye(4)
                T[:3, :3] = xyz_fixed_matrix(*np.radians(values[3:6]))
                T[:3, 3] = np.asarray(values[:3]) / 1000.0
                if job.user is not None:
                    T = pose_in_base(prog.work.T, T)
                cache[c] = Position(name or f"C{c:05d}", T, None, rconf_back(robot, rconf))
            return cache[c]

        parts: list[NeutralProgram] = []
        arc: list[tuple[Position, str, dict]] = []
        chain_open = False
        current: Position | None = None
        for kind, item in job.body:
            if kind == "call":
                if item not in parsed:
                    raise ExportError(f"{key} calls {item}, which is not among the files")
                parts.append(self._build(item, parsed, frames, robot, stack | {key}))
                continue
            if kind != "move":
                prog.instructions.append(item)
                continue
            word, c, name, tags, step = item
            p = position(c, name)
            if word != "MOVC":
                if arc:
                    raise ExportError(f"{key}: an arc needs a via and an end point")
                chain_open = False
                mk = MoveKind.JOINT if word == "MOVJ" else MoveKind.LINEAR
                prog.instructions.append(self._move(mk, p, None, tags, step))
                current = p
                continue
            if not chain_open and not arc:  # the arc's start: where the robot stands
                if current is not None and p is not current and not _same(p, current):
                    raise ExportError(f"{key}: the arc starts at C{c:05d}, not at the "
                                      "previous point")
                chain_open = True
                continue
            arc.append((p, step, tags))
            if len(arc) == 2:
                (via, _, _), (end, st, tg) = arc
                prog.instructions.append(self._move(MoveKind.CIRCULAR, end, via, tg, st))
                arc, current = [], end
                chain_open = "FPT" in tg
        if arc:
            raise ExportError(f"{key}: an arc needs a via and an end point")
        if parts:
            out = flatten(parts, prog.name)
            out.tool, out.work = prog.tool, prog.work
            return out
        return prog

    def _move(self, kind: MoveKind, target: Position, via: Position | None, tags: dict,
              step: str) -> Move:
        if kind == MoveKind.JOINT:
            speed = tags["VJ"] / 100.0 if "VJ" in tags else None
        else:
            speed = tags["V"] / 1000.0 if "V" in tags else None
        accel = tags["ACC"] / 100.0 if "ACC" in tags else None
        blend = self._zone(int(tags.get("PL", 0)))
        return Move(kind, target, via, speed=speed, acceleration=accel, blend_radius=blend,
                    step=step)


# ---------------------------------------------------------------------------- configuration
def _half_turns(angle_deg: float) -> bool:
    """True for ">= 180": outside -180 < angle <= 180."""
    return not -180.0 < angle_deg <= 180.0 + 1e-9


def _flip(r_deg: float) -> bool:
    """Flip: -90 < R <= 90 deg (and 270 < R <= 360, -360 < R <= -270)."""
    wrapped = (r_deg + 90.0) % 360.0 - 90.0  # into (-90, 270]
    return -90.0 < wrapped <= 90.0 + 1e-9


def _types(robot: Robot, q: Array, geo=None) -> tuple[int, ...]:
    geo = geo or arm_configuration(robot, q)
    deg = {s: (None if j is None else math.degrees(float(q[j])))
           for s in (1, 4, 6) for j in [joint_for_slot(robot, s)]}
    r, t, s = deg[4], deg[6], deg[1]
    return (0 if r is None or _flip(r) else 1, 0 if geo.elbow_up else 1, 0 if geo.front else 1,
            int(r is not None and _half_turns(r)), int(t is not None and _half_turns(t)),
            int(s is not None and _half_turns(s)))


def _flag_function(robot: Robot, q: Array):
    geo = arm_configuration(robot, q)
    return lambda qq: _types(robot, qq, geo)


def rconf_text(robot: Robot, q: Array) -> str:
    """``l,m,n,o,p,q`` and the unused zeros for the joint solution (module docstring)."""
    return ",".join(str(v) for v in _types(robot, q) + (0,) * RCONF_UNUSED)


def rconf_back(robot: Robot, values: Sequence[int]) -> ArmConfig:
    """The branch RCONF selects: flip and the >= 180 flags as unions of joint ranges."""
    l_, m, n, o, p, q = (list(values) + [0] * 6)[:6]
    d = math.radians
    sets = []
    r = joint_for_slot(robot, 4)
    if r is not None:
        flip, turned = l_ == 0, o == 1
        if flip and not turned:
            spans = [(-90.0, 90.0)]
        elif flip:
            spans = [(270.0, 360.0), (-360.0, -270.0)]
        elif not turned:
            spans = [(90.0, 180.0), (-180.0, -90.0)]
        else:
            spans = [(180.0, 270.0), (-270.0, -180.0)]
        sets.append(tuple(JointRange(r, d(a), d(b)) for a, b in spans))
    for slot, flag in ((6, p), (1, q)):
        j = joint_for_slot(robot, slot)
        if j is not None:
            spans = [(-180.0, 180.0)] if flag == 0 else [(180.0, 540.0), (-540.0, -180.0)]
            sets.append(tuple(JointRange(j, d(a), d(b)) for a, b in spans))
    return ArmConfig(front=n == 0, elbow_up=m == 0, joint_sets=tuple(sets))


def _same(a: Position, b: Position) -> bool:
    if a.T_base_tool is None or b.T_base_tool is None:
        return False
    return bool(np.allclose(a.T_base_tool, b.T_base_tool, atol=1e-6))


# ---------------------------------------------------------------------------- text
def _vj(fraction: float, step: str) -> float:
    v = round(fraction * 100.0, 2)
    if not 0.01 <= v <= 100.0:
        raise ExportError(f"joint speed {fraction * 100:.3f} % is outside INFORM's "
                          "0.01..100.00 %", step=step)
    return v


def _v(speed: float, step: str) -> float:
    v = round(speed * 1000.0, 1)
    if v < 0.1:
        raise ExportError(f"speed {speed * 1000:.3f} mm/s is below INFORM's 0.1 mm/s",
                          step=step)
    return v


def _acc(fraction: float, step: str) -> int:
    pct = round(fraction * 100.0)
    if not 20 <= pct <= 100:
        raise ExportError(f"acceleration {fraction * 100:.1f} % is outside INFORM's ACC= "
                          "20..100 %", step=step)
    return pct
