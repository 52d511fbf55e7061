"""Programs in the robot's program frame: the frame its controller takes poses in.

A robot model's base is its mounting frame; its controller may count poses from another
frame fixed to it (`Robot.program_frame`): FANUC's world frame 330 mm up on the J1 axis of
an LR Mate, a UR's base turned 180 deg about z. `in_program_frame` re-expresses a neutral
program there (every pose and the work frame; joints stay) and hands the dialects a view of
the robot whose base *is* that frame (`robots.framed.FramedRobot`): writers, readers,
checks, simulation and cycle time then all work in the controller's frame without knowing
it, and every header names it (`dialect.base_words`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from assistant.export.program import Frame, Move, NeutralProgram, Position
from assistant.robots.framed import FramedRobot
from assistant.robots.model import Robot
from assistant.transforms import inv_T

Array = np.ndarray


def in_program_frame(program: NeutralProgram, robot: Robot,
                     ) -> tuple[NeutralProgram, Robot]:
    """The program and the robot as its controller's frame sees them (unchanged when that
    frame is the model base)."""
    T, words = robot.program_frame()
    if np.allclose(T, np.eye(4), atol=1e-12):
        return program, robot
    Ti = inv_T(np.asarray(T, dtype=float))
    cache: dict[int, Position] = {}

    def conv(p: Position | None) -> Position | None:
        if p is None or p.T_base_tool is None:
            return p
        if id(p) not in cache:
            cache[id(p)] = replace(p, T_base_tool=Ti @ np.asarray(p.T_base_tool, float))
        return cache[id(p)]

    out = []
    for ins in program.instructions:
        if isinstance(ins, Move):
            ins = replace(ins, target=conv(ins.target), via=conv(ins.via),
                          through=tuple(conv(t) for t in ins.through))
        out.append(ins)
    work = program.work if program.work.is_identity else \
        Frame(program.work.name, Ti @ np.asarray(program.work.T, dtype=float))
    return replace(program, instructions=out, work=work), FramedRobot(robot, T, words)
