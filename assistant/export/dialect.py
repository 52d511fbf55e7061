"""The one interface every program dialect implements, and what they share.

Modelled on trimesh's exchange modules: one module per dialect (`melfa`, `krl`, `rapid`,
`urscript`), each a small class with `name`, `file_extensions`, `rules`, `axis_counts`,
`write` and `read`; `get_dialect` picks one by name. Shared here: the file type, the check
that the robot has an axis count the dialect's controller runs (`check_axis_count`),
splitting a long program into parts with a main that calls them, frames, comments and the
step labels that become comments.
"""

from __future__ import annotations

import textwrap
import unicodedata
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from assistant.export.dialect_names import AXIS_COUNTS, DIALECT_NAMES, dialect_label
from assistant.export.errors import ExportError
from assistant.export.program import (
    Gripper,
    Instruction,
    Move,
    MoveKind,
    NeutralProgram,
    Position,
    SetOutput,
    Wait,
)
from assistant.export.rules import DialectRules, check_identifier

if TYPE_CHECKING:  # the prediction imports the simulation, which imports this module
    from assistant.export.cycle_time import CycleTime
from assistant.robots.model import Robot
from assistant.transforms import angle_between, inv_T, matrix_to_rpy, rpy_to_matrix

Array = np.ndarray


@dataclass(frozen=True)
class ProgramFile:
    """One file of a program as the controller wants it (name, text, line ending, MIME)."""

    name: str
    text: str
    mime: str = "text/plain"
    newline: str = "\n"

    @property
    def data(self) -> bytes:
        return self.text.replace("\n", self.newline).encode("ascii")


@runtime_checkable
class Dialect(Protocol):
    """A robot programming language: writes a neutral program, reads back what it wrote."""

    name: str
    title: str
    file_extensions: tuple[str, ...]
    rules: DialectRules
    #: Robot axis counts (`Robot.dof`) the controller runs, e.g. (6,) for UR arms.
    axis_counts: tuple[int, ...]
    #: What the dialect writes, for the refusal: "URScript runs on 6-axis UR arms".
    axis_rule: str
    #: Why more axes than the largest count are not written ("" when there is nothing to say).
    axes_beyond: str

    def write(self, program: NeutralProgram, robot: Robot, *,
              cycle_time: CycleTime | None = None) -> list[ProgramFile]:
        """Controller files for the program (the predicted `cycle_time` in the header);
        `ExportError` for anything it would reject."""
        ...

    def read(self, files: Sequence[ProgramFile], robot: Robot) -> NeutralProgram:
        """The neutral program back from files this dialect wrote (robot: axis map, flags)."""
        ...


# ------------------------------------------------------------------------------ axes
def check_axis_count(dialect: Dialect, robot: Robot) -> None:
    """Refuse a robot whose number of axes the dialect's controller does not run.

    A program with the wrong number of joint values (a 7-value ``movej`` list, a 5-axis arm
    as a UR) would be written without complaint and rejected, or misread, on the controller.
    The `ExportError` says what the dialect runs and names the dialects that do take the
    robot's axis count, if any. Dialects without `axis_counts` are not checked.
    """
    counts = tuple(getattr(dialect, "axis_counts", ()) or ())
    n = robot.dof
    if not counts or n in counts:
        return
    rule = getattr(dialect, "axis_rule", "") or \
        f"{dialect_label(dialect.name)} runs on arms with {_count_text(counts)} axes"
    text = f"{rule}; this robot ({robot.name}) has {n} axes."
    beyond = getattr(dialect, "axes_beyond", "")
    if beyond and n > max(counts):
        text += f" {beyond[0].upper()}{beyond[1:]}."
    takes: dict[tuple[int, ...], list[str]] = {}
    for name in DIALECT_NAMES:
        takes.setdefault(AXIS_COUNTS[name], []).append(dialect_label(name))
    others = [label for c, labels in takes.items() if n in c for label in labels
              if label != dialect_label(dialect.name)]
    arm = f"{'an' if str(n)[0] == '8' or n in (11, 18) else 'a'} {n}-axis arm"
    if others:
        text += f" Choose {_or_list(others)} for {arm}."
    else:
        summary = "; ".join(f"{_and_list(labels)} take{'s' if len(labels) == 1 else ''} "
                            f"{_count_text(c)} axes" for c, labels in takes.items())
        text += f" No dialect here writes {arm}: {summary}."
    raise ExportError(text, dialect=dialect.name)


