"""Neutral program from a trajectory, and the checks that refuse offending input by step."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from assistant.export import (
    ExportError,
    Gripper,
    Move,
    MoveKind,
    NeutralProgram,
    Position,
    check_program,
    export_files,
    program_from_trajectory,
    simulate,
)
from assistant.export.samples import thesis_trajectory, waypoint
from assistant.mission.motion import (
    Motion,
    MotionKind,
    ToolAction,
    ToolActionKind,
    Trajectory,
    Waypoint,
)


def test_thesis_program_has_the_thesis_shape(thesis_program):
    moves = thesis_program.moves()
    assert [m.kind for m in moves[1:]] == [MoveKind.JOINT, MoveKind.CIRCULAR, MoveKind.LINEAR,
                                          MoveKind.CIRCULAR, MoveKind.LINEAR, MoveKind.CIRCULAR]
    assert [p.name for p in thesis_program.positions()] == [f"P{k}" for k in range(1, 11)]
    assert moves[0].target.name == "P1" and moves[0].step == "move to the start posture"
    grip = [i for i in thesis_program.instructions if isinstance(i, Gripper)]
    assert grip == [Gripper(1, False, "around O2")]
    assert moves[2].via.name == "P3" and moves[2].target.name == "P4"


def test_unnamed_waypoints_are_numbered_in_order_of_use(rv2aj):
    traj = thesis_trajectory(rv2aj)
    anon = Trajectory(replace(traj.start, name=""),
                      [replace(m, target=replace(m.target, name=""),
                               via=None if m.via is None else replace(m.via, name=""))
                       for m in traj.motions])
    prog = program_from_trajectory(anon, rv2aj, name="anon")
    assert [p.name for p in prog.positions()] == [f"P{k}" for k in range(1, 11)]


def test_move_to_start_is_optional(rv2aj):
    prog = program_from_trajectory(thesis_trajectory(rv2aj), rv2aj, name="t",
                                   move_to_start=False)
    assert prog.primitive_count() == 6  # the thesis' own count
    assert prog.q_start is not None
    check_program(prog, rv2aj)


def test_missing_joint_solution_names_the_step(rv2aj):
    traj = thesis_trajectory(rv2aj)
    m = traj.motions[4]
    traj.motions[4] = replace(m, target=Waypoint(m.target.T_base_tool, None, "P8"))
    with pytest.raises(ExportError, match=r"^step 'P7->P8': position P8 has no joint solution"):
        program_from_trajectory(traj, rv2aj, name="t")
    prog = NeutralProgram("t", [Move(MoveKind.LINEAR, Position("P8", np.eye(4)), step="a")])
    with pytest.raises(ExportError, match=r"^step 'a': position 'P8' has no joint solution"):
        check_program(prog, rv2aj)


def test_target_outside_joint_limits_names_step_and_joint(rv2aj, thesis_program):
    m = thesis_program.moves()[5]  # P7 -> P8
    q = m.target.q.copy()
    q[2] = np.radians(125.0)  # J3 beyond +120
    bad = replace(m.target, T_base_tool=rv2aj.fk(q), q=q)
    prog = _replace_position(thesis_program, m.target, bad)
    with pytest.raises(ExportError) as e:
        check_program(prog, rv2aj)
    assert str(e.value).startswith("step 'P7->P8': target 'P8' outside J3 limits")
    with pytest.raises(ExportError, match="outside J3 limits"):
        export_files(prog, "krl", rv2aj)


def test_a_target_out_of_reach_is_refused(rv2aj, thesis_program):
    m = thesis_program.moves()[3]  # LIN P5
    T = m.target.T_base_tool.copy()
    T[:3, 3] = [0.9, 0.0, 0.2]  # 900 mm away: the RV-2AJ reaches about 410 mm
    prog = _replace_position(thesis_program, m.target, replace(m.target, T_base_tool=T))
    with pytest.raises(ExportError, match=r"^step 'P4->P5': target 'P5'.*out of the arm's reach"):
        check_program(prog, rv2aj)


def test_a_linear_path_through_the_unreachable_centre_is_refused(rv2aj):
    a = waypoint(rv2aj, "PA", np.array([0.25, -0.20, 0.15]))
    b = waypoint(rv2aj, "PB", np.array([-0.25, 0.20, 0.15]), seed=np.radians(
        [140.0, 20.0, 90.0, 70.0, 0.0]))
    traj = Trajectory(a, [Motion(MotionKind.LINEAR, b, label="across the base")])
    prog = program_from_trajectory(traj, rv2aj, name="bad")
    with pytest.raises(ExportError, match=r"^step 'across the base': linear path"):
        check_program(prog, rv2aj)


def test_collinear_arc_and_duplicate_names_are_refused(rv2aj):
    a = waypoint(rv2aj, "PA", np.array([0.30, -0.05, 0.15]))
    v = waypoint(rv2aj, "PV", np.array([0.30, 0.00, 0.15]))
    b = waypoint(rv2aj, "PB", np.array([0.30, 0.05, 0.15]))
    traj = Trajectory(a, [Motion(MotionKind.CIRCULAR, b, via=v, label="flat arc")])
    with pytest.raises(ExportError, match=r"^step 'flat arc': .*on one line"):
        check_program(program_from_trajectory(traj, rv2aj, name="t"), rv2aj)
    twin = Waypoint(v.T_base_tool, v.q, "PA")  # another position called PA
    traj = Trajectory(a, [Motion(MotionKind.LINEAR, twin, label="twin")])
    with pytest.raises(ExportError, match="name 'PA' is used for two different positions"):
        program_from_trajectory(traj, rv2aj, name="t")


def test_gripper_output_clash_is_refused(rv2aj, thesis_program):
    from assistant.export import SetOutput

    prog = replace(thesis_program, instructions=thesis_program.instructions
                   + [SetOutput(1, True, "end")])
    with pytest.raises(ExportError, match=r"\$OUT\[1\] is the gripper's output"):
        export_files(prog, "krl", rv2aj, check=False)


def test_tool_actions_become_instructions(rv2aj):
    traj = thesis_trajectory(rv2aj)
    traj.actions_at_start = (ToolAction(ToolActionKind.GRIPPER_CLOSE, 2),)
    traj.motions[0] = replace(traj.motions[0], actions_after=(
        ToolAction(ToolActionKind.OUTPUT, 3, False), ToolAction(ToolActionKind.WAIT,
                                                                seconds=0.25)))
    prog = program_from_trajectory(traj, rv2aj, name="t")
    kinds = [type(i).__name__ for i in prog.instructions[:5]]
    assert kinds == ["Move", "Gripper", "Move", "SetOutput", "Wait"]


def test_bent_planned_joint_path_gets_intermediate_joint_targets(rv2aj):
    """A straight joint move would leave the planner's (collision-free) joint path."""
    q0 = np.radians([-40.0, 30.0, 80.0, 70.0, 0.0])
    q1 = np.radians([40.0, 30.0, 80.0, 70.0, 0.0])
    s = np.linspace(0.0, 1.0, 41)[:, None]
    path = q0 + s * (q1 - q0)
    path[:, 1] -= np.radians(25.0) * np.sin(np.pi * s[:, 0])  # lean back in the middle
    a = Waypoint(rv2aj.fk(q0), q0, "PA")
    b = Waypoint(rv2aj.fk(q1), q1, "PB")
    traj = Trajectory(a, [Motion(MotionKind.JOINT, b, joint_path=path, label="around")])
    prog = program_from_trajectory(traj, rv2aj, name="t")
    moves = prog.moves()
    assert len(moves) > 3 and all(m.kind == MoveKind.JOINT for m in moves)
    assert all(m.target.joint_target for m in moves[1:-1])
    sim = simulate(prog, rv2aj, q0, max_step=0.001)
    planned = rv2aj.batch_fk(path).positions
    got = sim.tcp_points()
    d = np.min(np.linalg.norm(planned[:, None] - got[None], axis=2), axis=1)
    assert d.max() < 0.002 + 0.001  # within the split tolerance (+ sampling)
    straight = program_from_trajectory(Trajectory(a, [Motion(MotionKind.JOINT, b)]), rv2aj,
                                       name="t")
    got2 = simulate(straight, rv2aj, q0, max_step=0.001).tcp_points()
    d2 = np.min(np.linalg.norm(planned[:, None] - got2[None], axis=2), axis=1)
    assert d2.max() > 0.02  # without the splits the robot would leave the plan


def _replace_position(prog, old, new):
    out = []
    for ins in prog.instructions:
        if isinstance(ins, Move):
            ins = replace(ins, target=new if ins.target is old else ins.target,
                          via=new if ins.via is old else ins.via)
        out.append(ins)
    return replace(prog, instructions=out)
