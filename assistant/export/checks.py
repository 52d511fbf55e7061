"""Checks before any text is written: every target reachable as planned, every path drivable.

Offending input gives an `ExportError` naming the step ("step 'P7->P8': target 'P8' outside
J3 limits ..."), never a program that a controller would reject or run differently from the
plan. The path check is the simulation itself (`simulate.simulate`), so the program is proven
drivable through the same kinematics the round trip uses.
"""

from __future__ import annotations

import numpy as np

from assistant.export.errors import ExportError
from assistant.export.program import (
    Gripper,
    Move,
    MoveKind,
    NeutralProgram,
    Position,
    SetOutput,
    Wait,
)
from assistant.export.simulate import Simulation, simulate
from assistant.robots.model import Robot
from assistant.transforms import rotation_angle

#: A joint solution must put the TCP this close to its Cartesian target (m, rad).
POSE_TOLERANCE = 1e-5
ANGLE_TOLERANCE = 1e-5


def check_program(program: NeutralProgram, robot: Robot, *, simulate_paths: bool = True,
                  max_step: float = 0.005) -> Simulation | None:
    """Raise `ExportError` for anything a controller would reject or drive differently.

    Returns the simulation of the program when `simulate_paths` (reused by callers).
    """
    if not program.moves():
        raise ExportError("the program has no moves")
    for ins in program.instructions:
        if isinstance(ins, Move):
            _check_move(ins, robot)
        elif isinstance(ins, SetOutput | Gripper):
            ch = ins.channel if isinstance(ins, SetOutput) else ins.hand
            if int(ch) != ch or ch < 0:
                raise ExportError(f"output/hand number {ch!r} must be a whole number >= 0",
                                  step=ins.step)
        elif isinstance(ins, Wait) and not (ins.seconds >= 0.0 and np.isfinite(ins.seconds)):
            raise ExportError(f"wait of {ins.seconds!r} s", step=ins.step)
    if not simulate_paths:
        return None
    return simulate(program, robot, max_step=max_step)


def _check_move(m: Move, robot: Robot) -> None:
    if m.speed is not None:
        bad = not np.isfinite(m.speed) or m.speed <= 0.0
        if m.kind == MoveKind.JOINT and m.speed > 1.0:
            bad = True
        if bad:
            unit = "a fraction in (0, 1]" if m.kind == MoveKind.JOINT else "m/s > 0"
            raise ExportError(f"speed {m.speed!r} to {m.target.name!r} must be {unit}",
                              step=m.step)
    if m.acceleration is not None and not 0.0 < m.acceleration <= 1.0:
        raise ExportError(f"acceleration {m.acceleration!r} must be a fraction in (0, 1]",
                          step=m.step)
    if not (np.isfinite(m.blend_radius) and m.blend_radius >= 0.0):
        raise ExportError(f"blend radius {m.blend_radius!r} m must be >= 0", step=m.step)
    if m.kind == MoveKind.CIRCULAR and m.via is None:
        raise ExportError("a circular move needs a via point", step=m.step)
    if m.kind != MoveKind.CIRCULAR and m.via is not None:
        raise ExportError("only circular moves have a via point", step=m.step)
    for p in m.positions():
        check_position(p, robot, m.step)


def check_position(p: Position, robot: Robot, step: str) -> None:
    """Joint solution present, inside the limits, and reaching the Cartesian target."""
    if p.q is None:
        raise ExportError(f"position {p.name!r} has no joint solution; its configuration "
                          "flags cannot be derived", step=step)
    q = np.asarray(p.q, dtype=float)
    if q.shape != (robot.dof,) or not np.all(np.isfinite(q)):
        raise ExportError(f"position {p.name!r}: the joint solution must be {robot.dof} finite "
                          "numbers", step=step)
    bad = robot.limits.violations(q, robot.joint_names)
    if bad:
        joints = ", ".join(b.split("=")[0] for b in bad)
        raise ExportError(f"target {p.name!r} outside {joints} limits ({'; '.join(bad)})",
                          step=step)
    if p.T_base_tool is None:
        return
    T = np.asarray(p.T_base_tool, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ExportError(f"position {p.name!r}: pose must be a finite 4x4 transform",
                          step=step)
    got = robot.fk(q)
    off = float(np.linalg.norm(got[:3, 3] - T[:3, 3]))
    turn = rotation_angle(got[:3, :3].T @ T[:3, :3])
    if off > POSE_TOLERANCE or turn > ANGLE_TOLERANCE:
        res = robot.ik(T)
        why = f" ({res.message})" if not res.ok else ""
        raise ExportError(f"target {p.name!r}: its joint solution does not reach it "
                          f"({off * 1000:.3f} mm, {np.degrees(turn):.3f} deg off){why}",
                          step=step)
