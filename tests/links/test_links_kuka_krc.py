"""The controller side of the KUKA bridge: the shipped KRL program is read by the project's
KRL reader (extended by control statements) and driven by the emulated KR C4 on the KR 6
R900 sixx from the robot catalogue, with the shipped bridge server in front and our KUKA link
as the client: moves, the TCP, refusals by the program's own checks, a halt of the program
that the bridge reports instead of hanging, and an exported program run through the bridge.
"""

from __future__ import annotations

import numpy as np
import pytest
from krl_reader import problems

from assistant.emulators.kuka_krc_emulator import KukaKrcEmulator, kuka_arm
from assistant.links import kuka_protocol as kp
from assistant.links.kuka_bridge import files
from assistant.links.kuka_rest import KukaRestLink
from assistant.links.link import LinkEventKind
from assistant.robots.catalog import CATALOG, RobotSpec, ToolSpec

HOME = np.radians([0.0, -90.0, 90.0, 0.0, 45.0, 0.0])
Q1 = np.radians([25.0, -75.0, 95.0, 15.0, 40.0, 30.0])
Q2 = np.radians([-30.0, -70.0, 100.0, -10.0, 50.0, -20.0])
#: The bridge's numbers: 6 decimals of mm/deg on the wire and on the file channel; the arm
#: lands within the IK's own tolerance of them (1e-9 rad), so 1e-5 rad bounds it.
TOL = 1e-5


@pytest.fixture(scope="module")
def robot():
    return RobotSpec(kind="kuka_kr6_r900_sixx",
                     tool=ToolSpec.straight(0.1, 0.02, has_gripper=False)).build()


def _texts() -> tuple[str, str]:
    p = files()
    return p["cellbridge.src"].read_text(), p["cellbridge.dat"].read_text()


def test_the_krl_program_is_read_by_the_projects_krl_reader():
    src, dat = _texts()
    assert problems("cellbridge.src", src, "cellbridge.dat", dat) == []
    # The reader is not a rubber stamp: it finds a missing ENDIF, an undeclared variable,
    # a misspelt system variable and a renamed module.
    broken = src.replace("      ENDIF\n      pAux = $POS_ACT", "      pAux = $POS_ACT", 1)
    assert any("ends too early" in p or "unexpected" in p
               for p in problems("cellbridge.src", broken, "cellbridge.dat", dat))
    assert any("nGhost is used but not declared" in p for p in problems(
        "cellbridge.src", src.replace("nLast = nCid", "nGhost = nCid"), "cellbridge.dat", dat))
    assert any("$POS_ACTUAL" in p for p in problems(
        "cellbridge.src", src.replace("pTgt = $POS_ACT\n", "pTgt = $POS_ACTUAL\n"),
        "cellbridge.dat", dat))
    assert any("file is CELLBRIDGE" in p for p in problems(
        "cellbridge.src", src.replace("DEF cellbridge( )", "DEF other( )"), "cellbridge.dat",
        dat))


def test_the_catalogue_arm_follows_the_data_sheet(robot):
    arm = CATALOG["kuka_kr6_r900_sixx"]
    assert arm.vendor == "kuka_rest" and "KR AGILUS" in arm.source
    assert np.allclose(np.degrees(robot.limits.upper), [170, 45, 156, 185, 120, 350])
    assert np.allclose(np.degrees(robot.limits.lower), [-170, -190, -120, -185, -120, -350])
    flange = kuka_arm("flange")
    # The candle (A2 -90, A3 +90): the flange 25 + 420 + 80 mm forward, 400 + 455 + 35 up.
    T = flange.fk(np.radians([0.0, -90.0, 90.0, 0.0, 0.0, 0.0]))
    assert np.allclose(T[:3, 3], [0.525, 0.0, 0.890], atol=1e-9)
    assert np.allclose(T[:3, 0], [1.0, 0.0, 0.0], atol=1e-9)  # $FLANGE: x out of the flange
    # Reach: the wrist point (A5) at most 455 + hypot(420, 35) mm from A2.
    wrist = np.hypot(0.42, 0.035) + 0.455
    assert abs(wrist - 0.8765) < 1e-3


