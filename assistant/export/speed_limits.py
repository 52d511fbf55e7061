"""Exported speeds within the arm's own limits, and the cycle time on the same numbers.

A Cartesian move's TCP speed is the plan's wish; on its path every joint turns |dq/ds| per
metre of TCP travel, so the TCP may go no faster than min over the path and the joints of
v_i / |dq_i/ds| (and no faster than the path's curvature allows the joint accelerations:
`cycle_time._joint_speed_cap`, the very cap the cycle time applies). `clamp_speeds` writes
each faster move at that cap, rounded down to whole mm/s (every dialect can write those),
and says so in the export notes. Joint moves are fractions of the robot's joint speeds,
checked <= 1 (`checks.check_program`); a dialect that writes absolute joint speeds
(URScript's rad/s) derives them from the robot's limits (`URScriptDialect.cycle_limits`).

Since the cycle time caps a Cartesian move at the same number, the prediction and the
program run the move at the same speed.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from assistant.export.cycle_time import CycleTimeLimits, _joint_speed_cap
from assistant.export.program import Move, MoveKind, NeutralProgram
from assistant.export.simulate import Simulation
from assistant.robots.model import Robot

Array = np.ndarray


def clamp_speeds(program: NeutralProgram, robot: Robot, sim: Simulation,
                 limits: CycleTimeLimits) -> tuple[NeutralProgram, tuple[str, ...]]:
    """The program with every Cartesian move no faster than its joints allow, and a note per
    lowered move. `sim` is the program's simulation (dense joint path per move)."""
    v_max, a_max, _ = limits.joint_limits(robot)
    moves = program.moves()
    if len(sim.moves) != len(moves):
        raise ValueError("the simulation given is not this program's")
    notes: list[str] = []
    out = []
    k = 0
    modal: float | None = None  # the Cartesian speed in force (a move without one keeps it)
    accel = 1.0
    lowered = False
    for ins in program.instructions:
        if not isinstance(ins, Move):
            out.append(ins)
            continue
        sm = sim.moves[k]
        k += 1
        accel = accel if ins.acceleration is None else ins.acceleration
        if ins.kind == MoveKind.JOINT:
            out.append(ins)
            continue
        speed = ins.speed if ins.speed is not None else modal
        modal = speed
        length = float(np.sum(np.linalg.norm(np.diff(sm.tcp, axis=0), axis=1)))
        if speed is None or length <= 1e-6:
            out.append(ins)
            continue
        cap = _joint_speed_cap(sm.q, sm.tcp, v_max, a_max * accel)
        if speed > cap:
            new = _round_down(cap)
            notes.append(_note(ins, speed, new, robot, sm.q, sm.tcp, v_max))
            out.append(replace(ins, speed=new))
            lowered = True
        elif lowered and ins.speed is None:
            # after a lowered move the speed in force is said again, not inherited
            out.append(replace(ins, speed=speed))
        else:
            out.append(ins)
    if not notes:
        return program, ()
    return replace(program, instructions=out), tuple(notes)


def _round_down(cap: float) -> float:
    """Whole mm/s below the cap (0.1 mm/s below 1 mm/s: MELFA and FANUC refuse those)."""
    step = 1e-3 if cap >= 1e-3 else 1e-4
    return max(math.floor(cap / step * (1 - 1e-12)) * step, step / 10)


def _note(m: Move, wish: float, new: float, robot: Robot, q: Array, tcp: Array,
          v_max: Array) -> str:
    """Which joint holds the move back (or the path's curvature: accelerations)."""
    ds = np.linalg.norm(np.diff(tcp, axis=0), axis=1)
    ok = ds > 1e-9
    dq = np.abs(np.diff(q, axis=0))[ok] / ds[ok, None]
    per_joint = v_max / np.maximum(dq.max(axis=0), 1e-12)
    j = int(np.argmin(per_joint))
    kind = {MoveKind.LINEAR: "line", MoveKind.CIRCULAR: "arc",
            MoveKind.SPLINE: "spline"}.get(m.kind, m.kind.value)
    why = (f"{robot.joint_names[j]} would pass its {np.degrees(v_max[j]):.0f} deg/s"
           if per_joint[j] <= new * 1.01 + 1e-3 else
           "the path's curvature asks more than the joints' accelerations")
    step = f"{m.step}: " if m.step else ""
    return (f"{step}the {kind} to {m.target.name} is written at {new * 1000:g} mm/s, not "
            f"{wish * 1000:g} mm/s: faster, {why}")
