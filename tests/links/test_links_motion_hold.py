"""The enabling switch on real protocol peers: when the page that holds motion authority goes,
the session stops the arm through the link's own stop, and the emulated controller's arm
stands within 300 ms; nobody else starts it (Collision! and Stop never do), and the next
holder can.

The page side (a closed browser tab is the holder leaving) is tested in
tests/web/test_web_hold_to_run.py; here the holder leaves by `MotionHold.left`, the same call
the page makes, so the figure is the link's and the controller's, not the browser's.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from ur_fixtures import HOME, UR5_URDF, start_emulator

from assistant.emulators.melfa_emulator import MelfaEmulator
from assistant.links.settings import LinkSettings
from assistant.robots.catalog import RobotSpec, installed_robot_urdf
from assistant.session import Session
from assistant.session.motion_hold import MotionRefused
from workflow.machine import Mode

#: The arm must stand this soon after its holder goes (the issue's enabling-switch figure):
#: a product promise, kept - measured 0-4 ms at load 1.5 (the stop is sent inside `left`).
STOP_S = 0.3
#: A joint that changes by less than this between two reads stands (rad): the emulators
#: step whole ticks of motion, far above it; rounding on the wire is ~1e-7 rad.
STILL_RAD = 1e-5
HOLDER, OTHER = 1, 2


def _moving(emu, q0: np.ndarray, deadline_s: float = 30.0) -> None:  # noqa: ANN001
    end = time.monotonic() + deadline_s
    while np.max(np.abs(emu.arm.q - q0)) < 0.02:
        assert time.monotonic() < end, "the arm never started"
        time.sleep(0.005)


def _last_change_after(emu, t0: float, watch_s: float = 1.5) -> float:  # noqa: ANN001
    """Seconds from t0 to the last read at which the emulated arm still moved."""
    last, q = t0, emu.arm.q.copy()
    end = t0 + watch_s
    while time.monotonic() < end:
        time.sleep(0.002)
        now, q_now = time.monotonic(), emu.arm.q.copy()
        if np.max(np.abs(q_now - q)) > STILL_RAD:
            last = now
        q = q_now
    return last - t0


def _hold_and_let_go(s: Session, emu, q_far: np.ndarray) -> None:  # noqa: ANN001
    s.hold.enforce()
    assert s.hold.joined(HOLDER) and not s.hold.joined(OTHER)
    q0 = emu.arm.q.copy()
    with s.hold.acting(OTHER), pytest.raises(MotionRefused, match="motion authority"):
        s.jog_joints(q_far, wait=False)  # not the holder: nothing starts
    assert np.max(np.abs(emu.arm.q - q0)) < STILL_RAD
    with s.hold.acting(HOLDER):
        fut = s.jog_joints(q_far, wait=False)
    _moving(emu, q0)
    t0 = time.monotonic()
    s.hold.left(HOLDER)  # the holder's page closed
    stood_after = _last_change_after(emu, t0)
    print(f"arm stood {stood_after * 1000:.0f} ms after its holder went")
    assert stood_after <= STOP_S, f"the arm moved on {stood_after * 1000:.0f} ms"
    fut.exception(timeout=30)  # the jog ended (cancelled or stopped), it did not go on
    end = time.monotonic() + 30
    while s.machine.mode == Mode.MOVING:
        assert time.monotonic() < end
        time.sleep(0.01)
    here = emu.arm.q.copy()
    assert np.max(np.abs(here - q_far)) > 0.05  # it stopped short of the target
    # Collision! and Stop from a page without authority record and stop - never start.
    with s.hold.acting(OTHER):
        s.fire("collision")
        s.fire("stop")
    assert _last_change_after(emu, time.monotonic(), watch_s=1.0) == 0.0
    assert np.max(np.abs(emu.arm.q - here)) < STILL_RAD
    with s.hold.acting(OTHER), pytest.raises(MotionRefused):
        s.jog_joints(q_far, wait=False)  # nobody holds it: nothing starts either
    # The next holder takes it and moves the arm on.
    assert s.hold.take(OTHER)
    with s.hold.acting(OTHER):
        s.jog_joints(q_far, wait=True)
    assert np.max(np.abs(emu.arm.q - q_far)) < 1e-3


def test_the_ur_arm_stops_when_its_holder_goes(closing, tmp_path):
    urdf, share = installed_robot_urdf(UR5_URDF)
    s = closing(Session(folder=tmp_path / "s"))
    s.choose_robot(RobotSpec(kind="urdf", urdf_path=str(urdf), package_dirs=(str(share),),
                             tool_link="tool0"))
    emu = start_emulator(s.robot, closing, time_scale=0.25)  # a slow, long move
    s.set_link(LinkSettings(kind="ur", host=emu.host, ur_script_port=emu.script_port,
                            ur_rtde_port=emu.rtde_port, ur_dashboard_port=emu.dashboard_port,
                            ur_primary_port=emu.primary_port))
    q_far = HOME + np.array([1.2, 0.0, 0.0, 0.0, 0.0, 0.0])
    _hold_and_let_go(s, emu, q_far)


def test_the_melfa_arm_stops_when_its_holder_goes(closing, tmp_path):
    s = closing(Session.from_sample("thesis_rv2aj", tmp_path / "s"))
    q_start = s.current_joints()
    emu = closing(MelfaEmulator(s.robot, time_scale=0.5, tick_s=0.004,
                                start_q=q_start).start())
    s.set_link(LinkSettings(kind="melfa", port=emu.port, datalink_port=emu.datalink_port(),
                            stream_cycle_s=0.004, timeout_s=1.5, connect_timeout_s=1.0))
    q_far = q_start + np.array([1.0, 0.0, 0.0, 0.0, 0.0])
    _hold_and_let_go(s, emu, q_far)