def _count_text(counts: Sequence[int]) -> str:
    return _or_list([str(c) for c in sorted(counts)])


def _or_list(words: Sequence[str]) -> str:
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]


def _and_list(words: Sequence[str]) -> str:
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


# ------------------------------------------------------------------------------ text
def ascii_text(text: str) -> str:
    """Comments in controller files must be plain ASCII (arrows become "->")."""
    text = text.replace("\u2192", "->").replace("\u2190", "<-").replace("\u00b0", " deg")
    text = unicodedata.normalize("NFKD", text)
    out = "".join(ch if 32 <= ord(ch) < 127 else ("" if unicodedata.combining(ch) else "?")
                  for ch in text)
    return " ".join(out.split())


def step_changes(instructions: Sequence[Instruction]) -> Iterator[tuple[Instruction, str | None]]:
    """Each instruction with the step label to announce before it (None: same step)."""
    current: str | None = None
    for ins in instructions:
        step = getattr(ins, "step", None)
        if step is not None and step != "" and step != current:
            current = step
            yield ins, step
        else:
            yield ins, None


STEP_PREFIX = "step: "


def comment_lines(lead: str, text: str, max_line: int) -> list[str]:
    """A free comment as one or more comment lines, each within the controller's limit."""
    width = max(max_line - len(lead), 10)
    return [lead + part for part in textwrap.wrap(ascii_text(text), width) or [""]]


def step_line(lead: str, step: str, max_line: int) -> str:
    """The comment announcing a mission step; long labels are shortened with "..."."""
    text = STEP_PREFIX + ascii_text(step)
    width = max(max_line - len(lead), 10)
    return lead + (text if len(text) <= width else text[: width - 3] + "...")


def parse_step_comment(text: str) -> str | None:
    text = text.strip()
    return text[len(STEP_PREFIX):].strip() if text.startswith(STEP_PREFIX) else None


# ------------------------------------------------------------------------------ checks
def check_output_channels(program: NeutralProgram, gripper_output: int,
                          ref: Callable[[int], str], first: int = 1) -> None:
    """Outputs numbered from `first`; gripper n drives output `gripper_output + n - 1`, which
    no plain output may also set (`ref(n)` names output n as the controller writes it)."""
    hands = {i.hand for i in program.instructions if isinstance(i, Gripper)}
    grippers = {gripper_output + h - 1 for h in hands}
    for i in program.instructions:
        if isinstance(i, SetOutput | Gripper):
            ch = i.channel if isinstance(i, SetOutput) else gripper_output + i.hand - 1
            if ch < first:
                raise ExportError(f"{ref(ch)}: this controller's outputs are numbered from "
                                  f"{first}", step=i.step)
            if isinstance(i, SetOutput) and ch in grippers:
                raise ExportError(f"output {ref(ch)} is the gripper's output on this "
                                  "controller", step=i.step)


def check_position_names(program: NeutralProgram, rules: DialectRules) -> None:
    """Every position name legal as it is (`names.legal_for` renames before writing) and no
    two differing only in case (a name comment is read back without case)."""
    seen: dict[str, str] = {}
    for m in program.moves():
        for p in m.positions():
            check_identifier(p.name, rules, what="position", step=m.step)
            key = p.name.upper()
            if seen.setdefault(key, p.name) != p.name:
                raise ExportError(f"positions {seen[key]!r} and {p.name!r} differ only in "
                                  f"case ({rules.dialect} names)", step=m.step,
                                  dialect=rules.dialect)


# ------------------------------------------------------------------------------ frames
def base_words(robot: Robot) -> str:
    """The frame a dialect's poses are in (work frames are given in it), for the header:
    "robot base: URDF link 'base' (the controller's base frame, ...)". `export_files` hands
    the writers the robot as seen from its program frame (`program_frame.in_program_frame`);
    a robot given as it is (its model base) is named by its mounting frame."""
    T, words = robot.program_frame()
    if np.allclose(T, np.eye(4), atol=1e-12):
        return f"robot base: {ascii_text(words)}"
    link = getattr(robot, "base_link", None)
    where = f" (URDF link '{ascii_text(str(link))}')" if link else ""
    return f"robot base: the robot's mounting frame{where}"


