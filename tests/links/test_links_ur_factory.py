"""The UR as it ships and as its documents describe it: an e-Series in Local control, a CB3
at 125 Hz, the primary interface's packages (unknown ones skipped by length, errors quoted),
ur-rtde's DashboardClient against the emulator, and what ur-rtde's RTDEControlInterface does
with it (it needs its own control script running on the controller: not emulated)."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from ur_fixtures import HOME, Q_A, connect_link, start_emulator, ur5

from assistant.emulators.ur_emulator import NOT_REMOTE
from assistant.links import ur_primary as up
from assistant.links.errors import ControllerRefused, ProtocolError
from assistant.links.link import LinkEventKind
from assistant.links.settings import LinkSettings, make_link
from assistant.links.ur import LOCAL_MODE
from assistant.links.ur_channels import dashboard

__all__ = ["ur5"]

DASH = textwrap.dedent("""
    import json, sys
    import dashboard_client
    d = dashboard_client.DashboardClient(sys.argv[1], int(sys.argv[2]))
    d.connect()
    out = {"connected": d.isConnected(), "remote": d.isInRemoteControl(),
           "version": d.polyscopeVersion(), "serial": d.getSerialNumber(),
           "mode": d.robotmode(), "safety": d.safetystatus()}
    d.send("power on\\n")
    out["power_on"] = d.receive()
    d.disconnect()
    print(json.dumps(out))
