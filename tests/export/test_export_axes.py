"""Dialects refuse robots their controller does not run (issue 32 item 5).

URScript runs on 6-axis UR arms; MELFA on 4-, 5- and 6-axis Mitsubishi arms; FANUC TP and
Yaskawa INFORM are written for 4- to 6-axis arms (a FANUC position's seventh value would be
an extended axis, a Motoman 7-axis arm's elbow angle Re is not public); KRL writes the main
axes A1..A6 and a 7-axis arm's third joint as E1 (KUKA LBR); RAPID the robot axes
rax_1..rax_6 and a 7-axis arm's third joint as eax_a (IRB 14000 YuMi); what they write for a
7-axis arm is tested in test_export_seven_axes.py. The refusal is an `ExportError` before
anything is checked or written, at every way into a program: the download (`export_files`),
the round-trip proof and each dialect's `write`.
"""

from __future__ import annotations

import numpy as np
import pytest

from assistant.export import (
    DIALECT_NAMES,
    ExportError,
    Frame,
    Move,
    MoveKind,
    NeutralProgram,
    Position,
    export_files,
    get_dialect,
    round_trip,
)
from assistant.export.dialect import check_axis_count
from assistant.robots.urdf_robot import URDFRobot

#: What every dialect takes, as the refusal of an axis count no dialect writes ends.
TAKES = ("MELFA, FANUC and Yaskawa take 4, 5 or 6 axes; KRL and RAPID take 4, 5, 6 or 7 axes; "
         "URScript takes 6 axes.")
SEVEN_AXES = "Choose KRL or RAPID for a 7-axis arm."


def chain_urdf(n: int) -> str:
    """A plain serial arm with `n` revolute joints j1..jn, 0.1 m apart (no meshes)."""
    links = "".join(f'<link name="l{k}"/>' for k in range(n + 1))
    joints = "".join(
        f'<joint name="j{k}" type="revolute"><parent link="l{k - 1}"/><child link="l{k}"/>'
        f'<origin xyz="0 0 0.1"/><axis xyz="{"0 0 1" if k % 2 else "0 1 0"}"/>'
        f'<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>'
        for k in range(1, n + 1))
    return f'<robot name="arm{n}">{links}{joints}</robot>'


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    """n -> an n-axis URDF arm, built from a string."""
    base = tmp_path_factory.mktemp("arms")

    def make(n: int) -> URDFRobot:
        return URDFRobot.from_string(chain_urdf(n), base_dir=base, load_visual=False)

    return make


def one_joint_move(robot) -> NeutralProgram:
    """A program any arm could run if its controller took it: one joint move."""
    q = np.full(robot.dof, 0.1)
    return NeutralProgram("axes", [Move(MoveKind.JOINT, Position("P1", None, q,
                                                                  joint_target=True))],
                          Frame("tool"), q_start=np.zeros(robot.dof))


# ------------------------------------------------------------------ declared axis counts
def test_each_dialect_declares_the_axis_counts_its_controller_runs():
    assert {n: get_dialect(n).axis_counts for n in DIALECT_NAMES} == {
        "melfa": (4, 5, 6), "krl": (4, 5, 6, 7), "rapid": (4, 5, 6, 7), "urscript": (6,),
        "fanuc": (4, 5, 6), "yaskawa": (4, 5, 6)}


# ------------------------------------------------------------------ 7 axes: KRL and RAPID
@pytest.mark.parametrize("dialect", ["melfa", "urscript", "fanuc", "yaskawa"])
def test_a_seven_axis_panda_is_refused_by_the_six_axis_dialects(panda, dialect):
    assert panda.dof == 7
    prog = one_joint_move(panda)
    with pytest.raises(ExportError) as e:
        export_files(prog, dialect, panda)
    assert e.value.dialect == dialect
    rule = {
        "urscript": "URScript runs on 6-axis UR arms",
        "melfa": "MELFA BASIC runs on 4-, 5- and 6-axis Mitsubishi arms (RH SCARA, 5-axis "
                 "RV such as the RV-2AJ, 6-axis RV)",
        # the format cannot hold a redundant arm joint: the reason is part of the refusal
        "fanuc": "FANUC TP positions hold the joints J1..J6 of 4- to 6-axis FANUC arms; this "
                 "robot (panda) has 7 axes. A seventh joint would be an extended axis E1 (a "
                 "rail or positioner) in FANUC's positions, not an arm joint, so a 7-axis arm "
                 "cannot be written",
        "yaskawa": "INFORM Cartesian positions are written here for 4- to 6-axis Motoman arms; "
                   "this robot (panda) has 7 axes. A 7-axis arm's (SIA, SDA) Cartesian "
                   "positions carry its elbow angle Re, which Yaskawa does not define "
                   "publicly, and pulse positions need the controller's pulses per degree",
    }[dialect]
    if dialect in ("fanuc", "yaskawa"):
        assert str(e.value) == f"{rule}. {SEVEN_AXES}"
    else:
        assert str(e.value) == f"{rule}; this robot (panda) has 7 axes. {SEVEN_AXES}"
    # The same refusal from the round-trip proof and from the writer itself.
    with pytest.raises(ExportError, match="has 7 axes"):
        round_trip(prog, dialect, panda)
    with pytest.raises(ExportError, match="has 7 axes"):
        get_dialect(dialect).write(prog, panda)


