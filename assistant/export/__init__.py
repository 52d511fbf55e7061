"""Program export: planned trajectory -> robot-neutral program -> controller dialects.

Owns the neutral program (`program`), the dialects (`melfa`, `krl`, `rapid`, `urscript`,
`fanuc`, `yaskawa`, one module each behind the `Dialect` protocol), the controller rules
(`rules`), arm configuration flags (`configuration`), a 7-axis arm's third joint as the
external axis RAPID and KRL write it (`redundant_axis`), position names each controller
accepts (`names`), the round-trip proof (`simulate`, `roundtrip`), the predicted cycle time
(`cycle_time`, with ruckig), downloads (`download`); it samples free-shape Bezier paths with
`trajectory.bezier`.
May import mission, robots, trajectory (geometry only) and transforms; never the planner,
`web` or `viser`: it consumes a `Trajectory`.
Units inside are metres and radians; millimetres and degrees appear only in dialect text.
"""

from assistant.export.checks import check_program
from assistant.export.configuration import ArmConfig, arm_configuration
from assistant.export.cycle_time import (
    CycleTime,
    CycleTimeLimits,
    StepTime,
    predict_cycle_time,
)
from assistant.export.dialect import Dialect, ProgramFile
from assistant.export.download import DownloadFile, ExportResult, export_files
from assistant.export.errors import ExportError
from assistant.export.fanuc import FanucDialect
from assistant.export.krl import KrlDialect
from assistant.export.melfa import MelfaDialect
from assistant.export.program import (
    Comment,
    Frame,
    Gripper,
    Move,
    MoveKind,
    NeutralProgram,
    Position,
    ProgramDefaults,
    SetOutput,
    Wait,
    program_from_trajectory,
)
from assistant.export.rapid import RapidDialect
from assistant.export.registry import DIALECT_NAMES, get_dialect
from assistant.export.roundtrip import RoundTripReport, round_trip
from assistant.export.simulate import simulate
from assistant.export.urscript import URScriptDialect
from assistant.export.yaskawa import YaskawaDialect
from assistant.trajectory.bezier import (
    BezierChain,
    BezierSampling,
    CubicBezier,
    de_casteljau,
    sample_bezier_chain,
    sample_fixed_dt,
)

__all__ = [
    "ArmConfig", "BezierChain", "BezierSampling", "Comment", "CubicBezier", "CycleTime",
    "CycleTimeLimits", "DIALECT_NAMES", "StepTime", "predict_cycle_time",
    "Dialect", "DownloadFile", "ExportError", "ExportResult", "FanucDialect", "Frame", "Gripper",
    "KrlDialect", "MelfaDialect", "Move", "MoveKind", "NeutralProgram", "Position",
    "ProgramDefaults", "ProgramFile", "RapidDialect", "RoundTripReport", "SetOutput",
    "URScriptDialect", "Wait", "arm_configuration", "check_program", "de_casteljau",
    "export_files", "get_dialect", "program_from_trajectory", "round_trip", "sample_bezier_chain",
    "sample_fixed_dt", "simulate", "YaskawaDialect",
]