def test_the_krl_program_drives_the_kuka_arm_through_the_bridge(robot, closing):
    emu = closing(KukaKrcEmulator(time_scale=5.0, bridge_timeout_s=20.0, start_q=HOME).start())
    link = closing(KukaRestLink(robot, port=emu.port, timeout_s=5.0))
    link.connect()  # sets the TCP through the program ($TOOL = XFLANGE_TOOL0 : tcp)
    assert np.allclose(link.current_joints(), HOME, atol=TOL)
    assert np.allclose(link.current_pose(), robot.fk(HOME), atol=1e-5)
    ev = link.move_path(np.array([HOME, Q2, Q1]))
    assert ev.kind == LinkEventKind.REACHED, (ev.message, emu.messages)
    assert np.allclose(emu.arm.q, Q1, atol=TOL) and link.last_command_count == 2
    T = robot.fk(Q1)
    T[2, 3] -= 0.05
    ev = link.move_linear(T)
    assert ev.kind == LinkEventKind.REACHED, (ev.message, emu.messages)
    assert np.allclose(robot.fk(emu.arm.q)[:3, 3], T[:3, 3], atol=1e-5)
    # The program's own checks: a target beyond the software limit switches (narrowed on
    # this controller) is refused with statuscode -1 and nothing moves.
    narrow = np.radians([[-20.0, 40.0], [-190, 45], [-120, 156], [-185, 185], [-120, 120],
                         [-350, 350]])
    emu.machine.robot = emu.machine.robot.with_limits(narrow)
    q_before = emu.arm.q.copy()
    ev = link.move_path(np.array([link.current_joints(), Q2]))
    assert ev.kind == LinkEventKind.ERROR, ev.message
    assert ev.details["statuscode"] == kp.STATUS_LIMIT and np.allclose(emu.arm.q, q_before)
    assert emu.program_running.is_set()  # a refused command does not stop the program


def test_a_halted_program_is_reported_then_acknowledged(robot, closing):
    from link_fixtures import box_on_sweep

    box = box_on_sweep(robot, HOME, Q1, 0.5, size=0.1)
    emu = closing(KukaKrcEmulator(time_scale=5.0, bridge_timeout_s=1.5, start_q=HOME,
                                  hidden_obstacles=[box]).start())
    link = closing(KukaRestLink(robot, port=emu.port, timeout_s=5.0))
    link.connect()
    ev = link.move_path(np.array([HOME, Q1]))
    # The collision halts the KRL program (as a KR C4 does); the bridge does not hang: it
    # says after its timeout that the program did not answer.
    assert ev.kind == LinkEventKind.ERROR and "did not answer" in ev.message, ev.message
    assert emu.wait_halted(10.0) and "collision" in emu.messages[-1]
    emu.acknowledge()  # the operator confirms the message and starts cellbridge again
    ev = link.move_path(np.array([link.current_joints(), HOME]))
    assert ev.kind == LinkEventKind.REACHED, (ev.message, emu.messages)


def test_an_exported_krl_program_runs_through_the_bridge(robot, closing):
    from assistant.export import get_dialect
    from assistant.export.program import Move, MoveKind, NeutralProgram, Position

    T1 = robot.fk(Q1)
    T2 = T1.copy()
    T2[1, 3] += 0.06
    q2 = robot.ik(T2, Q1).best(Q1)
    prog = NeutralProgram("CELLJOB", [Move(MoveKind.JOINT, Position("P1", T1, Q1)),
                                      Move(MoveKind.LINEAR, Position("P2", T2, q2), speed=0.2)])
    out = get_dialect("krl").write(prog, robot)
    emu = closing(KukaKrcEmulator(time_scale=10.0, bridge_timeout_s=20.0, start_q=HOME).start())
    link = closing(KukaRestLink(robot, port=emu.port, timeout_s=5.0))
    link.connect()
    name = link.upload_program("celljob", {f.name: f.text.encode() for f in out})
    assert name.lower().startswith("celljob_")
    assert np.allclose(robot.fk(emu.arm.q)[:3, 3], T2[:3, 3], atol=1e-5)
    assert np.allclose(link.current_joints(), emu.arm.q, atol=TOL)
