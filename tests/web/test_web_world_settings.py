"""The world step's Advanced settings in the real page: applied to the session, a bad value
refused with the allowed range and nothing changed."""

from __future__ import annotations

import pytest

from assistant.session import Session

pytestmark = pytest.mark.browser


def test_advanced_world_settings_apply_and_refuse(serve_session, open_ui, tmp_path):
    session = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=True,
                                  with_mission=True)
    session.goto("explore")
    assert session.machine.state == "explore"
    app = serve_session(session)
    ui = open_ui(app.url)
    ui.step("5")
    apply = ui.button("Apply settings")
    ui.expand("Advanced", apply)
    ui.fill("Joint samples", 500000)
    ui.fill("Memory budget (MB)", 1024)
    ui.fill("Clearance (mm)", 15)
    ui.click("Apply settings")
    ui.page.wait_for_function("() => true")
    for _ in range(240):  # up to 60 s for the server to apply it, never a timing
        if session.world_settings.memory_mb == 1024:
            break
        ui.page.wait_for_timeout(250)
    ws = session.world_settings
    assert (ws.joint_samples, ws.memory_mb, ws.clearance_mm) == (500000, 1024, 15.0)
    ui.shot("world-settings")
    # a cell size below what the octree allows: the page says the range, nothing changes
    ui.fill("Cell size (mm, 0 = auto)", 5)
    ui.click("Apply settings")
    ui.wait_text("10-250 mm")
    assert session.world_settings == ws
