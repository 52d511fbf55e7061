"""ABB as it ships: an IRC5 task that holds its own main runs our program beside it, the link
follows programs over an RWS subscription instead of polling, and an OmniCore speaks RWS 2.0
(HTTPS with its self-signed certificate, Basic login, hal+json v2, actions in the path)."""

from __future__ import annotations

import ssl
import urllib.error
import urllib.request

import numpy as np
import pytest
from abb_fixtures import HOME, Q_A, Q_B, TIME_SCALE, ur5
from link_fixtures import sweep

from assistant.emulators.abb_rws_emulator import AbbRwsEmulator
from assistant.links import LinkSettings, make_link
from assistant.links import abb_rws_protocol as rp
from assistant.links.abb_rws import AbbRwsLink
from assistant.links.link import LinkError, LinkEventKind

TOL = 1e-6  # rad: the wire carries 1e-6 deg


@pytest.fixture(scope="module")
def robot():
    return ur5()


def _mission(robot) -> dict[str, bytes]:  # noqa: ANN001
    from test_links_abb import mission

    return mission(robot)


@pytest.mark.parametrize("version", [1, 2])
def test_a_task_with_its_own_main_runs_our_program(robot, closing, version):
    emu = closing(AbbRwsEmulator(robot, start_q=HOME, time_scale=TIME_SCALE,
                                 rws_version=version).start())
    link = closing(AbbRwsLink(robot, port=emu.port, rws_version=version, timeout_s=2.0))
    link.connect()
    assert link.subscription is not None and link.subscription.alive
    assert [m.name for m, _ in emu.rapid.modules.values()] == ["MainModule"]
    n_exec = emu.received_paths().count("GET /rw/rapid/execution")
    ev = link.move_path(np.vstack([sweep(HOME, Q_A, 30), sweep(Q_A, Q_B, 30)[1:]]))
    assert ev.kind == LinkEventKind.REACHED, ev.message
    assert np.allclose(emu.arm.q, Q_B, atol=TOL)
    # The end came as an event: the state was read about once a second, not 100 times.
    reads = emu.received_paths().count("GET /rw/rapid/execution") - n_exec
    assert reads <= 3, reads
    assert link.upload_program("MISSION", _mission(robot)) == "MISSION"
    ev = link.run_program("MISSION")
    assert ev.kind == LinkEventKind.REACHED, ev.message
    assert emu.rapid.runs[-1] == "MISSION" and np.allclose(emu.arm.q, HOME, atol=TOL)
    names = [m.name for m, _ in emu.rapid.modules.values()]
    assert names == ["MainModule", "MISSION"]  # the cell's main untouched, ours beside it
    assert emu.sessions.master is None


def test_omnicore_speaks_rws_2_only(robot, closing, tmp_path):
    emu = closing(AbbRwsEmulator(robot, start_q=HOME, time_scale=TIME_SCALE,
                                 rws_version=2).start())
    assert emu.base_url.startswith("https://")
    ctx = ssl.create_default_context(cafile=str(emu.certfile))  # the controller's own cert
    ctx.check_hostname = False
    import base64

    auth = "Basic " + base64.b64encode(b"Default User:robotics").decode()

    def get(path: str, **headers: str) -> tuple[int, bytes]:
        req = urllib.request.Request(emu.base_url + path, headers=headers)
        try:
            with urllib.request.urlopen(req, timeout=5.0, context=ctx) as r:
                return r.status, r.read()
        except urllib.error.HTTPError as exc:
            return exc.code, exc.read()

    code, body = get("/rw/panel/ctrl-state", Accept="application/hal+json;v=2.0",
                     Authorization=auth)
    assert code == 200 and rp.states(body, "ctrl-state")[0]["ctrlstate"] == "motoron"
    assert get("/rw/panel/ctrl-state", Authorization=auth)[0] == 406  # no v2 Accept
    assert get("/rw/panel/ctrl-state", Accept="application/hal+json;v=2.0")[0] == 401
    code, body = get("/rw/rapid/execution?action=start", Accept="application/hal+json;v=2.0",
                     Authorization=auth)
    assert code == 405 and "RWS 1.0" in body.decode()
    # The RWS 1.0 link (plain HTTP, digest) does not get through; the 2.0 link does.
    old = closing(AbbRwsLink(robot, port=emu.port, timeout_s=2.0))
    with pytest.raises(LinkError):
        old.connect()
    s = LinkSettings(kind="omnicore", host=emu.host, port=emu.port, rws_password="robotics")
    link = closing(make_link(s, robot, log_dir=tmp_path))
    assert isinstance(link, AbbRwsLink) and link.rws.version == 2
    link.connect()
    assert link.move_path(np.array([HOME, Q_A])).kind == LinkEventKind.REACHED
    log = (tmp_path / "wire.log").read_text()
    assert "/rw/mastership/edit/request" in log and "/rw/rapid/tasks/T_ROB1/pcp/routine" in log
    assert "robotics" not in log  # the password never reaches the file
    wrong = closing(AbbRwsLink(robot, port=emu.port, rws_version=2, password="nope"))
    with pytest.raises(LinkError, match="refused the login"):
        wrong.connect()
