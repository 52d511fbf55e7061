"""Link settings as a session stores them, the links they build, and the demo emulators."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys

import numpy as np
import pytest
from link_fixtures import HOME, Q_A

from assistant.emulators.kuka_bridge_emulator import KukaBridgeEmulator
from assistant.emulators.melfa_emulator import MelfaEmulator
from assistant.links import LinkSettings, LinkSettingsError, make_link
from assistant.links.kuka_rest import KukaRestLink
from assistant.links.link import LinkEventKind
from assistant.links.melfa import MelfaLink
from assistant.links.simulated import SimulatedRobot


def test_settings_round_trip_through_json():
    s = LinkSettings(kind="melfa", host="192.168.0.1", port=10001, datalink_port=10002,
                     slot=2, timeout_s=0.5, stream_cycle_s=0.0071)
    back = LinkSettings.from_json(json.loads(json.dumps(s.to_json())))
    assert back == s
    assert LinkSettings.from_json({"kind": "kuka_rest", "port": "8000"}).port == 8000


@pytest.mark.parametrize("data, field", [
    ({"kind": "fanuc"}, "kind"),
    ({"port": 70000}, "port"),
    ({"timeout_s": 0}, "timeout_s"),
    ({"slot": 40}, "slot"),
    ({"stream_window": 0}, "stream_window"),
    ({"colour": "red"}, "colour"),
    ({"port": "ten"}, "port"),
])
def test_bad_settings_name_the_field(data, field):
    with pytest.raises(LinkSettingsError, match=field):
        LinkSettings.from_json(data)


def test_make_link_builds_each_kind(rv2aj):
    assert isinstance(make_link(LinkSettings(), rv2aj), SimulatedRobot)
    assert isinstance(make_link(LinkSettings(kind="melfa"), rv2aj), MelfaLink)
    assert isinstance(make_link(LinkSettings(kind="kuka_rest", port=8000), rv2aj), KukaRestLink)


def test_links_built_from_settings_drive_the_emulators(fast_robot, closing):
    melfa = closing(MelfaEmulator(fast_robot, start_q=HOME, tick_s=0.004).start())
    kuka = closing(KukaBridgeEmulator(fast_robot, start_q=HOME, tick_s=0.004).start())
    for s in (LinkSettings(kind="melfa", port=melfa.port, datalink_port=melfa.datalink_port(),
                           stream_cycle_s=0.004),
              LinkSettings(kind="kuka_rest", port=kuka.port)):
        link = closing(make_link(s, fast_robot))
        link.connect()
        assert link.move_path(np.array([HOME, Q_A])).kind == LinkEventKind.REACHED
        assert np.allclose(link.current_joints(), Q_A, atol=1e-3)
    assert np.allclose(melfa.arm.q, Q_A, atol=1e-3) and np.allclose(kuka.arm.q, Q_A, atol=1e-3)


@pytest.mark.parametrize("module, args", [
    ("assistant.emulators.melfa_emulator", ["--port", "0", "--datalink-port", "0"]),
    ("assistant.emulators.kuka_bridge_emulator", ["--port", "0"]),
])
@pytest.mark.parametrize("sigint_ignored", [False, True])
def test_emulators_run_as_scripts(rv2aj, module, args, sigint_ignored):
    """Started, answering, and stopped cleanly by Ctrl-C - also when started the way a
    background job of a non-interactive shell is (SIGINT inherited as ignored)."""
    def ignore_sigint() -> None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)

    proc = subprocess.Popen([sys.executable, "-m", module, *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=ignore_sigint if sigint_ignored else None)
    try:
        line = proc.stdout.readline()
        ports = [int(p) for p in re.findall(r":(\d+)", line)]
        assert ports, f"no port in {line!r}; stderr: {proc.stderr.read() if proc.poll() else ''}"
        if "melfa" in module:
            link = MelfaLink(rv2aj, port=ports[0], datalink_port=ports[1], timeout_s=2.0)
        else:
            link = KukaRestLink(rv2aj, port=ports[0], timeout_s=2.0)
        link.connect()
        assert np.allclose(link.current_joints(), 0.0, atol=1e-4)
        link.close()
    finally:
        proc.send_signal(signal.SIGINT)
        try:  # a loaded machine may take seconds to run the emulator's shutdown
            proc.wait(timeout=60.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=5.0)
        proc.stdout.close()
        proc.stderr.close()
    assert proc.returncode == 0
