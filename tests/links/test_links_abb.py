"""AbbRwsLink against the IRC5 RWS emulator over real localhost HTTP: the thesis-like
execution (exploration, one collision, the exported RAPID program uploaded and run), the
operator's button, and the faults (drop, late replies, garbage, refused targets, login,
mastership held by someone else)."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from abb_fixtures import HOME, Q_A, Q_B, TIME_SCALE, ur5
from link_fixtures import box_on_sweep, sweep

from assistant.collision.checker import CollisionChecker
from assistant.emulators.abb_rws_emulator import AbbRwsEmulator
from assistant.export.download import export_files
from assistant.export.program import Frame, Move, MoveKind, NeutralProgram, Position
from assistant.links import LinkSettings, make_link
from assistant.links import abb_rws_protocol as rp
from assistant.links.abb_rws import AbbRwsLink
from assistant.links.errors import ControllerRefused, ProtocolError
from assistant.links.link import LinkError, LinkEventKind, LinkLost
from assistant.transforms import make_T

TOL = 1e-6  # rad: the wire carries 1e-6 deg


@pytest.fixture(scope="module")
def robot():
    return ur5()


@pytest.fixture
def start(robot, closing):
    def _start(emu_robot=None, link_kw=None, **kw):
        kw.setdefault("start_q", HOME)
        kw.setdefault("time_scale", TIME_SCALE)
        emu = closing(AbbRwsEmulator(emu_robot or robot, **kw).start())
        link = closing(AbbRwsLink(robot, port=emu.port, **{"timeout_s": 1.0, **(link_kw or {})}))
        link.connect()
        return emu, link

    return _start


def mission(robot) -> dict[str, bytes]:
    """The exported RAPID program: joint target home, a MoveJ, a short MoveL, home again."""
    q1 = np.radians([-20.0, -70.0, 80.0, -100.0, -90.0, 0.0])  # clear of the box
    T1 = robot.fk(q1)
    T2 = T1.copy()
    T2[2, 3] -= 0.05
    q2 = robot.ik(T2, q1).best(q1)
    home = Position("HOME", robot.fk(HOME), HOME, joint_target=True)
    prog = NeutralProgram("MISSION", [
        Move(MoveKind.JOINT, home),
        Move(MoveKind.JOINT, Position("P1", T1, q1), speed=0.5),
        Move(MoveKind.LINEAR, Position("P2", T2, q2), speed=0.1),
        Move(MoveKind.JOINT, home, speed=0.5)])
    result = export_files(prog, "rapid", robot)
    return {f.name: f.data for f in result.files}


def test_thesis_like_execution_explore_collide_replan_upload_run(start, robot):
    box = box_on_sweep(robot, Q_A, Q_B, 0.7, size=0.08)  # off the HOME -> Q_A sweep
    emu, link = start(hidden_obstacles=[box])
    assert np.allclose(link.current_joints(), HOME, atol=TOL)
    assert np.allclose(link.current_pose(), robot.fk(HOME), atol=1e-6)
    # Exploration: a dense planner path becomes a few MoveAbsJ and lands exactly.
    dense = np.vstack([sweep(HOME, Q_A, 60), sweep(Q_A, HOME, 60)[1:], sweep(HOME, Q_A, 60)[1:]])
    ev = link.move_path(dense)
    assert ev.kind == LinkEventKind.REACHED and ev.path_index == len(dense) - 1
    assert link.last_command_count == 3
    assert emu.rapid.symbol("CellMove", "cj3").startswith("[[-40.000000,-80.000000")
    assert np.allclose(emu.arm.q, Q_A, atol=TOL)
    # The hidden box stops the sweep: motion supervision (50204) in the event log.
    ev = link.move_path(sweep(Q_A, Q_B, 5))
    assert ev.kind == LinkEventKind.COLLISION_INDICATED, ev.message
    assert ev.details["code"] == rp.ELOG_MOTION_SUPERVISION and "hidden" in ev.message
    assert np.allclose(ev.q, emu.arm.q, atol=TOL)
    assert CollisionChecker(robot, [box], self_collision=False).is_valid(emu.arm.q)
    assert Q_A[0] < ev.q[0] < Q_A[0] + 0.7 * (Q_B[0] - Q_A[0])
    # Re-planned: back off home.
    assert link.move_path(np.array([ev.q, HOME])).kind == LinkEventKind.REACHED
    # The final program: uploaded, loaded (our CellMove unloaded first), run to its end.
    # The task keeps its own MainModule (a shipped task has a main): our main goes in as
    # the routine ct_MISSION, started with "set PP to routine".
    files = mission(robot)
    assert link.upload_program("MISSION", files) == "MISSION"
    assert emu.rapid.files["$HOME/MISSION.MOD"] == rp.main_as_routine(
        files["MISSION.mod"].decode(), "ct_MISSION").encode()
    assert [m.name for m, _ in emu.rapid.modules.values()] == ["MainModule", "MISSION"]
    moved: list = []
    link.subscribe(lambda e: moved.append(e) if e.kind == LinkEventKind.MOVED else None)
    ev = link.run_program("MISSION")
    assert ev.kind == LinkEventKind.REACHED and "MISSION finished" in ev.message
    # the link told the arm's pose while the program ran (how often depends on the machine's
    # load: a busy one merges updates, so no count)
    assert emu.rapid.runs[-1] == "MISSION" and moved
    assert np.allclose(emu.arm.q, HOME, atol=TOL)
    assert emu.sessions.master is None  # mastership given back after each load


def test_operator_button_and_stop_during_a_move(start):
    emu, link = start()
    first = threading.Event()
    link.subscribe(lambda e: first.set() if e.kind == LinkEventKind.MOVED else None)

    def press():
        first.wait(10.0)
        while emu.arm.q[0] > 0.5 * Q_A[0] and not done.is_set():
            done.wait(0.002)
        link.indicate_collision("operator: cable snagged")

    done = threading.Event()
    th = threading.Thread(target=press)
    th.start()
    ev = link.move_path(np.array([HOME, Q_A]), speed_scale=0.1)
    done.set()
    th.join(timeout=10.0)
    assert ev.kind == LinkEventKind.COLLISION_INDICATED and ev.path_index == 1
    assert ev.details["source"] == "operator" and "cable" in ev.message
    assert np.allclose(ev.q, emu.arm.q, atol=TOL) and not emu.arm.moving
    assert Q_A[0] < ev.q[0] < 0.0
    # A plain stop from another thread is STOPPED; the link moves on afterwards.
    timer = threading.Timer(0.1, link.stop)
    timer.start()
    ev = link.move_path(np.array([ev.q, Q_B]), speed_scale=0.1)
    timer.join()
    assert ev.kind == LinkEventKind.STOPPED and not emu.arm.moving
    assert link.move_path(np.array([HOME])).kind == LinkEventKind.REACHED


def test_drop_mid_move_then_reconnect_and_resume(start):
    emu, link = start()
    emu.faults.drop_mid_move(after_moving_s=0.1)
    ev = link.move_path(np.array([Q_A, Q_B]), speed_scale=0.25)
    assert ev.kind == LinkEventKind.LINK_LOST and emu.faults.drops == 1
    assert not link.connected and "lost" in ev.message
    with pytest.raises(LinkError, match="not connected"):
        link.move_path(np.array([Q_B]))
    deadline = threading.Event()
    deadline.wait(emu.unplug_s)  # the cable is back after unplug_s
    link.connect()  # a fresh login: the controller forgot the old session
    q_now = link.current_joints()
    assert np.allclose(q_now, emu.arm.q, atol=TOL) and not emu.arm.moving
    assert link.move_path(np.array([q_now, Q_B])).kind == LinkEventKind.REACHED
    assert np.allclose(emu.arm.q, Q_B, atol=TOL)


def test_late_replies_past_the_timeout(start):
    emu, link = start(link_kw={"timeout_s": 0.3})
    emu.faults.delay_replies(1.0)
    with pytest.raises(LinkLost, match="no answer to GET /rw/motionsystem"):
        link.current_joints()
    assert not link.connected
    emu.faults.clear()
    link.connect()
    emu.faults.delay_replies(1.0)
    ev = link.move_path(np.array([Q_A]))
    assert ev.kind == LinkEventKind.LINK_LOST and "no answer to" in ev.message
    emu.faults.clear()
    link.connect()
    ev = link.move_path(np.array([Q_A]))
    assert ev.kind == LinkEventKind.REACHED, ev.message


def test_garbage_replies_are_quoted_and_the_program_is_stopped(start):
    emu, link = start()
    emu.faults.garble_next(1)
    with pytest.raises(ProtocolError, match="GARBLED"):
        link.current_joints()
    ev = None
    armed = threading.Event()

    def garble_once_moving(e):
        if e.kind == LinkEventKind.MOVED and not armed.is_set():
            armed.set()
            emu.faults.garble_next(1)

    link.subscribe(garble_once_moving)
    ev = link.move_path(np.array([Q_A, Q_B]), speed_scale=0.2)
    assert ev.kind == LinkEventKind.ERROR and "GARBLED" in ev.message
    assert "program stopped" in ev.message and not emu.rapid.running and not emu.arm.moving
    assert link.connected
    link.unsubscribe(garble_once_moving)
    assert link.move_path(np.array([Q_B])).kind == LinkEventKind.REACHED
    assert np.allclose(emu.arm.q, Q_B, atol=TOL)


def test_refused_targets(start, robot):
    narrow = robot.with_limits(np.column_stack([robot.limits.lower, robot.limits.upper])
                               * np.array([[0.2], [1], [1], [1], [1], [1]]))
    emu, link = start(emu_robot=narrow)
    n = len(emu.received)
    bad = HOME.copy()
    bad[1] = np.radians(400.0)
    with pytest.raises(LinkError, match="outside"):
        link.move_path(np.array([HOME, bad]))
    assert len(emu.received) == n  # refused before anything was sent
    # Inside our model's range, outside the controller's (axis 1 at +-72 deg): event 50027.
    far = HOME.copy()
    far[0] = np.radians(100.0)
    ev = link.move_path(np.array([HOME, far]))
    assert ev.kind == LinkEventKind.ERROR and ev.details["code"] == rp.ELOG_JOINT_OUT_OF_RANGE
    assert "Joint Out of Range" in ev.message and "outside" in ev.message
    assert np.allclose(emu.arm.q, HOME, atol=TOL)
    # A module the controller cannot load: the refusal with its code, nothing runs.
    with pytest.raises(ControllerRefused, match="cannot load") as info:
        link.upload_program("x", {"x.mod": b"MODULE x\n  FOO bar\nPROC main()\nENDPROC\n"
                                           b"ENDMODULE\n"})
    assert info.value.code == str(rp.RC_LOAD_ERROR)
    with pytest.raises(LinkError, match="exactly one module with PROC main"):
        link.upload_program("y", {"y.mod": b"MODULE y\nENDMODULE\n"})


def test_login_motors_and_mastership_held_elsewhere(start, robot, closing):
    emu, link = start()
    emu.rapid.motors_on = False  # e.g. after an emergency stop was reset
    link.connect()  # switches the motors on (allowed in AUTO), as a cell operator would
    assert emu.rapid.motors_on
    wrong = closing(AbbRwsLink(robot, port=emu.port, password="nope"))
    with pytest.raises(LinkError, match="refused the login of 'Default User'"):
        wrong.connect()
    other = closing(AbbRwsLink(robot, port=emu.port))
    other.connect()
    other.request_mastership()
    ev = link.move_path(np.array([Q_A]))
    assert ev.kind == LinkEventKind.ERROR and "held by another client" in ev.message
    assert ev.details["code"] == str(rp.RC_HELD_BY_OTHER) and not emu.arm.moving
    other.release_mastership()
    assert link.move_path(np.array([Q_A])).kind == LinkEventKind.REACHED


def test_settings_build_the_abb_link(start, robot, closing):
    emu, _ = start()
    s = LinkSettings.from_json({"kind": "abb", "port": emu.port, "rws_user": "Default User",
                                "rws_password": "robotics"})
    link = closing(make_link(s, robot))
    assert isinstance(link, AbbRwsLink)
    link.connect()
    assert link.move_path(np.array([HOME, Q_A])).kind == LinkEventKind.REACHED


def test_an_exported_program_with_tool_and_work_object_lands_where_planned(robot, closing):
    """tooldata and wobjdata travel in the module; the controller (bare arm, tool0 = flange)
    must put the planned joints where the planner put them."""
    T_tool = make_T(p=[0.0, 0.0, 0.12])
    tooled = robot.with_tool(T_tool)
    emu = closing(AbbRwsEmulator(robot, start_q=HOME, time_scale=TIME_SCALE).start())
    link = closing(AbbRwsLink(tooled, port=emu.port))
    link.connect()
    q1 = np.radians([-20.0, -70.0, 80.0, -100.0, -90.0, 30.0])
    T1 = tooled.fk(q1)
    T2 = T1.copy()
    T2[:3, 3] += [0.03, 0.02, -0.04]
    q2 = tooled.ik(T2, q1).best(q1)
    prog = NeutralProgram("TOOLED", [
        Move(MoveKind.JOINT, Position("P1", T1, q1), speed=0.5),
        Move(MoveKind.LINEAR, Position("P2", T2, q2), speed=0.1)],
        tool=Frame("gripper", T_tool), work=Frame("table", make_T(p=[0.3, -0.2, 0.05])))
    files = {f.name: f.data for f in export_files(prog, "rapid", tooled).files}
    text = files["TOOLED.mod"].decode()
    assert "PERS tooldata tGripper" in text and "wobjdata wTable" in text
    link.upload_program("TOOLED", files)
    assert link.run_program().kind == LinkEventKind.REACHED
    # The module carries 0.001 mm and 6-decimal quaternions: ~1e-6 m and rad, bound 1e-5.
    assert np.allclose(emu.arm.q, q2, atol=1e-5)
    assert np.allclose(link.current_pose(), T2, atol=1e-5)


def test_reduced_speed_stretches_a_move_and_the_link_follows_it(start):
    """Manual mode's reduced speed (here the arm at 5 % of the planned pace) stretches a move
    many times past its planned time plus the timeout: the link follows the moving arm to
    the end rather than stopping it as a program that never ends."""
    emu, link = start(link_kw={"timeout_s": 0.3}, time_scale=0.05)
    ev = link.move_path(np.array([HOME, Q_A]))
    assert ev.kind == LinkEventKind.REACHED, ev.message
    assert np.allclose(emu.arm.q, Q_A, atol=TOL)
