"""The UR link and emulator over real localhost sockets: UR's own client (ur-rtde's
RTDEReceiveInterface) reads the emulator unmodified; the thesis-like session (exploration,
one collision indication, re-plan, the exported program uploaded and run) through our link."""

from __future__ import annotations

import re
import struct

import numpy as np
import pytest
from link_fixtures import sweep
from ur_fixtures import (
    HOME,
    Q_A,
    Q_B,
    WIRE_TOL,
    Peer,
    box_on_wrist,
    connect_link,
    start_emulator,
    ur5,
)

from assistant.collision.checker import CollisionChecker
from assistant.emulators.ur_script_interp import ScriptError, compile_script
from assistant.links import ur_kinematics as uk
from assistant.links import ur_rtde_wire as w
from assistant.links import ur_script as us
from assistant.links.errors import ProtocolError
from assistant.links.link import LinkError, LinkEventKind
from assistant.links.settings import LinkSettings, LinkSettingsError, make_link
from assistant.links.ur import URLink
from assistant.links.ur_rtde_client import RtdeClient

__all__ = ["ur5"]  # the fixture, imported for pytest


def test_ur_rtde_receive_interface_reads_the_emulator(ur5, closing):
    emu = start_emulator(ur5, closing, rtde_port=30004)
    q = np.array([0.3, -1.2, 1.4, -1.8, -1.5, 0.7])
    emu.arm.set_q(q)
    peer = closing(Peer(emu.host, ["actual_q", "actual_TCP_pose", "robot_mode", "safety_mode",
                                   "safety_status_bits"]))
    got = peer.read()
    assert got["connected"] and got["robot_mode"] == w.RobotMode.RUNNING
    assert got["safety_mode"] == w.SafetyMode.NORMAL and not got["protective_stop"]
    assert np.allclose(got["q"], q, atol=1e-12)  # doubles on the wire: exact up to packing
    # The TCP, in the controller's base frame (the URDF's "base", turned 180 deg about z
    # against base_link), is the installation TCP on the controller's *calibrated* chain:
    # a few mm from our nominal model (the wire's doubles round at 1e-9 here).
    T = us.from_controller_pose(ur5, got["tcp"])
    cal = uk.calibrated_robot(emu.calibration, ur5)
    assert np.allclose(got["tcp"][:3], (cal.fk(q) @ ur5.T_flange_tool)[:3, 3], atol=1e-9)
    assert 0.001 < np.linalg.norm(T[:3, 3] - ur5.fk(q)[:3, 3]) < 0.01
    assert not np.allclose(np.array(got["tcp"][:2]), ur5.fk(q)[:2, 3], atol=0.01)
    emu.trigger_protective_stop("C153A1 protective stop: test")
    got = peer.read_until(lambda s: s["safety_mode"] != w.SafetyMode.NORMAL)
    assert got["safety_mode"] == w.SafetyMode.PROTECTIVE_STOP and got["protective_stop"]
    emu.press_emergency_stop()
    got = peer.read_until(lambda s: s["emergency_stop"])
    assert got["emergency_stop"] and got["robot_mode"] == w.RobotMode.POWER_OFF
    # ur-rtde's default recipe: every variable it knows for PolyScope 5.11, one package.
    full = closing(Peer(emu.host, None)).read()
    assert full["connected"] and np.allclose(full["q"], q, atol=1e-12)
    assert full["timestamp"] > 0.0 and full["status"] == 0  # powered off by the e-stop
    assert emu.rtde.received.count("S") == 2


def test_our_rtde_client_handshake_and_refusals(ur5, closing):
    emu = start_emulator(ur5, closing)
    c = RtdeClient(emu.host, emu.rtde_port, frequency_hz=500.0, timeout_s=1.0)
    closing(c)
    st = c.connect()
    assert c.controller_version == emu.version
    assert np.allclose(st.q, HOME, atol=1e-12) and st["runtime_state"] == w.RuntimeState.STOPPED
    bad = RtdeClient(emu.host, emu.rtde_port, variables=("actual_q", "actual_joy"))
    with pytest.raises(LinkError, match="actual_joy"):
        bad.connect()
    with pytest.raises(ValueError, match="500"):
        RtdeClient(emu.host, emu.rtde_port, frequency_hz=1000.0)
    reader = w.PackageReader()
    assert list(reader.feed(w.pack(w.Cmd.START, b"\x01")[:2])) == []
    assert list(reader.feed(w.pack(w.Cmd.START, b"\x01")[2:])) == [(w.Cmd.START, b"\x01")]
    with pytest.raises(ProtocolError, match="not an RTDE package"):
        list(reader.feed(struct.pack(">HB", 9, 200) + b"xxxxxx"))


