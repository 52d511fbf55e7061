"""Guards in the real page: what the step does not allow cannot be triggered, a refused action
shows its message, broken or oversized uploads leave the session as it was."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from web_ui import UI

from assistant.session import Session

SAMPLE = Path(__file__).resolve().parents[2] / "sample_cells" / "thesis_rv2aj"
O1 = SAMPLE / "dxf" / "O1.dxf"

pytestmark = pytest.mark.browser


def _to_cad_step(ui: UI) -> None:
    ui.click("Next")
    ui.step("2")


def test_disabled_and_refused_actions(serve_session, open_ui):
    session = Session()
    app = serve_session(session)
    ui = open_ui(app.url)
    ui.step("1")
    ui.shot("setup")
    # Step 1 has no Previous: the button is greyed out and a forced click does nothing.
    prev = ui.button("Previous")
    assert prev.is_disabled()
    prev.click(force=True)
    assert session.machine.state == "setup"
    _to_cad_step(ui)
    # Without a part, Next is disabled and the page says why.
    assert ui.button("Next").is_disabled()
    ui.wait_text("Import or place at least one object first")
    ui.shot("cad-next-refused")
    ui.upload("Upload CAD file", O1)
    ui.wait_text("Imported O1")
    ui.click("Next")
    ui.step("3.1")
    ui.click("Next")
    ui.click("Next")
    ui.step("4.1")
    # A name a robot controller would reject: the session refuses with its message.
    ui.fill("Name", "1st point")
    ui.fill_vec("Point (mm)", (300, 0, 100))
    ui.click("Teach by pointer dwell")
    ui.wait_text("use a letter, then letters, digits or _")
    assert session.locations == {}
    # Out of reach: refused with what to do next.
    ui.fill("Name", "far")
    ui.expand("From the robot or by numbers", ui.button("Teach this pose"))
    ui.fill_vec("Position (mm)", (2000, 0, 100))
    ui.click("Teach this pose")
    ui.wait_text("Move the point closer to the robot")
    assert ui.errors() and "Error:" in ui.page.inner_text("body")
    assert session.locations == {}
    ui.shot("teach-refused")
    # Explore is not reachable without start and goal: Next is refused with the reason.
    ui.click("Next")
    ui.step("4.2")
    # the step moved on: the out-of-reach error is stale and gone (notification and toolbar)
    ui.wait_no_errors()
    assert ui.button("Next").is_disabled()
    ui.wait_text("The mission needs a start")
    ui.button("Next").click(force=True)
    assert session.machine.state == "teach.paths"


def test_broken_cad_upload_leaves_session_intact(serve_session, open_ui, tmp_path):
    session = Session()
    app = serve_session(session)
    ui = open_ui(app.url)
    _to_cad_step(ui)
    ui.upload("Upload CAD file", O1)
    ui.wait_text("Imported O1")
    before = session.document()
    undo_before = session.history.undo_label()
    broken = tmp_path / "broken.stl"
    broken.write_bytes(b"solid x\nfacet normal 0 0 1\n  outer loop\n    vertex 0 0\nendsolid\n")
    ui.upload("Upload CAD file", broken)
    ui.wait_text("broken.stl")
    ui.wait_text("Nothing you did was lost.")
    ui.shot("broken-cad")
    assert list(session.cell.objects) == ["O1"]
    assert session.document().obstacles_key() == before.obstacles_key()
    assert session.history.undo_label() == undo_before
    # The page still works: the next good upload goes through, and the refusal, now stale,
    # leaves the screen (no "Could not do that" beside the new part).
    ui.upload("Upload CAD file", SAMPLE / "dxf" / "O2.dxf")
    ui.wait_text("Imported O2")
    ui.wait_no_errors()
    assert list(session.cell.objects) == ["O1", "O2"]


def test_upload_over_the_limit_is_refused_with_the_limit(serve_session, open_ui):
    session = Session()
    app = serve_session(session, max_upload_mb=0.01)  # O1.dxf is ~16 kB
    ui = open_ui(app.url)
    _to_cad_step(ui)
    ui.upload("Upload CAD file", O1)
    ui.wait_text("this page accepts files up to")
    ui.shot("too-large")
    assert session.cell.objects == {}


def test_two_browsers_show_the_same_session(serve_session, open_ui):
    session = Session()
    app = serve_session(session)
    a = open_ui(app.url, "a")
    b = open_ui(app.url, "b")
    a.click("Next")
    b.step("2")
    b.upload("Upload CAD file", O1)
    a.wait_text("Imported O1")
    a.click("Next")
    b.step("3.1")
    b.fill_vec("Position (mm)", (220, -200, 0))
    b.click("Place part")
    a.page.wait_for_function(
        "() => [...document.querySelectorAll('input')].some(i => i.value === '220')")
    assert np.allclose(session.cell.objects["O1"].T_world_object[:3, 3], [0.22, -0.2, 0.0])
    a.shot("browser-a")
    b.shot("browser-b")


def test_collision_key_stops_the_moving_robot(serve_session, open_ui):
    from assistant.links.settings import LinkSettings

    session = Session()
    # slow (the move takes ~15 s): the press lands mid-move even when a loaded machine
    # delays the page by seconds; the press stops it at once
    session.set_link(LinkSettings(time_scale=0.05))
    app = serve_session(session)
    ui = open_ui(app.url)
    ui.expand("Jog the robot", ui.button("Move to the slider values"))
    target_deg = 120.0
    ui.fill("J1 (deg)", target_deg)
    ui.click("Move to the slider values")
    ui.wait_text("The robot is moving")
    app.wait_idle(30)  # every update of the step is out to the page: Space is armed
    ui.page.keyboard.press("Space")
    ui.wait_text("Collision #1 recorded")
    ui.shot("collision-key")
    assert session.counters.collision_indications == 1
    q = session.recorded_collisions[0]
    assert 0.0 < np.degrees(q[0]) < target_deg - 1.0
