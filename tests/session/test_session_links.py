"""The session on a real protocol peer: the MELFA controller emulator over localhost TCP.

A dropped connection mid-execution puts the session into the safe "link lost" state with the
plan and the world model kept; Reconnect + Resume finishes the mission.
"""

from __future__ import annotations

import numpy as np
import pytest

from assistant.emulators.melfa_emulator import MelfaEmulator
from assistant.links.settings import LinkSettings
from assistant.session import Session, SessionError
from assistant.session.events import RobotMoved
from assistant.session.report import all_obstacles, session_report
from workflow.machine import Mode


@pytest.mark.slow
def test_link_lost_mid_execution_then_reconnect_and_resume(tmp_path):
    s = Session.from_sample("thesis_rv2aj", tmp_path / "s")
    hidden = [o for o in all_obstacles(s) if o.name == "O3"]
    emu = MelfaEmulator(s.robot, hidden_obstacles=hidden, time_scale=8.0, tick_s=0.004,
                        start_q=s.current_joints()).start()
    try:
        s.set_link(LinkSettings(kind="melfa", port=emu.port, datalink_port=emu.datalink_port(),
                                stream_cycle_s=0.004, timeout_s=1.5, connect_timeout_s=1.0))
        s.goto("plan")
        s.plan()
        planned = s.trajectory
        assert planned is not None and s.world_ready
        # Pull the cable once the robot is really moving under the execution.
        armed = []

        def on_event(ev):
            if isinstance(ev, RobotMoved) and not armed:
                armed.append(True)
                emu.faults.drop_mid_move(after_moving_s=0.05)

        unsubscribe = s.bus.subscribe(on_event)
        with pytest.raises(SessionError, match="Resume"):
            s.execute()
        unsubscribe()
        assert armed
        assert s.machine.mode == Mode.ERROR and "link lost" in s.machine.error_message
        assert s.world_ready  # the world model survived
        held = s.current_joints()
        assert np.all(np.isfinite(held))
        emu.faults.clear()
        s.reconnect_link()
        assert s.machine.mode == Mode.IDLE
        summary = s.resume_execution().result()
        assert summary["ok"], summary
        rep = session_report(s, wall_time_s=0.0)
        assert rep["collision_free"] and rep["within_limits"]
    finally:
        s.close()
        emu.close()