def pose_in_work(program: NeutralProgram, T_base_tool: Array) -> Array:
    """A base-frame target re-expressed in the program's work frame (what controllers store)."""
    return inv_T(np.asarray(program.work.T, dtype=float)) @ np.asarray(T_base_tool, float)


def pose_in_base(T_base_work: Array, T_work_tool: Array) -> Array:
    return np.asarray(T_base_work, dtype=float) @ np.asarray(T_work_tool, dtype=float)


def position_pose(robot: Robot, p: Position) -> Array:
    if p.T_base_tool is not None:
        return np.asarray(p.T_base_tool, dtype=float)
    if p.q is None:
        raise ExportError(f"position {p.name!r} has neither a pose nor joints")
    return robot.fk(p.q)


def positions_to_base(prog: NeutralProgram) -> NeutralProgram:
    """A program read with its positions in its work frame, re-expressed in the robot base."""
    if prog.work.is_identity:
        return prog
    cache: dict[int, Position] = {}

    def conv(p: Position | None) -> Position | None:
        if p is None or p.T_base_tool is None:
            return p
        if id(p) not in cache:
            cache[id(p)] = replace(p, T_base_tool=pose_in_base(prog.work.T, p.T_base_tool))
        return cache[id(p)]

    out = []
    for ins in prog.instructions:
        if isinstance(ins, Move):
            ins = replace(ins, target=conv(ins.target), via=conv(ins.via),
                          through=tuple(conv(t) for t in ins.through))
        out.append(ins)
    return replace(prog, instructions=out)


def xyz_fixed_angles(T: Array) -> tuple[float, float, float]:
    """(rx, ry, rz) in rad, rotations about the fixed X, Y, Z axes: R = Rz(rz) Ry(ry) Rx(rx).
    MELFA's A, B, C, FANUC's W, P, R and Yaskawa's Rx, Ry, Rz all mean this."""
    a, b, c = matrix_to_rpy(np.asarray(T, dtype=float)[:3, :3])
    return c, b, a


def xyz_fixed_matrix(rx: float, ry: float, rz: float) -> Array:
    """The rotation matrix of `xyz_fixed_angles` (rad)."""
    return rpy_to_matrix(rz, ry, rx)


# ------------------------------------------------------------------------------ parts
@dataclass(frozen=True)
class Part:
    """A slice of the program written to its own file(s), called in order by a main."""

    index: int  # 1-based; 0 when the program is not split
    instructions: list[Instruction]
    positions: list[Position]
    #: Where the robot is when the part begins (the previous part's last target).
    start: Position | None = None


def split_into_parts(program: NeutralProgram, limit: int | None,
                     needs: Callable[[Move, Position | None], list[Position]] | None = None
                     ) -> list[Part]:
    """Cut the instruction list so no part declares more than `limit` positions.

    `needs(move, previous_target)` lists the positions a move's text refers to (MELFA's MVR
    names its start point too). Spline moves longer than a part are cut into several splines
    through the same points. One part (index 0) when everything fits.
    """
    def default_needs(m: Move, prev: Position | None) -> list[Position]:
        return m.positions()

    needs = needs or default_needs
    instructions = list(program.instructions)
    if limit is not None:
        instructions = _cut_long_splines(instructions, limit)
    parts: list[tuple[list[Instruction], dict[str, Position]]] = [([], {})]
    starts: list[Position | None] = [None]
    prev: Position | None = None
    for ins in instructions:
        if isinstance(ins, Move):
            want = {p.name: p for p in needs(ins, prev)}
            cur_ins, cur_pos = parts[-1]
            new = {k: v for k, v in want.items() if k not in cur_pos}
            if limit is not None and len(cur_pos) + len(new) > limit and cur_ins:
                parts.append(([], {}))
                starts.append(prev)
                cur_ins, cur_pos = parts[-1]
                new = want
            if limit is not None and len(want) > limit:
                raise ExportError(f"one move needs {len(want)} positions; the controller "
                                  f"allows {limit} per file", step=ins.step)
            cur_pos.update(new)
            cur_ins.append(ins)
            prev = ins.target
        else:
            parts[-1][0].append(ins)
    if len(parts) == 1:
        return [Part(0, parts[0][0], list(parts[0][1].values()))]
    return [Part(i + 1, ins, list(pos.values()), starts[i])
            for i, (ins, pos) in enumerate(parts)]