def test_script_compiler_refuses_what_it_does_not_run():
    prog = compile_script("def a():\n  X = p[0.1, 0, 0.2, 0, 3.14, 0]  # pose\n"
                          "  movel(X, v=0.1)\n  movej([0, -1, 1, 0, 0, 0], a=1, v=2)\nend\na()\n")
    assert prog.name == "a" and [s.call for s in prog.body] == ["=", "movel", "movej"]
    for text, why in (("def a():\n  while True:\n  end\nend\n", "not supported"),
                      ("def a():\n  servoj([0,0,0,0,0,0], t=0.002)\nend\n", "servoj"),
                      ("def a():\n  movej(Q)\nend\n", "name_not_found:Q"),
                      ("def a():\n  movel(p[1, 2], v=1)\nend\n", "6 numbers"),
                      ("def a():\n  movej([0]*6, v=3)\nend\n", "not supported"),
                      ("def a():\n  movej(q=[0,0,0,0,0,0], speed=3)\nend\n", "'speed'"),
                      ("def a():\n  movej([0,0,0,0,0,0])\n", "no 'end'")):
        with pytest.raises(ScriptError, match=why):
            compile_script(text)


def test_thesis_like_session_explore_collide_replan_upload(ur5, closing):
    box = box_on_wrist(ur5, Q_A, Q_B, 0.5)
    emu = start_emulator(ur5, closing, hidden_obstacles=[box])
    link = connect_link(ur5, emu, closing)
    assert np.allclose(link.current_joints(), HOME, atol=1e-12)
    # Exploration: a dense out-and-back path is one program of three exact-stop movej.
    dense = np.vstack([sweep(HOME, Q_A, 80), sweep(Q_A, HOME, 80)[1:], sweep(HOME, Q_A, 80)[1:]])
    events: list = []
    link.subscribe(events.append)
    ev = link.move_path(dense, speed_scale=0.5)
    assert ev.kind == LinkEventKind.REACHED and ev.path_index == len(dense) - 1
    assert link.last_command_count == 3 and link.last_program.count("movej(") == 3
    assert any(e.kind == LinkEventKind.MOVED for e in events)
    assert np.allclose(emu.arm.q, Q_A, atol=WIRE_TOL)
    # The hidden box: the UR's protective stop is the collision indication.
    n_programs = len(emu.programs_run)
    ev = link.move_path(sweep(Q_A, Q_B, 5))
    assert ev.kind == LinkEventKind.COLLISION_INDICATED and ev.details["source"] == "controller"
    assert ev.details["safety_mode"] == "PROTECTIVE_STOP"
    assert len(emu.programs_run) == n_programs + 1
    assert np.allclose(ev.q, emu.arm.q, atol=1e-9)
    assert CollisionChecker(ur5, [box], self_collision=False).is_valid(emu.arm.q)
    assert Q_A[0] < ev.q[0] < 0.5 * (Q_A[0] + Q_B[0])
    # Re-planned: the link unlocks the protective stop (refused for a while, as on a UR),
    # backs off and goes on.
    ev = link.move_path(np.array([ev.q, HOME]))
    assert ev.kind == LinkEventKind.REACHED, ev.message
    said = [r.text for r in emu.received if r.channel == "dashboard"]
    assert said[0] == "is in remote control"  # connect asks first (an e-Series)
    assert said[1:] and set(said[1:]) == {"unlock protective stop"}
    assert emu.safety_mode == w.SafetyMode.NORMAL
    assert np.allclose(emu.arm.q, HOME, atol=WIRE_TOL)
    # The final program: the URScript exporter's own output, uploaded and run to its end.
    from assistant.export import get_dialect, program_from_trajectory
    from assistant.export.samples import thesis_trajectory

    traj = thesis_trajectory(ur5)
    files = get_dialect("urscript").write(program_from_trajectory(traj, ur5, name="thesis"), ur5)
    emu.arm.time_scale = 20.0  # the program's 50-100 mm/s lines: faster than life
    emu.time_scale = 20.0
    name = link.upload_program("thesis", {f.name: f.text.encode() for f in files})
    assert name.startswith("thesis_") and emu.programs_run[-1] == name
    assert emu.digital_outputs == {"set_tool_digital_out[0]": False}
    text = files[0].text
    kind, args = re.findall(r"^\s*(movel|movec|movej)\(([^)]*)\)", text, re.M)[-1]
    target = [a.strip() for a in args.split(",") if "=" not in a][-1]
    pose = re.search(rf"^\s*{target} = p\[(.*)\]", text, re.M)
    assert kind != "movej" and pose is not None
    T_goal = us.from_controller_pose(ur5, [float(v) for v in pose.group(1).split(",")])
    # The controller solves movel with its calibrated chain: that chain, not our nominal
    # model, puts the tool on the goal (1e-6: the file's 6 decimals).
    cal = uk.calibrated_robot(emu.calibration, ur5).with_tool(ur5.T_flange_tool)
    assert np.allclose(us.from_controller_pose(ur5, us.to_controller_pose(cal, cal.fk(
        emu.arm.q))), T_goal, atol=1e-6)
    assert link.calibration is not None and 0.001 < link.calibration.max_deviation_m < 0.01
    assert np.allclose(link.current_joints(), emu.arm.q, atol=1e-12)
    uploaded = [r.text for r in emu.received if r.channel == "script"][-1]
    assert f"def {name}():" in uploaded and "set_tcp(p[0.000000, 0.000000, 0.100000" in uploaded


