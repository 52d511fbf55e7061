"""abb-robot-client's own RWS class against our IRC5 emulator, unmodified: if ABB's protocol
as that library speaks it works here, our emulator (and so our link's tests) speak RWS 1.0,
not a private dialect. Calls the library has no method for (mastership, loadmod) go through
its own request path (`_do_post`: its digest session, its error parsing)."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request

import numpy as np
import pytest
from abb_fixtures import HOME, Q_A, TIME_SCALE, ur5
from abb_robot_client import rws  # the vendor's client: a test extra, never skipped

from assistant.emulators.abb_rws_emulator import AbbRwsEmulator
from assistant.links import abb_rws_protocol as rp
from assistant.robots.framed import controller_view


@pytest.fixture(scope="module")
def robot():
    return ur5()


@pytest.fixture
def emu(robot, closing):
    return closing(AbbRwsEmulator(robot, start_q=HOME, time_scale=TIME_SCALE).start())


@pytest.fixture
def client(emu, closing):
    return closing(rws.RWS(emu.base_url))


def wait_stopped(c, timeout_s: float = 60.0) -> None:  # tens of seconds: a busy machine
    deadline = time.monotonic() + timeout_s
    while c.get_execution_state().ctrlexecstate == "running":
        assert time.monotonic() < deadline, "program did not stop"
        time.sleep(0.01)


def test_connect_and_read_state(emu, client, robot):
    assert client.get_controller_state() == "motoron"
    assert client.get_operation_mode() == "AUTO"
    ex = client.get_execution_state()
    assert (ex.ctrlexecstate, ex.cycle) == ("stopped", "once")
    tasks = client.get_tasks()
    assert tasks["T_ROB1"].motiontask and tasks["T_ROB1"].active
    jt = client.get_jointtarget()
    # 6 decimals of a degree on the wire
    assert np.allclose(np.radians(jt.robax), HOME, atol=1e-7) and np.all(jt.extax == 9e9)
    rt = client.get_robtarget()
    T = controller_view(robot).fk(HOME)  # counted from the UR5 controller's base frame
    assert np.allclose(rt.trans, T[:3, 3] * 1000.0, atol=1e-3)
    assert np.allclose(rp.pose_from(rt.trans, rt.rot), T, atol=1e-6)
    assert list(rt.robconf[:3]) == [0, -1, 0]  # quadrants of axes 1, 4 (-90 deg), 6
    assert client.get_speedratio() == 100.0


def test_login_is_http_digest_and_wrong_passwords_are_refused(emu):
    with pytest.raises(urllib.error.HTTPError) as info:
        urllib.request.urlopen(f"{emu.base_url}/rw/panel/ctrlstate?json=1", timeout=2.0)
    assert info.value.code == 401
    assert info.value.headers["WWW-Authenticate"].startswith('Digest realm="validusers@')
    with pytest.raises(Exception, match="HTTP error 401"):
        rws.RWS(emu.base_url, "Default User", "wrong").get_controller_state()
    with pytest.raises(Exception, match="HTTP error 401"):
        rws.RWS(emu.base_url, "Intruder", "robotics").get_controller_state()
    assert rws.RWS(emu.base_url).get_controller_state() == "motoron"  # the IRC5 default user


def test_single_mastership(emu, client, closing):
    other = closing(rws.RWS(emu.base_url))
    client._do_post("rw/mastership?action=request")
    with pytest.raises(rws.ABBException) as info:
        other._do_post("rw/mastership?action=request")
    assert info.value.code == rp.RC_HELD_BY_OTHER and "held by another" in str(info.value)
    other.upload_file("$HOME/m.mod", b"MODULE m\nPROC go()\nENDPROC\nENDMODULE\n")
    with pytest.raises(rws.ABBException, match="held by another"):
        other._do_post("rw/rapid/tasks/T_ROB1?action=loadmod",
                       {"modulepath": "$HOME/m.mod", "replace": "true"})
    with pytest.raises(rws.ABBException, match="held by another"):
        other.resetpp()
    client._do_post("rw/mastership?action=release")
    with pytest.raises(rws.ABBException, match="request mastership first"):
        other._do_post("rw/rapid/tasks/T_ROB1?action=loadmod",
                       {"modulepath": "$HOME/m.mod", "replace": "true"})
    other._do_post("rw/mastership?action=request")
    other._do_post("rw/rapid/tasks/T_ROB1?action=loadmod",
                   {"modulepath": "$HOME/m.mod", "replace": "true"})
    other.logout()  # a session that ends gives mastership back
    client._do_post("rw/mastership?action=request")


def test_upload_load_start_stop_and_the_event_log(emu, client):
    module = rp.joint_move_module(np.array([Q_A, HOME]), 50.0)  # 5 % speed: slow enough
    client.upload_file("$HOME/CellMove.mod", module.encode())
    assert "CellMove.mod" in client.list_files("$HOME")
    assert client.read_file("$HOME/CellMove.mod") == module.encode()
    client._do_post("rw/mastership?action=request")
    client._do_post("rw/rapid/tasks/T_ROB1?action=loadmod",
                    {"modulepath": "$HOME/CellMove.mod", "replace": "true"})
    client._do_post("rw/mastership?action=release")
    assert client.get_rapid_variable("cj1", "T_ROB1/CellMove").startswith("[[-40.000000,")
    # The task has its own main (MainModule): PP to our routine, as RWS documents it.
    client._do_post("rw/rapid/tasks/T_ROB1/pcp?action=set-pp-routine",
                    {"module": "CellMove", "routine": "cellmove", "userlevel": "false"})
    client.start(cycle="once")
    assert client.get_execution_state().ctrlexecstate == "running"
    deadline = time.monotonic() + 30.0  # a wait, never a hang
    while emu.arm.q[0] > Q_A[0] / 2:  # under way to Q_A
        assert time.monotonic() < deadline, "the arm never got under way"
        time.sleep(0.005)
    client.stop()
    assert client.get_execution_state().ctrlexecstate == "stopped"
    q_stop = np.radians(client.get_jointtarget().robax)
    assert Q_A[0] < q_stop[0] < 0.0 and not emu.arm.moving
    client.start(cycle="once")  # continues from the interrupted instruction
    wait_stopped(client)
    assert np.allclose(np.radians(client.get_jointtarget().robax), HOME, atol=1e-6)
    titles = [(e.code, e.title) for e in client.read_event_log()]
    assert titles[0][0] == rp.ELOG_PROGRAM_STOPPED  # newest first, as the controller lists
    assert all(e.msgtype != rp.ELOG_ERROR for e in client.read_event_log())
    assert emu.rapid.runs == ["CellMove", "CellMove"]
    client.delete_file("$HOME/CellMove.mod")
    with pytest.raises(Exception, match="File not found"):
        client.read_file("$HOME/CellMove.mod")


def test_what_it_does_not_understand_is_refused(emu, client):
    with pytest.raises(rws.ABBException) as info:
        client._do_get("rw/motionsystem/mechunits/ROB_9/jointtarget")
    assert info.value.code == rp.RC_NOT_FOUND
    with pytest.raises(rws.ABBException, match="no action 'fly'"):
        client._do_post("rw/rapid/execution?action=fly", {})
    with pytest.raises(rws.ABBException, match="cycle 'sometimes'"):
        client.start(cycle="sometimes")
    with pytest.raises(rws.ABBException, match="program pointer lost"):
        client.start(cycle="once")  # nothing loaded, pointer never set
    client._do_post("rw/mastership?action=request")
    client.upload_file("$HOME/bad.mod", b"MODULE bad\nPROC go()\n  TPWrite \"hi\";\n"
                                        b"ENDPROC\nENDMODULE\n")
    client._do_post("rw/rapid/tasks/T_ROB1?action=loadmod", {"modulepath": "$HOME/bad.mod"})
    with pytest.raises(rws.ABBException, match="cannot execute 'TPWrite") as info:
        client._do_post("rw/rapid/tasks/T_ROB1/pcp?action=set-pp-routine",
                        {"module": "bad", "routine": "go"})
    assert info.value.code == rp.RC_LOAD_ERROR
    client._do_post("rw/rapid/tasks/T_ROB1?action=unloadmod", {"module": "bad"})
    # The shipped task holds a main of its own: a second one cannot be loaded.
    assert [m.name for m, _ in emu.rapid.modules.values()] == ["MainModule"]
    client.upload_file("$HOME/two.mod", b"MODULE two\nPROC main()\nENDPROC\nENDMODULE\n")
    with pytest.raises(rws.ABBException, match="ambiguous PROC MAIN"):  # one main per task
        client._do_post("rw/rapid/tasks/T_ROB1?action=loadmod", {"modulepath": "$HOME/two.mod"})
    client.upload_file("$HOME/worse.mod", b"MODULE worse\n  garbage here\nENDMODULE\n")
    with pytest.raises(rws.ABBException, match="line 2: cannot load"):
        client._do_post("rw/rapid/tasks/T_ROB1?action=loadmod",
                        {"modulepath": "$HOME/worse.mod"})
    # The XHTML flavour of RWS is not spoken here: refused, not half-answered.
    c = rws.RWS(emu.base_url)
    res = c._session.get(f"{emu.base_url}/rw/panel/ctrlstate", auth=c.auth)
    assert res.status_code == 400 and "JSON only" in res.text


def test_the_emulator_runs_as_a_script():
    """The demo command: started, answering abb-robot-client, stopped cleanly by SIGTERM."""
    proc = subprocess.Popen([sys.executable, "-m", "assistant.emulators.abb_rws_emulator",
                             "--port", "0", "--time-scale", "5"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        ports = [int(p) for p in re.findall(r":(\d+)", line)]
        assert ports, f"no port in {line!r}; stderr: {proc.stderr.read() if proc.poll() else ''}"
        c = rws.RWS(f"http://127.0.0.1:{ports[0]}")
        assert c.get_controller_state() == "motoron"
        assert np.allclose(c.get_jointtarget().robax, 0.0)
        c.close()
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=5.0)
        proc.stdout.close()
        proc.stderr.close()
    assert proc.returncode == 0


def test_abb_robot_clients_subscription_hears_the_execution_state(emu, client):
    """abb-robot-client's own websocket subscription (robapi2_subscription) on our emulator:
    the execution state arrives as events, the way our link follows a program."""
    import threading

    heard: list = []
    got = threading.Event()

    def handler(ev):  # noqa: ANN001
        heard.append(ev)
        if isinstance(ev, rws.RAPIDExecutionState) and ev.ctrlexecstate == "stopped":
            got.set()

    sub = client.subscribe([rws.SubscriptionResourceRequest(
        rws.SubscriptionResourceType.ExecutionState, rws.SubscriptionResourcePriority.Medium)],
        handler)
    try:
        deadline = time.monotonic() + 20.0
        while not emu.events._subs or not any(s.sockets for s in emu.events._subs.values()):
            assert time.monotonic() < deadline, f"the websocket never opened: {heard}"
            time.sleep(0.02)
        client._do_post("rw/rapid/tasks/T_ROB1/pcp?action=set-pp-routine",
                        {"module": "MainModule", "routine": "main"})
        client.start(cycle="once")  # the cell's own main: WaitTime 0.1
        assert got.wait(20.0), heard
        states = [e.ctrlexecstate for e in heard if isinstance(e, rws.RAPIDExecutionState)]
        assert states[-2:] == ["running", "stopped"]
    finally:
        sub.close()