""")


def ur_rtde_dashboard(emu) -> dict:  # noqa: ANN001
    """ur-rtde's DashboardClient in a child process (its blocking reads hold the GIL)."""
    out = subprocess.run([sys.executable, "-c", DASH, emu.host, str(emu.dashboard_port)],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_shipped_e_series_is_in_local_control_and_the_link_says_what_to_switch(ur5, closing):
    emu = start_emulator(ur5, closing, local_mode=None)  # None: the controller's own default
    assert not emu.remote_control
    with pytest.raises(ControllerRefused) as info:
        connect_link(ur5, emu, closing)
    assert str(info.value) == LOCAL_MODE and "Remote Control" in LOCAL_MODE
    assert "Settings > System > Remote Control" in LOCAL_MODE
    # What the controller does in Local: client interfaces dropped, power on refused.
    assert dashboard(emu.host, emu.dashboard_port, "power on", 2.0) == NOT_REMOTE
    import socket
    with socket.create_connection((emu.host, emu.primary_port), 2.0) as s:
        s.settimeout(5.0)
        assert s.recv(100) == b""  # closed at once
    # ur-rtde's own dashboard client reads the same server.
    got = ur_rtde_dashboard(emu)
    assert got["connected"] and got["remote"] is False and got["version"] == "5.11.1.108318"
    assert got["serial"] == emu.serial and got["mode"] == "Robotmode: RUNNING"
    assert got["safety"] == "Safetystatus: NORMAL" and got["power_on"] == NOT_REMOTE
    emu.set_remote_control(True)  # the operator's toggle on the pendant
    assert ur_rtde_dashboard(emu)["remote"] is True
    link = connect_link(ur5, emu, closing)
    assert link.remote_control is True and link.robot_state()["control"] == "remote"
    assert link.move_path(np.array([HOME, Q_A])).kind == LinkEventKind.REACHED
    # Back to Local mid-session: the client interfaces drop, the next move is lost.
    emu.set_remote_control(False)
    ev = link.move_path(np.array([Q_A, HOME]))
    assert ev.kind in (LinkEventKind.LINK_LOST, LinkEventKind.ERROR), ev.message


def test_a_cb3_streams_at_125_hz_and_has_no_local_mode(ur5, closing):
    emu = start_emulator(ur5, closing, version=(3, 15, 7, 106331), local_mode=None)
    link = connect_link(ur5, emu, closing, rtde_hz=500.0)
    assert link.rtde.requested_hz == 500.0 and link.rtde.frequency_hz == 125.0
    assert link.remote_control is None  # not asked: a CB3 has no such mode
    said = [r.text for r in emu.received if r.channel == "dashboard"]
    assert "is in remote control" not in said
    assert link.move_path(np.array([HOME, Q_A])).kind == LinkEventKind.REACHED


def test_primary_packages_unknown_types_skipped_by_length_errors_quoted():
    cal = up.KinematicsInfo((1,) * 6, (0.001,) * 6, (0.0, -0.425, -0.392, 0, 0, 0),
                            (0.089, 0, 0, 0.109, 0.094, 0.082), (1.57, 0, 0, 1.57, -1.57, 0), 1)
    mode = up.RobotModeData(True, False, False, True, 7)
    stream = b"".join([
        up.unknown_package(22, b"\x07" * 33),  # HMC message: not ours
        up.robot_state(up.unknown_package(77, b"\x00" * 9), up.kinematics_sub(cal),
                       up.robot_mode_sub(mode)),
        up.error_code_message(204, 3, 3, "Safety plane violation"),
        up.popup_message("Error", "Gripper not found", error=True),
        up._msg(42, b"a message type of a future version"),
        up.runtime_exception("Compile error: name 'foo' is not defined", 3, 5),
    ])
    reader = up.PrimaryReader()
    got = []
    for k in range(0, len(stream), 7):  # arrives in pieces
        got += list(reader.feed(stream[k:k + 7]))
    assert got[0] == cal and got[1] == mode
    msgs = got[2:]
    assert [m.kind for m in msgs] == [up.MSG_ERROR_CODE, up.MSG_POPUP, up.MSG_RUNTIME_EXCEPTION]
    assert msgs[0].describe() == "C204A3: Safety plane violation" and msgs[0].is_error
    assert msgs[1].title == "Error" and msgs[1].is_error
    assert msgs[2].describe().endswith("(script line 3, column 5)")
    assert reader.skipped == {22: 1}
    with pytest.raises(ProtocolError, match="not a primary-interface package"):
        list(up.PrimaryReader().feed(struct.pack(">iB", 2, 16) + b"garbage"))


def test_a_refused_program_quotes_the_controller_and_the_wire_log_has_it(ur5, closing,
                                                                          tmp_path):
    emu = start_emulator(ur5, closing)
    s = LinkSettings(kind="ur", host=emu.host, ur_script_port=emu.script_port,
                     ur_rtde_port=emu.rtde_port, ur_dashboard_port=emu.dashboard_port,
                     ur_primary_port=emu.primary_port, rws_password="s3cret-pw")
    link = closing(make_link(s, ur5, log_dir=tmp_path))
    link.connect()
    with pytest.raises(ControllerRefused) as info:
        link.upload_program("bad", {"bad.script": b"def bad():\n  servoj([0,0,0,0,0,0])\n"
                                                  b"end\n"})
    assert "servoj" in str(info.value) and "(line 2 of bad.script)" in str(info.value)
    log = (tmp_path / "wire.log").read_text()
    assert "servoj" in log and "dashboard:" in log and "is in remote control" in log
    assert "s3cret-pw" not in log
    assert link.calibration is not None and link.kinematics == emu.calibration


RTDE_CONTROL = textwrap.dedent("""
    import rtde_control, sys
    try:
        rtde_control.RTDEControlInterface(sys.argv[1])
        print("constructed")
    except Exception as exc:
        print(f"failed: {exc}")
""")


def test_what_ur_rtdes_control_interface_gets_from_the_emulator(ur5, closing):
    """ur-rtde's RTDEControlInterface asks the dashboard (PolyscopeVersion, serial number,
    remote control), sets up its output recipe and 23 input recipes, and uploads its ~40 kB
    control script to 30003. The emulator answers all of that as a controller does but takes
    no RTDE inputs and cannot run that script (threads, register commands), so the constructor
    fails after its own 5 s wait: our link drives the emulator with plain programs instead."""
    emu = start_emulator(ur5, closing, rtde_port=30004, dashboard_port=29999,
                         realtime_port=30003)
    out = subprocess.run([sys.executable, "-c", RTDE_CONTROL, emu.host], capture_output=True,
                         text=True, timeout=60)
    assert "Failed to start control script" in out.stdout, out.stdout + out.stderr[-1000:]
    said = [r.text for r in emu.received if r.channel == "dashboard"]
    assert {"PolyscopeVersion", "get serial number", "is in remote control"} <= set(said)
    assert "S" in emu.rtde.received and "I" in emu.rtde.received
    script = [r.text for r in emu.received if r.channel == "script"]
    assert script and script[-1].startswith("def rtde_control():")
    assert emu.messages and "syntax_error" in emu.messages[-1], emu.messages  # on 30001
