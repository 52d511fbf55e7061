"""What the session hands to the browser: files as bytes with names and MIME types.

`export_files` checks that the dialect's controller runs a robot with this many axes, checks
the program (limits, reach, drivable paths), lowers every Cartesian speed the joints cannot
follow to what they can (`speed_limits`; said in the notes), writes the dialect,
reads it straight back to prove the text says what was planned (positions within the number
format, same moves), and bundles multi-file programs (MELFA .MB4 + .POS, KRL .src + .dat,
split programs) into a zip too. The zip is deterministic (fixed timestamps), so the same
program gives the same bytes.
"""

from __future__ import annotations

import inspect
import io
import zipfile
from dataclasses import dataclass, field

import numpy as np

from assistant.export.checks import check_program
from assistant.export.cycle_time import CycleTime, CycleTimeLimits, predict_cycle_time
from assistant.export.dialect import Dialect, ProgramFile, check_axis_count
from assistant.export.errors import ExportError
from assistant.export.names import legal_for
from assistant.export.program import NeutralProgram
from assistant.export.program_frame import in_program_frame
from assistant.export.registry import get_dialect
from assistant.export.simulate import simulate, target_pose
from assistant.export.speed_limits import clamp_speeds
from assistant.robots.model import Robot
from assistant.transforms import rotation_angle

#: Read-back positions must agree with the plan within the coarsest number format we write.
VERIFY_POSITION = 1e-5  # m (MELFA: 0.005 mm rounding)
VERIFY_ANGLE = np.radians(0.01)


@dataclass(frozen=True)
class DownloadFile:
    name: str
    data: bytes
    mime: str


@dataclass(frozen=True)
class ExportResult:
    """The files of one exported program and a zip of them when there are several."""

    dialect: str
    program_name: str
    files: tuple[DownloadFile, ...]
    zip: DownloadFile | None
    primitives: int
    primitive_counts: dict[str, int] = field(default_factory=dict)
    #: Predicted time of the program as written (a prediction, not measured).
    cycle_time: CycleTime | None = None
    #: Positions renamed to satisfy the controller's identifier rules, one line each.
    renames: tuple[str, ...] = ()
    #: Other things the controller's rules changed: a program split into parts, positions
    #: written as joint values, blends the controller cannot express (one line each).
    notes: tuple[str, ...] = ()

    @property
    def download(self) -> DownloadFile:
        """The one thing to offer for download: the zip, or the single file."""
        return self.zip if self.zip is not None else self.files[0]


def export_files(program: NeutralProgram, dialect: str | Dialect, robot: Robot, *,
                 check: bool = True, verify: bool = True,
                 cycle_limits: CycleTimeLimits | None = None) -> ExportResult:
    """Program files ready for download.

    Args:
        program: the neutral program (e.g. from `program_from_trajectory`).
        dialect: "melfa", "krl", "rapid", "urscript" or a configured dialect instance.
        robot: the robot the program was planned for.
        check: run `check_program` (limits, reach, drivable Cartesian paths) first.
        verify: read the written files back and compare positions and moves.
        cycle_limits: acceleration/jerk limits and fixed times of the cycle time prediction
            (`predict_cycle_time`; written into the program header, kept in the result).
    Raises:
        ExportError naming the step for anything a controller would reject or run
        differently from the plan; first of all when the dialect's controller does not run
        a robot with `robot.dof` axes (a 7-axis arm in URScript).
    """
    d = get_dialect(dialect)
    check_axis_count(d, robot)
    program, renames = legal_for(program, d)
    # Written, checked and read back in the frame the robot's controller takes poses in.
    program, robot = in_program_frame(program, robot)
    sim = check_program(program, robot) if check else None
    limits = dialect_limits(d, robot, cycle_limits)
    if sim is None:
        sim = simulate(program, robot, max_step=limits.path_step)
    # No Cartesian move faster than its joints allow, written as the cycle time runs it.
    program, clamped = clamp_speeds(program, robot, sim, limits)
    lowered = d.lower(program)
    # The check's simulation is the lowered program's when lowering changed nothing.
    cycle = predict_cycle_time(lowered, robot, limits,
                               simulation=sim if lowered is program else None)
    files, notes = _write(d, program, robot, cycle)
    if verify:
        _verify(d, program, files, robot)
    out = tuple(DownloadFile(f.name, f.data, _mime(f)) for f in files)
    zipped = _zip(program.name, d, files) if len(files) > 1 else None
    return ExportResult(d.name, program.name, out, zipped, lowered.primitive_count(),
                        lowered.primitive_counts(), cycle, renames, clamped + notes)