def with_arc_start(m: Move, prev: Position | None) -> list[Position]:
    """The positions a move's text names when a circular move also names its start point
    (MELFA's MVR start,via,end; INFORM's three MOVC steps): `split_into_parts`' `needs`."""
    pts = m.positions()
    if m.kind == MoveKind.CIRCULAR and prev is not None:
        pts = [prev] + pts
    return pts


def parts_within(program: NeutralProgram, max_positions: int | None, max_lines: int | None,
                 lines: Callable[[Part], int],
                 needs: Callable[[Move, Position | None], list[Position]] | None = None,
                 what: str = "the controller") -> list[Part]:
    """`split_into_parts`, with the positions per part lowered until no part has more than
    `max_lines` program lines (`lines(part)` counts them as the dialect writes them)."""
    need = needs or (lambda m, prev: m.positions())
    fewest, prev = 1, None
    for m in program.moves():  # no part can hold fewer positions than one move names
        fewest = max(fewest, len({p.name for p in need(m, prev)}))
        prev = m.target
    limit = max_positions
    while True:
        parts = split_into_parts(program, limit, needs)
        longest = max(lines(p) for p in parts)
        if max_lines is None or longest <= max_lines:
            return parts
        most = max(len(p.positions) for p in parts)
        if most <= fewest:
            raise ExportError(f"{what} allows {max_lines} lines per program; a part as small "
                              f"as the program's moves allow needs {longest}")
        limit = max(fewest, min(most - 1, int(most * max_lines / longest)))


def part_names(main: str, count: int, max_length: int) -> list[str]:
    """Names of the parts a main program calls: MAIN1, MAIN2, ... shortened to fit."""
    out = []
    for k in range(1, count + 1):
        suffix = str(k)
        out.append(main[: max_length - len(suffix)] + suffix)
    return out


def cut_long_splines(program: NeutralProgram, limit: int | None) -> NeutralProgram:
    """Splines with more points than fit in one file, as several splines through them."""
    if limit is None:
        return program
    return replace(program, instructions=_cut_long_splines(list(program.instructions), limit))


def _cut_long_splines(instructions: list[Instruction], limit: int) -> list[Instruction]:
    out: list[Instruction] = []
    chunk = max(limit - 2, 1)
    for ins in instructions:
        if isinstance(ins, Move) and ins.kind == MoveKind.SPLINE and len(ins.through) + 1 > chunk:
            pts = list(ins.through) + [ins.target]
            for a in range(0, len(pts), chunk):
                piece = pts[a:a + chunk]
                last = a + chunk >= len(pts)
                out.append(replace(ins, target=piece[-1], through=tuple(piece[:-1]),
                                   blend_radius=ins.blend_radius if last else 0.0))
        else:
            out.append(ins)
    return out


def merge_smooth_splines(program: NeutralProgram) -> NeutralProgram:
    """Runs of spline moves that blend into each other (the planner knew the curves' tangents
    and saw no corner; same step, speed and acceleration, nothing between them) as one spline
    move: a controller then keeps the speed through the joins instead of stopping exactly at
    each segment's end."""
    out: list[Instruction] = []
    for ins in program.instructions:
        prev = out[-1] if out else None
        if isinstance(ins, Move) and isinstance(prev, Move) and _blends_into(prev, ins):
            out[-1] = replace(ins, through=prev.through + (prev.target,) + ins.through)
        else:
            out.append(ins)
    return replace(program, instructions=out)


def _blends_into(a: Move, b: Move) -> bool:
    return a.kind == b.kind == MoveKind.SPLINE and a.blend_radius > 0.0 and \
        (a.step, a.speed, a.acceleration) == (b.step, b.speed, b.acceleration)


