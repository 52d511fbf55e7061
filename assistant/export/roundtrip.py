"""Proof by round trip: write a dialect, read it back, drive both through the kinematics.

The reference is the program as the dialect can express it (`dialect.lower`: e.g. splines
become blended linear moves on controllers without splines); the comparison is the largest
TCP distance between the two simulated paths, point by point at equal path parameters. What
remains is the number format (0.005 mm for MELFA's two decimals, 0.5 um for KRL/RAPID,
1 um for URScript) and, for Cartesian joint moves, the IK of the rounded pose.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.export.dialect import Dialect, ProgramFile, check_axis_count
from assistant.export.errors import ExportError
from assistant.export.names import legal_for
from assistant.export.program import Comment, Move, NeutralProgram
from assistant.export.registry import get_dialect
from assistant.export.simulate import simulate
from assistant.robots.model import Robot


@dataclass(frozen=True)
class RoundTripReport:
    dialect: str
    #: Largest TCP distance (m) between the planned and the read-back program's paths.
    max_tcp_deviation: float
    per_move: tuple[float, ...]
    primitives: int
    #: Non-motion instructions (gripper, outputs, waits) that did not come back equal.
    instruction_differences: tuple[str, ...]
    #: Read-back targets whose configuration flags matched no IK solution.
    config_mismatches: tuple[str, ...]
    files: tuple[ProgramFile, ...]

    @property
    def file_sizes(self) -> dict[str, int]:
        return {f.name: len(f.data) for f in self.files}


def round_trip(program: NeutralProgram, dialect: str | Dialect, robot: Robot, *,
               max_step: float = 0.002) -> RoundTripReport:
    """Write, read back, simulate both; raises `ExportError` if the structure changed or
    the dialect's controller does not run a robot with that many axes."""
    d = get_dialect(dialect)
    check_axis_count(d, robot)
    program, _ = legal_for(program, d)  # the names the files carry (`export.names`)
    reference = d.lower(program)
    files = d.write(program, robot)
    back = d.read(files, robot)
    ref_moves, got_moves = reference.moves(), back.moves()
    kinds_ref = [m.kind for m in ref_moves]
    kinds_got = [m.kind for m in got_moves]
    if kinds_ref != kinds_got:
        raise ExportError(f"{d.name}: the program read back has other moves "
                          f"({len(kinds_got)} vs {len(kinds_ref)})")
    q0 = program.q_start
    ref = simulate(reference, robot, q0, max_step=max_step)
    got = simulate(back, robot, q0, samples=ref.sample_counts())
    per = tuple(float(np.max(np.linalg.norm(a.tcp - b.tcp, axis=1)))
                for a, b in zip(ref.moves, got.moves, strict=True))
    return RoundTripReport(d.name, max(per, default=0.0), per, len(ref_moves),
                           tuple(_instruction_diffs(reference, back)), got.config_mismatches,
                           tuple(files))


def _instruction_diffs(a: NeutralProgram, b: NeutralProgram) -> list[str]:
    """Gripper, output and wait instructions in order (comments do not execute)."""
    ia = [i for i in a.instructions if not isinstance(i, Move | Comment)]
    ib = [i for i in b.instructions if not isinstance(i, Move | Comment)]
    out = []
    strip = [type(i).__name__ + repr(_key(i)) for i in ia]
    back = [type(i).__name__ + repr(_key(i)) for i in ib]
    if strip != back:
        out.append(f"planned {strip}, read {back}")
    return out


def _key(i) -> tuple:
    d = dict(vars(i))
    d.pop("step", None)
    if "seconds" in d:
        d["seconds"] = round(d["seconds"], 3)
    return tuple(sorted(d.items()))