def dialect_limits(d: Dialect, robot: Robot,
                   base: CycleTimeLimits | None = None) -> CycleTimeLimits:
    """The limits the dialect's controller runs `robot` under (`cycle_limits` of a dialect
    that writes absolute joint speeds), else `base`: what the program and its predicted
    cycle time both use."""
    base = base or CycleTimeLimits()
    own = getattr(d, "cycle_limits", None)
    return own(robot, base) if own is not None else base


def _write(d: Dialect, program: NeutralProgram, robot: Robot,
           cycle: CycleTime) -> tuple[list[ProgramFile], tuple[str, ...]]:
    """The dialect's files with the predicted cycle time in their header, and its notes.

    The built-in dialects take the prediction made here (the header and the result agree);
    a dialect written to the plain `Dialect.write(program, robot)` predicts its own. One
    with `write_noted` also says what the controller's rules changed (a split, ...).
    """
    noted = getattr(d, "write_noted", None)
    if noted is not None:
        files, notes = noted(program, robot, cycle_time=cycle)
        return files, tuple(notes)
    if "cycle_time" in inspect.signature(d.write).parameters:
        return d.write(program, robot, cycle_time=cycle), ()
    return d.write(program, robot), ()


def _mime(f: ProgramFile) -> str:
    return f"{f.mime}; charset=us-ascii"


def _zip(name: str, d: Dialect, files: list[ProgramFile]) -> DownloadFile:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for f in files:
            info = zipfile.ZipInfo(f.name, date_time=(2020, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(info, f.data)
    return DownloadFile(f"{name}_{d.name}.zip", buf.getvalue(), "application/zip")


def _verify(d: Dialect, program: NeutralProgram, files: list[ProgramFile],
            robot: Robot) -> None:
    back = d.read(files, robot)
    planned = d.lower(program).moves()
    got = back.moves()
    if [m.kind for m in planned] != [m.kind for m in got]:
        raise ExportError(f"{d.name}: the written program reads back with other moves")
    for a, b in zip(planned, got, strict=True):
        for pa, pb in zip(a.positions(), b.positions(), strict=True):
            if pb.q is not None and pa.q is not None and pb.T_base_tool is None:
                if not np.allclose(pa.q, pb.q, atol=VERIFY_ANGLE):
                    raise ExportError(f"{d.name}: joints of {pa.name!r} do not read back",
                                      step=a.step)
                continue
            held = None if pb.config is None else pb.config.redundant
            if held is not None and pa.q is not None and \
                    abs(pa.q[held[0]] - held[1]) > VERIFY_ANGLE:
                raise ExportError(f"{d.name}: the external axis of {pa.name!r} does not read "
                                  "back", step=a.step)
            Ta, Tb = target_pose(robot, pa), target_pose(robot, pb)
            dp = float(np.linalg.norm(Ta[:3, 3] - Tb[:3, 3]))
            da = rotation_angle(Ta[:3, :3].T @ Tb[:3, :3])
            if dp > VERIFY_POSITION or da > VERIFY_ANGLE:
                raise ExportError(f"{d.name}: {pa.name!r} reads back {dp * 1000:.4f} mm, "
                                  f"{np.degrees(da):.4f} deg off", step=a.step)