def lower_splines(program: NeutralProgram) -> NeutralProgram:
    """Spline moves as linear moves through their points, for controllers without splines.

    Each inner point is blended over a distance r of at most a quarter of its shorter chord
    (blends never overlap) and small enough that the blend stays within `CORNER_DEVIATION`
    of the point: a blend tangent to both chords at distance r from a corner that turns by
    theta passes r tan(theta / 4) from it. Sharp corners are thus kept, gentle ones blended.
    """
    if not any(isinstance(i, Move) and i.kind == MoveKind.SPLINE for i in program.instructions):
        return program
    out: list[Instruction] = []
    prev: Position | None = None
    for ins in program.instructions:
        if isinstance(ins, Move) and ins.kind == MoveKind.SPLINE:
            pts = list(ins.through) + [ins.target]
            xyz = [None if prev is None or prev.T_base_tool is None else prev.T_base_tool[:3, 3]]
            xyz += [None if p.T_base_tool is None else p.T_base_tool[:3, 3] for p in pts]
            for k, p in enumerate(pts):
                if k == len(pts) - 1:
                    r = ins.blend_radius
                else:
                    r = _corner_blend(xyz[k], xyz[k + 1], xyz[k + 2])
                out.append(replace(ins, kind=MoveKind.LINEAR, target=p, through=(),
                                   blend_radius=r))
        else:
            out.append(ins)
        if isinstance(ins, Move):
            prev = ins.target
    return replace(program, instructions=out)


#: How far a blend between the linear moves of a lowered spline may pass from its point (m).
CORNER_DEVIATION = 5e-5


def _corner_blend(a: Array | None, b: Array | None, c: Array | None) -> float:
    if a is None or b is None or c is None:
        return 0.0
    u, v = b - a, c - b
    lu, lv = float(np.linalg.norm(u)), float(np.linalg.norm(v))
    if lu < 1e-9 or lv < 1e-9:
        return 0.0
    turn = angle_between(u, v)
    r = 0.25 * min(lu, lv)
    if turn > 1e-9:
        r = min(r, CORNER_DEVIATION / np.tan(turn / 4.0))
    return float(np.floor(r * 1e4) / 1e4)  # whole 0.1 mm: survives every number format


def settle_values(program: NeutralProgram, *,
                  joint_speed: Callable[[float, Move], float] | None = None,
                  cartesian_speed: Callable[[float, Move], float] | None = None,
                  blend: Callable[[float, Move], float] | None = None,
                  acceleration: Callable[[float, Move], float] | None = None,
                  wait: Callable[[float, Wait], float] | None = None) -> NeutralProgram:
    """The program with every setting as a dialect writes it (whole percent, mm/s steps,
    CNT values, ...), so the cycle time, the round trip and the read-back compare with
    what the controller gets. Controllers that want a speed on every motion get one: a move
    without one keeps the previous speed of its kind, the first joint move runs at full
    speed, a Cartesian move before any speed is refused (as `cycle_time` rules)."""
    out: list[Instruction] = []
    speeds: dict[bool, float | None] = {True: 1.0, False: None}
    for ins in program.instructions:
        if isinstance(ins, Move):
            joint = ins.kind == MoveKind.JOINT
            v = ins.speed if ins.speed is not None else speeds[joint]
            if v is None:
                raise ExportError(f"the {ins.kind.value} move to {ins.target.name!r} has no "
                                  "speed", step=ins.step)
            speeds[joint] = v
            settle = joint_speed if joint else cartesian_speed
            changes: dict[str, object] = {"speed": settle(v, ins) if settle else v}
            if blend is not None and ins.blend_radius > 0.0:
                changes["blend_radius"] = blend(ins.blend_radius, ins)
            if acceleration is not None and ins.acceleration is not None:
                changes["acceleration"] = acceleration(ins.acceleration, ins)
            ins = replace(ins, **changes)
        elif isinstance(ins, Wait) and wait is not None:
            ins = replace(ins, seconds=wait(ins.seconds, ins))
        out.append(ins)
    return replace(program, instructions=out)


def flatten(programs: Sequence[NeutralProgram], name: str) -> NeutralProgram:
    """Join parts read back from several files into one program (frames from the first)."""
    first = programs[0]
    out = NeutralProgram(name, [], first.tool, first.work)
    for p in programs:
        out.instructions += p.instructions
    return out
