"""The UR link's faults against the emulator: a pulled cable, a stream that goes silent past
the timeout, a protective stop and an emergency stop mid-move, refused targets and
programs, garbage on the stream, the operator's stop and Collision! buttons. Each ends in a
clear event or error within the timeout, never a hang, and the link recovers."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from ur_fixtures import HOME, Q_A, Q_B, WIRE_TOL, connect_link, start_emulator, ur5

from assistant.emulators.faults import GARBAGE
from assistant.links import ur_rtde_wire as w
from assistant.links.errors import ControllerRefused, ProtocolError
from assistant.links.link import LinkError, LinkEventKind, LinkLost

__all__ = ["ur5"]

#: A fault ends in a clear event within this (s), never a hang: the promise is "within the
#: timeout" (0.3-1 s here) plus the move's start and the link's teardown; ten times that
#: leaves room for a busy shared machine, and the message names which timeout fired.
NO_HANG_S = 10.0


def during_move(emu, action, *, past: float = 0.02):  # noqa: ANN001, ANN201
    """Run `action` on a thread once the arm has turned J1 by `past` rad from Q_A."""
    done = threading.Event()

    def watch():
        while not done.is_set() and emu.arm.q[0] < Q_A[0] + past:
            done.wait(0.002)
        if not done.is_set():
            action()

    th = threading.Thread(target=watch)
    th.start()
    return done, th


def run_with(link, emu, action, path=None, speed=0.1):  # noqa: ANN001, ANN201
    done, th = during_move(emu, action)
    try:
        return link.move_path(np.array([Q_A, Q_B]) if path is None else path, speed_scale=speed)
    finally:
        done.set()
        th.join(timeout=10.0)


@pytest.fixture
def ready(ur5, closing):
    def _start(link_kw=None, **kw):
        kw.setdefault("start_q", Q_A)
        emu = start_emulator(ur5, closing, **kw)
        return emu, connect_link(ur5, emu, closing, **(link_kw or {}))

    return _start


def test_drop_mid_move_then_reconnect_and_resume(ready):
    emu, link = ready()
    emu.faults.drop_mid_move(after_moving_s=0.05)
    t0 = time.monotonic()
    ev = link.move_path(np.array([Q_A, Q_B]), speed_scale=0.1)
    assert ev.kind == LinkEventKind.LINK_LOST and emu.faults.drops == 1
    assert time.monotonic() - t0 < NO_HANG_S and not link.connected
    assert np.allclose(link.current_joints(), ev.q)  # last known, nothing asked
    with pytest.raises(LinkError, match="not connected"):
        link.move_path(np.array([Q_B]))
    link.connect()
    q_now = link.current_joints()
    assert np.allclose(q_now, emu.arm.q, atol=1e-12) and Q_A[0] + 0.01 < q_now[0] < Q_B[0]
    assert link.move_path(np.array([q_now, Q_B])).kind == LinkEventKind.REACHED
    assert np.allclose(emu.arm.q, Q_B, atol=WIRE_TOL)


def test_stream_silent_past_the_timeout(ready):
    emu, link = ready(link_kw={"timeout_s": 0.3})
    emu.faults.delay_replies(1.0)
    t0 = time.monotonic()
    ev = link.move_path(np.array([Q_A, HOME]))
    # Silence is noticed by the stream's watchdog ("no data") or by the wait for the program's
    # state ("did not come within"), whichever fires first on a loaded machine: both say it.
    assert ev.kind == LinkEventKind.LINK_LOST
    assert "no data" in ev.message or "did not come within 0.30 s" in ev.message, ev.message
    assert time.monotonic() - t0 < NO_HANG_S and not link.connected
    # No wait for the stalled replies: each took its delay when it was made, so those still
    # sleeping go out on the lost connection's sockets; the new connection's are undelayed.
    emu.faults.clear()
    link.connect()
    assert link.move_path(np.array([HOME])).kind == LinkEventKind.REACHED
    assert np.allclose(emu.arm.q, HOME, atol=WIRE_TOL)


def test_protective_stop_mid_move_is_the_robots_collision_indication(ready):
    emu, link = ready()
    ev = run_with(link, emu, lambda: emu.trigger_protective_stop("C204A3 safety plane"))
    assert ev.kind == LinkEventKind.COLLISION_INDICATED and ev.details["source"] == "controller"
    assert ev.details["safety_mode"] == "PROTECTIVE_STOP" and ev.path_index == 1
    assert np.allclose(ev.q, emu.arm.q, atol=1e-12) and Q_A[0] < ev.q[0] < Q_B[0]
    assert link.robot_state()["safety_mode"] == "PROTECTIVE_STOP"
    # The next move unlocks it (the UR refuses during unlock_delay_s, the link retries).
    assert link.move_path(np.array([HOME])).kind == LinkEventKind.REACHED
    assert [r.text for r in emu.received if r.channel == "dashboard"].count(
        "unlock protective stop") >= 1
    # A robot that keeps refusing the unlock: a clear refusal, not a hang.
    emu.unlock_delay_s = 60.0
    emu.trigger_protective_stop()
    link.rtde.wait_for(lambda st: st["safety_mode"] == w.SafetyMode.PROTECTIVE_STOP)
    link.unlock_wait_s = 0.3
    with pytest.raises(ControllerRefused, match="could not be unlocked"):
        link.move_path(np.array([Q_A]))


def test_emergency_stop_mid_move_is_a_lost_link_until_released(ready):
    emu, link = ready()
    ev = run_with(link, emu, emu.press_emergency_stop)
    assert ev.kind == LinkEventKind.LINK_LOST and "emergency stop" in ev.message
    assert not link.connected and not emu.arm.moving
    with pytest.raises(LinkLost, match="emergency stop is pressed"):
        link.connect()
    emu.release_emergency_stop()
    link.connect()  # powers on and releases the brakes through the dashboard
    said = [r.text for r in emu.received if r.channel == "dashboard"]
    assert said[-2:] == ["power on", "brake release"]
    assert emu.robot_mode == w.RobotMode.RUNNING
    assert link.move_path(np.array([HOME])).kind == LinkEventKind.REACHED


def test_refused_targets_before_sending_and_by_the_robot(ready, ur5):
    narrow = ur5.with_limits(np.column_stack([ur5.limits.lower, ur5.limits.upper])
                             * np.array([[1.0, 1.0]] * 5 + [[0.1, 0.1]]))
    emu, link = ready()
    n = len(emu.received)
    bad = Q_A.copy()
    bad[2] = 3.5  # the elbow's limit is +-pi
    with pytest.raises(LinkError, match="outside the joint limits"):
        link.move_path(np.array([Q_A, bad]))
    far = np.eye(4)
    far[:3, 3] = [2.0, 0.0, 0.3]
    with pytest.raises(LinkError, match="refused before sending"):
        link.move_linear(far)
    assert len(emu.received) == n  # nothing went out
    # Within our model's limits, outside the robot's (a narrower safety configuration).
    emu.robot = emu.base_robot = narrow
    target = Q_A.copy()
    target[5] = 1.0  # wrist 3 limited to +-0.63 rad on this robot
    ev = link.move_path(np.array([Q_A, target]))
    assert ev.kind == LinkEventKind.ERROR and "outside the joint limits" in ev.message
    assert "wrist_3_joint" in ev.details["controller_message"]
    assert np.allclose(emu.arm.q, Q_A, atol=WIRE_TOL)
    # A program the robot cannot run: the controller's compile error, nothing moves.
    with pytest.raises(ControllerRefused, match="not supported by this emulator") as info:
        link.upload_program("loop", {"loop.script": b"def loop():\n  while True:\n"
                                                    b"    sleep(1)\n  end\nend\n"})
    assert "(line 2 of loop.script)" in str(info.value) and "script line 3" in info.value.raw
    assert np.allclose(emu.arm.q, Q_A, atol=WIRE_TOL)
    with pytest.raises(LinkError, match="exactly one .script"):
        link.upload_program("x", {"a.src": b"DEF a()\nEND\n"})
    emu.robot = emu.base_robot = ur5
    assert link.move_path(np.array([HOME])).kind == LinkEventKind.REACHED


def test_garbage_on_the_stream_is_quoted_and_the_stream_reopened(ready):
    emu, link = ready()
    emu.faults.garble_next(1)  # the next package is garbage; the stream is broken
    deadline = time.monotonic() + 30.0  # until the link has read it (late on a busy machine)
    while True:
        try:
            link.current_joints()
        except ProtocolError as exc:
            refused = exc
            break
        assert time.monotonic() < deadline, "the garbled package never reached the link"
        time.sleep(0.005)
    assert "GARBLED" in str(refused) and GARBAGE[:10] in refused.raw
    assert link.connected and np.allclose(link.current_joints(), Q_A, atol=1e-12)
    ev = run_with(link, emu, lambda: emu.faults.garble_next(1))
    assert ev.kind == LinkEventKind.ERROR and "GARBLED" in ev.message
    # The link stopped the robot it could not follow: the arm stands short of Q_B (left to
    # itself it would arrive there, so a generous deadline cannot hide a missing stop).
    deadline = time.monotonic() + 30.0
    while emu.arm.moving and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not emu.arm.moving and emu.arm.q[0] < Q_B[0] - 0.05
    assert link.move_path(np.array([HOME])).kind == LinkEventKind.REACHED
    assert np.allclose(emu.arm.q, HOME, atol=WIRE_TOL)


def test_stop_and_the_operator_button_during_a_move(ready):
    emu, link = ready()
    ev = run_with(link, emu, link.stop)
    assert ev.kind == LinkEventKind.STOPPED and ev.path_index == 1
    assert not emu.arm.moving and np.allclose(ev.q, emu.arm.q, atol=1e-12)
    assert [r.text for r in emu.received if r.channel == "script"][-1].startswith("stopj(")
    assert link.move_path(np.array([Q_A])).kind == LinkEventKind.REACHED
    ev = run_with(link, emu, lambda: link.indicate_collision("operator: cable snagged"))
    assert ev.kind == LinkEventKind.COLLISION_INDICATED and ev.details["source"] == "operator"
    assert "cable" in ev.message and Q_A[0] < ev.q[0] < Q_B[0]
    assert emu.safety_mode == w.SafetyMode.NORMAL  # our stop is no protective stop


def test_a_silent_or_garbled_controller_at_connect_never_hangs(ur5, closing):
    """Ours: LinkLost / ProtocolError within the timeout. ur-rtde's receive interface (why
    the link does not use it): still waiting on the silent peer when it is killed."""
    import random
    import socket
    import subprocess
    import sys

    from assistant.links.ur_rtde_client import RtdeClient

    host = f"127.{random.randint(1, 250)}.{random.randint(1, 250)}.{random.randint(2, 250)}"
    srv = socket.create_server((host, 30004))
    closing(srv)
    accepted: list = []

    def serve(answer: bytes) -> None:
        c, _ = srv.accept()
        accepted.append(c)
        c.recv(64)
        c.sendall(answer)

    for answer, error, match in ((b"", LinkLost, "did not answer the RTDE handshake"),
                                 (GARBAGE.encode(), ProtocolError, "GARBLED")):
        th = threading.Thread(target=serve, args=(answer,))
        th.start()
        t0 = time.monotonic()
        with pytest.raises(error, match=match):
            RtdeClient(host, 30004, timeout_s=0.5).connect()
        assert time.monotonic() - t0 < NO_HANG_S  # ended: ur-rtde, below, never ends
        th.join(timeout=5.0)
    threading.Thread(target=serve, args=(b"",), daemon=True).start()
    peer = subprocess.Popen([sys.executable, "-c", "import rtde_receive, sys\n"
                             f"rtde_receive.RTDEReceiveInterface({host!r})\nprint('connected')"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        with pytest.raises(subprocess.TimeoutExpired):
            peer.communicate(timeout=3.0)
    finally:
        peer.kill()
        peer.communicate(timeout=5.0)
        for c in accepted:
            c.close()


def test_a_slowed_arm_is_followed_and_a_standing_one_is_lost(ready):
    """The speed slider at 5 % stretches a move twenty-fold past its planned time: the link
    follows it to the end (a moving arm is never timed out). An arm that stands while its
    program still plays is lost once it has stood `timeout_s`."""
    emu, link = ready(link_kw={"timeout_s": 0.3}, time_scale=0.05)
    ev = link.move_path(np.array([Q_A, Q_B]))
    assert ev.kind == LinkEventKind.REACHED, ev.message
    assert np.allclose(emu.arm.q, Q_B, atol=WIRE_TOL)

    def freeze_once_moving() -> None:  # a drive that stalls mid-move; the program plays on
        end = time.monotonic() + 30.0
        while np.max(np.abs(emu.arm.q - Q_B)) < 0.01 and time.monotonic() < end:
            time.sleep(0.002)
        emu.arm.time_scale = 0.0

    th = threading.Thread(target=freeze_once_moving)
    th.start()
    try:
        ev = link.move_path(np.array([Q_B, Q_A]))
    finally:
        th.join(timeout=30.0)
    assert ev.kind == LinkEventKind.LINK_LOST and "stood still" in ev.message, ev.message