def test_urscript_refuses_seven_axes_before_checking_the_program(panda, rv2aj, thesis_program):
    """The axis count is the first thing looked at: the RV-2AJ's thesis program is nonsense
    for a Panda (five joint values), yet the operator reads why the dialect does not fit."""
    with pytest.raises(ExportError) as e:
        export_files(thesis_program, "urscript", panda)
    assert str(e.value).startswith("URScript runs on 6-axis UR arms; this robot (panda) has 7")


@pytest.mark.parametrize("dialect", ["melfa", "urscript", "fanuc", "yaskawa"])
def test_a_seven_axis_arm_from_a_urdf_string_is_refused(arm, dialect):
    robot = arm(7)
    with pytest.raises(ExportError, match="this robot \\(arm7\\) has 7 axes. (.* )?Choose "
                       "KRL or RAPID for a 7-axis arm.$"):
        export_files(one_joint_move(robot), dialect, robot)


@pytest.mark.parametrize("dialect", ["krl", "rapid"])
def test_a_seven_axis_arm_is_accepted_by_krl_and_rapid(arm, panda, dialect):
    for robot in (panda, arm(7)):
        check_axis_count(get_dialect(dialect), robot)


# ------------------------------------------------------------------ 8 axes: refused by all
@pytest.mark.parametrize("dialect", DIALECT_NAMES)
def test_an_eight_axis_arm_is_refused_by_every_dialect(arm, dialect):
    robot = arm(8)
    prog = one_joint_move(robot)
    with pytest.raises(ExportError) as e:
        export_files(prog, dialect, robot)
    msg = str(e.value)
    assert e.value.dialect == dialect
    assert "this robot (arm8) has 8 axes." in msg
    assert msg.endswith(f"No dialect here writes an 8-axis arm: {TAKES}")
    beyond = {"krl": "Further axes would be external axes E2.., which this exporter does not "
                     "write.",
              "rapid": "Further axes would be external axes eax_b.., which this exporter "
                       "does not write."}.get(dialect)
    assert beyond is None or beyond in msg
    for run in (lambda: round_trip(prog, dialect, robot),
                lambda: get_dialect(dialect).write(prog, robot)):
        with pytest.raises(ExportError, match="has 8 axes"):
            run()


def test_a_three_axis_arm_is_refused_by_every_dialect(arm):
    robot = arm(3)
    for dialect in DIALECT_NAMES:
        with pytest.raises(ExportError) as e:
            export_files(one_joint_move(robot), dialect, robot)
        assert str(e.value).endswith(f"No dialect here writes a 3-axis arm: {TAKES}")


# ------------------------------------------------------------------ 5 axes: not URScript
def test_the_five_axis_rv2aj_is_refused_by_urscript(rv2aj, thesis_program):
    message = ("URScript runs on 6-axis UR arms; this robot (Mitsubishi RV-2AJ) has 5 axes. "
               "Choose MELFA, FANUC, Yaskawa, KRL or RAPID for a 5-axis arm.")
    for run in (lambda: export_files(thesis_program, "urscript", rv2aj),
                lambda: round_trip(thesis_program, "urscript", rv2aj),
                lambda: get_dialect("urscript").write(thesis_program, rv2aj)):
        with pytest.raises(ExportError) as e:
            run()
        assert str(e.value) == message and e.value.dialect == "urscript"


@pytest.mark.parametrize("dialect", ["melfa", "krl", "rapid", "fanuc", "yaskawa"])
def test_the_rv2aj_is_accepted_by_the_others(rv2aj, dialect):
    check_axis_count(get_dialect(dialect), rv2aj)


@pytest.mark.parametrize("n", [4, 5])
def test_four_and_five_axis_arms_are_pointed_away_from_urscript(arm, n):
    robot = arm(n)
    with pytest.raises(ExportError, match=f"Choose MELFA, FANUC, Yaskawa, KRL or RAPID for a "
                       f"{n}-axis arm"):
        check_axis_count(get_dialect("urscript"), robot)
    for dialect in ("melfa", "krl", "rapid", "fanuc", "yaskawa"):
        check_axis_count(get_dialect(dialect), robot)


# ------------------------------------------------------------------ 6 axes: everyone
@pytest.mark.parametrize("dialect", DIALECT_NAMES)
def test_the_six_axis_ur5_is_accepted_by_every_dialect(ur5, program_for, dialect):
    program = program_for("thesis", ur5)
    res = export_files(program, dialect, ur5, check=False)  # checks: test_export_download
    assert res.dialect == dialect and res.primitives == 7
    if dialect == "urscript":
        text = res.files[0].data.decode("ascii")
        assert "P1_q = [" in text
        assert all(len(line.split("[")[1].split(",")) == 6
                   for line in text.splitlines() if "_q = [" in line)
