"""The served thesis sample and its script are one program: the page's session (the sample
opened with its taught mission, the simulated robot halting until Collision! is pressed at
each halt) writes the same bytes as `cellteach run sample_cells/thesis_rv2aj/session.yaml`
(the README's "the same headless"), and its steps and names are the script's."""

from __future__ import annotations

import threading

import pytest
from test_sample_cells import SAMPLES, run_cli

from assistant.session import Session
from assistant.session.events import RobotHalted
from web.app import operator_pace

pytestmark = pytest.mark.ci_extra  # two full runs of the thesis mission (~1 min)


def test_the_page_writes_the_scripts_program_byte_for_byte(tmp_path):
    proc = run_cli("run", str(SAMPLES / "thesis_rv2aj" / "session.yaml"), "--out",
                   str(tmp_path / "head"), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    s = Session.from_sample("thesis_rv2aj", tmp_path / "page")
    operator_pace(s)  # as `cellteach serve` opens it: the robot waits for Collision!
    s.set_simulation_speed(20.0, count=False)
    assert {"P7", "P8"} <= set(s.locations) and [p.name for p in s.mission.paths] == ["SEAM"]

    def press_at_each_halt(ev: object) -> None:  # the operator at the page
        if isinstance(ev, RobotHalted):
            threading.Thread(target=lambda: s.fire("collision"), daemon=True).start()

    s.bus.subscribe(press_at_each_halt)
    s.goto("explore")
    s.build_world()
    s.goto("plan")
    s.plan()
    rep = s.execute()
    assert rep["ok"] and rep["collision_indications"] >= 1, rep
    s.next()
    prog = s.export("melfa")
    for f in prog.files:
        assert f.data == (tmp_path / "head" / f.name).read_bytes(), f.name