def test_settings_build_the_ur_link(ur5, closing):
    emu = start_emulator(ur5, closing)
    data = {"kind": "ur", "host": emu.host, "ur_script_port": emu.script_port,
            "ur_rtde_port": emu.rtde_port, "ur_dashboard_port": emu.dashboard_port,
            "ur_primary_port": emu.primary_port,
            "ur_rtde_hz": 125.0, "timeout_s": 0.5}
    settings = LinkSettings.from_json(data)
    assert LinkSettings.from_json(settings.to_json()) == settings
    link = closing(make_link(settings, ur5))
    assert isinstance(link, URLink) and link.rtde.frequency_hz == 125.0
    link.connect()
    assert np.allclose(link.current_joints(), HOME, atol=1e-12)
    assert link.move_path(np.array([HOME, Q_A])).kind == LinkEventKind.REACHED
    with pytest.raises(LinkSettingsError, match="ur_rtde_hz"):
        LinkSettings(kind="ur", ur_rtde_hz=1000.0)
    with pytest.raises(LinkSettingsError, match="ur_rtde_port"):
        LinkSettings(kind="ur", ur_rtde_port=70000)


def test_wire_rotation_vectors_and_the_wrong_robot_model(ur5, closing, rng):
    from scipy.spatial.transform import Rotation

    for k in range(300):  # random rotations and ones within 1e-9..1e-2 rad of pi
        if k % 2:
            axis = rng.normal(size=3)
            axis /= np.linalg.norm(axis)
            R = Rotation.from_rotvec(axis * (np.pi - 10.0 ** rng.uniform(-9, -2))).as_matrix()
        else:
            R = Rotation.random(random_state=k).as_matrix()
        # Compared as matrices (near pi, v and -v are the same turn): within rounding.
        assert np.allclose(Rotation.from_rotvec(us.rotvec(R)).as_matrix(), R, atol=1e-12)
    # A link built for another arm: the reported TCP gives it away at connect.
    emu = start_emulator(ur5, closing)
    other = ur5.with_tool(np.array([[1, 0, 0, 0.0], [0, 1, 0, 0.05], [0, 0, 1, 0.1],
                                    [0, 0, 0, 1]]))
    link = closing(URLink(other, host=emu.host, script_port=emu.script_port,
                          rtde_port=emu.rtde_port, dashboard_port=emu.dashboard_port,
                          primary_port=emu.primary_port))
    with pytest.raises(LinkError, match="50.0 mm from where the controller"):
        link.connect()
    assert not link.connected
