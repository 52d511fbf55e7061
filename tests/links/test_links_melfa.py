"""MelfaLink against the MELFA emulator over real localhost TCP: the thesis-like session and
the faults (drop mid-move, late replies, garbage, refused targets)."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from link_fixtures import FAST_SPEEDS, HOME, Q_A, Q_B, box_on_sweep, sweep

from assistant.collision.checker import CollisionChecker
from assistant.emulators.faults import GARBAGE
from assistant.emulators.melfa_emulator import MelfaEmulator
from assistant.links import melfa_protocol as mp
from assistant.links.errors import ProtocolError
from assistant.links.link import LinkError, LinkEventKind, LinkLost
from assistant.links.melfa import MelfaLink
from assistant.robots.model import Tool
from assistant.robots.rv2aj import RV2AJ, RV2AJConfig

TOL = np.radians(0.02)  # JPOSF carries 0.01 deg


@pytest.fixture
def start(fast_robot, closing):
    """start(**emulator_kw) -> (emulator, connected link), both closed at teardown."""

    def _start(robot=None, link_kw=None, **kw):
        kw.setdefault("tick_s", 0.004)
        kw.setdefault("start_q", HOME)
        emu = closing(MelfaEmulator(robot or fast_robot, **kw).start())
        opts = {"stream_cycle_s": 0.004, "timeout_s": 1.5, "status_period_s": 0.02,
                "connect_timeout_s": 1.0, **(link_kw or {})}
        link = closing(MelfaLink(fast_robot, port=emu.port, datalink_port=emu.datalink_port(),
                                 **opts))
        link.connect()
        return emu, link

    return _start


def on_first_move(link, action):
    """Run `action` once, on the first MOVED event (i.e. while the arm is moving)."""
    done = threading.Event()

    def listener(ev):
        if ev.kind == LinkEventKind.MOVED and not done.is_set():
            done.set()
            action()

    link.subscribe(listener)
    return done


def test_thesis_like_session_explore_collide_replan_upload(start, fast_robot):
    box = box_on_sweep(fast_robot, Q_A, Q_B, 0.5)
    emu, link = start(hidden_obstacles=[box])
    kinds: list = []
    link.subscribe(lambda e: kinds.append(e.kind))
    assert link.connected and np.allclose(link.current_joints(), HOME, atol=TOL)
    # Exploration moves (streamed through the data link).
    ev = link.move_path(sweep(HOME, Q_A, 4))
    assert ev.kind == LinkEventKind.REACHED and ev.path_index == 3
    assert np.allclose(emu.arm.q, Q_A, atol=TOL)
    assert LinkEventKind.MOVED in kinds
    streamed = emu.received_texts("COM2")
    assert streamed and streamed[0].startswith("0,(")
    # The sweep runs into the hidden box: the controller stops, the link reports it.
    ev = link.move_path(sweep(Q_A, Q_B, 5))
    assert ev.kind == LinkEventKind.COLLISION_INDICATED
    assert ev.details["error_code"] == f"{mp.ERR_COLLISION:04d}"
    assert "Collision" in ev.details["controller_message"]
    assert np.allclose(ev.q, emu.arm.q, atol=TOL)
    chk = CollisionChecker(fast_robot, [box], self_collision=False)
    assert chk.is_valid(emu.arm.q)
    assert Q_A[0] < ev.q[0] < Q_A[0] + 0.5 * (Q_B[0] - Q_A[0])
    assert ev.path_index in (0, 1)
    assert link.read_error() == (0, "")  # recorded, then the alarm was reset
    # Re-planned: back off to HOME, then continue.
    assert link.move_path(np.array([ev.q, HOME])).kind == LinkEventKind.REACHED
    assert np.allclose(emu.arm.q, HOME, atol=TOL)
    # The final program, uploaded twice: two different names, both stored.
    j1, j2 = (mp.format_joint_literal(q, fast_robot.joint_names) for q in (Q_A, HOME))
    fl1, fl2 = mp.pose_flags(fast_robot, Q_A)
    p1 = mp.format_pose_literal(mp.MelfaPose(fast_robot.fk(Q_A), fl1, fl2))
    files = {"PICK.MB4": b"10 OVRD 100\n20 MOV J1\n30 MVS P1\n40 HCLOSE 1\n50 MOV J2\n60 END\n",
             "PICK.POS": f"J1={j1}\nJ2={j2}\nP1={p1}\n".encode()}
    name1 = link.upload_program("pick", files)
    name2 = link.upload_program("pick", files)
    assert name1 != name2 and name1.startswith("PICK")
    assert {name1, name2} <= set(link.program_names())
    assert emu.programs[name1].code[30] == "MVS P1"
    ev = link.run_program(name1)
    assert ev.kind == LinkEventKind.REACHED
    assert np.allclose(emu.arm.q, HOME, atol=TOL) and emu.hands == {1: True}


def test_cartesian_target_lands_on_the_planned_branch(start, fast_robot):
    emu, link = start()
    # Elbow-down twin of Q_A: same TCP pose, a different IK branch than the nearest one.
    twin = [s for s in fast_robot.ik(fast_robot.fk(Q_A)).solutions
            if not np.allclose(s, Q_A, atol=1e-6)]
    assert twin
    for q in (twin[0], Q_A):
        ev = link.move_to_pose(fast_robot.fk(q), seed=q)
        assert ev.kind == LinkEventKind.REACHED
        assert np.allclose(emu.arm.q, q, atol=np.radians(0.05))


def test_stop_from_another_thread_while_streaming(start):
    emu, link = start()
    on_first_move(link, lambda: threading.Thread(target=link.stop).start())
    path = np.vstack([sweep(HOME, Q_A, 3), sweep(Q_A, Q_B, 3), sweep(Q_B, Q_A, 3)])
    ev = link.move_path(path, speed_scale=0.2)
    assert ev.kind == LinkEventKind.STOPPED
    assert ev.path_index < len(path) - 1
    assert not emu.arm.moving and np.allclose(ev.q, emu.arm.q, atol=TOL)
    assert link.move_path(np.array([HOME])).kind == LinkEventKind.REACHED


def test_drop_mid_move_reports_link_lost_then_reconnect_and_resume(start):
    emu, link = start()
    lost: list = []
    link.subscribe(lambda e: lost.append(e) if e.kind == LinkEventKind.LINK_LOST else None)
    emu.faults.drop_mid_move(after_moving_s=0.05)
    path = np.vstack([sweep(HOME, Q_A, 3), sweep(Q_A, Q_B, 3)])
    ev = link.move_path(path, speed_scale=0.25)
    assert ev.kind == LinkEventKind.LINK_LOST and lost == [ev]
    assert emu.faults.drops == 1
    assert not link.connected
    # Disconnected: the robot counts as stopped at its last known joints.
    assert np.allclose(link.current_joints(), ev.q)
    with pytest.raises(LinkError, match="not connected"):
        link.move_path(path)
    # Reconnect (the controller's data-link alarm is reset), re-plan from where it is.
    link.connect()
    q_now = link.current_joints()
    assert np.allclose(q_now, emu.arm.q, atol=TOL)
    assert not np.allclose(q_now, Q_B, atol=0.1)  # it really stopped part-way
    ev = link.move_path(np.array([q_now, Q_B]))
    assert ev.kind == LinkEventKind.REACHED
    assert np.allclose(emu.arm.q, Q_B, atol=TOL)


def test_late_replies_past_the_timeout(start):
    emu, link = start(link_kw={"timeout_s": 0.3})
    # Mid-move: the acknowledgements stop coming in time.
    on_first_move(link, lambda: emu.faults.delay_replies(1.0))
    ev = link.move_path(np.vstack([sweep(HOME, Q_A, 3), sweep(Q_A, Q_B, 3)]), speed_scale=0.2)
    assert ev.kind == LinkEventKind.LINK_LOST and "within" in ev.message
    assert not link.connected
    emu.faults.clear()
    link.connect()
    # Idle: a status read that is answered too late.
    emu.faults.delay_replies(1.0)
    with pytest.raises(LinkLost, match="no reply to 'JPOSF'"):
        link.current_joints()
    assert not link.connected
    emu.faults.clear()
    # The link works again once reconnected - timed like a shop link (seen at load 10-12: an
    # unfaulted acknowledgement took more than the 0.3 s the fault phases need).
    link.timeout_s = 1.5
    link.connect()
    ev = link.move_path(np.array([HOME]))
    assert ev.kind == LinkEventKind.REACHED, ev.message


def test_garbage_replies_are_quoted_never_a_crash(start):
    emu, link = start()
    emu.faults.garble_next(1)
    with pytest.raises(ProtocolError) as info:
        link.current_joints()
    assert repr(GARBAGE + "\r") in str(info.value)
    assert link.connected and np.allclose(link.current_joints(), HOME, atol=TOL)
    # During a stream: the move ends with ERROR quoting the reply; the link stays usable.
    on_first_move(link, lambda: emu.faults.garble_next(1))
    ev = link.move_path(np.vstack([sweep(HOME, Q_A, 3), sweep(Q_A, Q_B, 3)]), speed_scale=0.2)
    assert ev.kind == LinkEventKind.ERROR and "GARBLED" in ev.message
    assert not emu.arm.moving
    assert link.move_path(np.array([Q_B])).kind == LinkEventKind.REACHED


def test_out_of_limit_or_unreachable_targets_are_never_sent(start, fast_robot):
    emu, link = start()
    before = len(emu.received)
    bad = np.radians([0.0, 0.0, 0.0, 95.0, 0.0])  # J5 beyond +-90
    with pytest.raises(LinkError, match="J5=95.0 deg outside"):
        link.move_path(np.array([HOME, bad]))
    with pytest.raises(LinkError, match="J5=95.0 deg outside"):
        link.move_joints_direct(bad)
    far = np.eye(4)
    far[:3, 3] = [2.0, 0.0, 0.5]
    with pytest.raises(LinkError, match="refused before sending"):
        link.move_to_pose(far)
    with pytest.raises(LinkError, match="speed_scale"):
        link.move_path(np.array([HOME]), speed_scale=2.0)
    assert len(emu.received) == before


def test_controller_refusal_carries_its_error_code(start, fast_robot):
    # The controller's J1 range is narrower than our model's (a mis-configured model): the
    # link sends, the controller refuses with its code.
    narrow = RV2AJ(RV2AJConfig(limits_deg=((-100, 100), (-60, 120), (-110, 120), (-90, 90),
                                           (-200, 200)), speeds_deg_s=FAST_SPEEDS,
                               tool=Tool.straight(0.1)))
    emu, link = start(robot=narrow)
    target = HOME.copy()
    target[0] = np.radians(120.0)
    errors: list = []
    link.subscribe(lambda e: errors.append(e) if e.kind == LinkEventKind.ERROR else None)
    ev = link.move_joints_direct(target)
    assert ev.kind == LinkEventKind.ERROR and errors == [ev]
    assert ev.details["error_code"] == f"{mp.ERR_JOINT_RANGE:04d}"
    assert "QeR2600" in ev.message and "joint range" in ev.message
    ev = link.move_path(np.array([HOME, target]))
    assert ev.kind == LinkEventKind.ERROR
    assert ev.details["error_code"] == f"{mp.ERR_JOINT_RANGE:04d}"
    assert abs(emu.arm.q[0]) <= np.radians(100.0) + 1e-9
    assert link.move_path(np.array([Q_A])).kind == LinkEventKind.REACHED


def test_operator_button_while_streaming_and_when_idle(start):
    emu, link = start()
    events: list = []
    link.subscribe(events.append)
    on_first_move(link, lambda: threading.Thread(
        target=link.indicate_collision, args=("gripper grazed the fixture",)).start())
    ev = link.move_path(np.vstack([sweep(HOME, Q_A, 3), sweep(Q_A, Q_B, 3)]), speed_scale=0.2)
    assert ev.kind == LinkEventKind.COLLISION_INDICATED
    assert ev.details["source"] == "operator" and "fixture" in ev.message
    assert not emu.arm.moving and np.allclose(ev.q, emu.arm.q, atol=TOL)
    link.indicate_collision()
    assert events[-1].kind == LinkEventKind.COLLISION_INDICATED
    assert np.allclose(events[-1].q, ev.q)
    assert link.move_path(np.array([HOME])).kind == LinkEventKind.REACHED


def test_a_stream_lost_by_its_status_poll_says_the_polls_reason(fast_robot):
    """The status poll runs in its own thread; when it loses the link it closes both sockets,
    and the stream's next read fails on a closed one ("file descriptor cannot be a negative
    integer", seen under load in `test_late_replies_past_the_timeout`). The operator is told
    the poll's reason, not the closed socket's."""

    class LostPoll:
        failure = LinkLost("MELFA link to 127.0.0.1:1 lost: no reply to 'DSTATE' within 0.30 s")
        closed = False

        def close(self) -> None:
            self.closed = True

    link = MelfaLink(fast_robot, port=1, datalink_port=2)
    poll = LostPoll()
    lost = link._data_link_failed(poll, ValueError("file descriptor cannot be a negative"))
    assert poll.closed and lost is LostPoll.failure
    poll.failure = None
    lost = link._data_link_failed(poll, OSError("reset by peer"))
    assert isinstance(lost, LinkLost) and "data link failed: reset by peer" in str(lost)
