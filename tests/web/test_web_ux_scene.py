"""An uncluttered scene in the real page: the simulated robot runs in real time by default
(the speed said with its unit), the scene-layer switches are on every step with the roads off,
parts and locations are labelled, and an imported part waits beside the robot."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from web_ui import UI

from assistant.session import Session

SAMPLE = Path(__file__).resolve().parents[2] / "sample_cells" / "thesis_rv2aj"

pytestmark = pytest.mark.browser


def _view_switch(ui: UI, label: str):
    box = ui.row(label).locator("input[type=checkbox]").first
    ui.expand("Scene layers", box)
    return box


def test_view_switches_labels_and_the_waiting_spot(serve_session, open_ui, tmp_path):
    session = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                                  with_mission=False)
    assert session.link_settings.time_scale == 20.0  # the sample's pace, for scripts
    app = serve_session(session)
    assert session.link_settings.time_scale == 1.0  # the page's: real time
    assert session.counters.operator_actions == 0  # not the operator's doing
    ui = open_ui(app.url)
    ui.step("1")
    ui.wait_text("Simulation speed (x real time)")
    roads = _view_switch(ui, "Roads")
    assert not roads.is_checked()  # hundreds of dots hide the path: off by default
    assert _view_switch(ui, "Labels").is_checked()
    ui.shot("1-view")
    ui.click("Next")
    ui.step("2")
    assert _view_switch(ui, "Roads").is_visible()  # the View is there on every step
    ui.choose("Units", "mm")
    ui.upload("Upload CAD file", SAMPLE / "dxf" / "O1.dxf")
    ui.wait_text("Imported O1")
    ui.shot("2-imported")
    # The part waits behind the robot's base, clear of the arm, labelled with its name.
    T = session.cell.objects["O1"].T_world_object
    lo, hi = session.cell.objects["O1"].display_mesh.bounds
    base = session.T_world_base()[:3, 3]
    assert np.linalg.norm(T[:2, 3] - base[:2]) > 0.3 + np.linalg.norm(hi[:2] - lo[:2]) / 2
    assert "O1/label" in app.scene_layers.objects._nodes  # noqa: SLF001
    # Hiding the labels hides the scene group they live in.
    _view_switch(ui, "Labels").uncheck()
    deadline = time.monotonic() + 60  # a wait for the server to hear it, never a timing
    while app.scene_layers.groups["labels"].visible and time.monotonic() < deadline:
        ui.page.wait_for_timeout(100)
    assert app.scene_layers.groups["labels"].visible is False
