"""Step 4 in the real page with fewer operator actions: the Name field suggests the location
after the one just taught, the path's "Through" is prefilled with the taught points no path
uses yet (not the start or goal), and a refused target is drawn with the arm's reach and how
far beyond it lies - gone at the next successful teach."""

from __future__ import annotations

import re

import numpy as np
import pytest

from assistant.robots.reach import arm_reach
from assistant.session import Session
from web.panels.paths import application_points, free_path_name
from web.panels.teach import name_after

pytestmark = pytest.mark.browser


def _at_teach(tmp_path) -> Session:  # noqa: ANN001
    session = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                                  with_mission=False)
    session.fire("next")
    session.add_primitive("box", (0.1, 0.1, 0.1), name="B")
    session.goto("teach.locations")
    return session


def _value(ui, label: str) -> str:  # noqa: ANN001
    return ui.row(label).locator("input:not([type=hidden])").first.input_value()


def _wait_value(ui, label: str, value: str) -> None:  # noqa: ANN001
    box = ui.row(label).locator("input:not([type=hidden])").first
    ui.page.wait_for_function("([el, v]) => el.value === v", arg=[box.element_handle(), value],
                              timeout=30_000, polling=100)


@pytest.mark.parametrize(("taught", "existing", "expected"), [
    ("P7", {"P7"}, "P8"),
    ("SEAM_3", {"SEAM_3"}, "SEAM_4"),
    ("P10", {"P10"}, "P11"),
    ("P09", {"P09"}, "P10"),
    ("P7", {"P7", "p8", "P9"}, "P10"),  # taken names are skipped, without case
    ("SEAM", {"SEAM"}, "SEAM_2"),
    ("SEAM", {"SEAM", "seam_2"}, "SEAM_3"),
])
def test_name_after(taught: str, existing: set[str], expected: str) -> None:
    assert name_after(taught, existing) == expected


def test_application_points_and_path_names(tmp_path) -> None:  # noqa: ANN001
    session = _at_teach(tmp_path)
    for name, x in (("P1", 0.25), ("P7", 0.30), ("P8", 0.33), ("P9", 0.36), ("P10", 0.28)):
        session.teach_from_pointer(name, (x, 0.1, 0.05))
    session.set_start("P1")
    session.set_goal("P10")
    assert application_points(session.locations, session.mission) == ["P7", "P8", "P9"]
    session.goto("teach.paths")
    session.add_path("SEAM", "line", ["P7", "P8"])
    assert application_points(session.locations, session.mission) == ["P9"]
    assert free_path_name(["SEAM", "l1", "L2"]) == "L3"


def test_name_follows_and_through_is_prefilled(serve_session, open_ui, tmp_path):
    session = _at_teach(tmp_path)
    session.teach_from_pointer("P1", (0.25, 0.15, 0.05))
    session.teach_from_pointer("P10", (0.25, -0.15, 0.05))
    app = serve_session(session)
    ui = open_ui(app.url)
    ui.step("4.1")
    teach = app.panels["Teach locations"]
    ui.fill("Name", "P7")
    ui.click("Teach by pointer dwell")  # at the Point field's (300, 0, 100) mm
    ui.wait_cell("P7")
    # The next name is suggested, and the synthetic camera's seed follows it.
    _wait_value(ui, "Name", "P8")
    assert teach.seed.value == 8
    # Any way of teaching: from the robot's pose, P8 as suggested, then P9.
    ui.expand("From the robot or by numbers", ui.button("Teach the robot's pose"))
    ui.click("Teach the robot's pose")
    ui.wait_cell("P8")
    _wait_value(ui, "Name", "P9")
    assert session.locations["P8"].source.value == "robot_pose"
    assert list(session.locations) == ["P1", "P10", "P7", "P8"]
    session.set_start("P1")
    session.set_goal("P10")
    ui.wait_enabled("Next")
    ui.click("Next")
    ui.step("4.2")
    # Through: the points taught for the application, in order; not the start nor the goal.
    _wait_value(ui, "Through", "P7, P8")
    _wait_value(ui, "Path name", "L1")
    ui.fill("Path name", "SEAM")
    ui.click("Add path")
    ui.wait_cell("SEAM")
    assert [p.name for p in session.mission.paths] == ["SEAM"]
    assert session.mission.paths[0].segments[0].names == ("P7", "P8")
    # Both points are used now: nothing left to suggest; the next path is L1.
    _wait_value(ui, "Through", "")
    _wait_value(ui, "Path name", "L1")
    # What the operator types stays when the locations change.
    ui.fill("Through", "P8, P7")
    session.goto("teach.locations")
    session.teach_from_pointer("P11", (0.30, 0.0, 0.05))
    session.goto("teach.paths")
    ui.step("4.2")
    app.wait_idle(10)
    assert _value(ui, "Through") == "P8, P7"
    ui.shot("paths")


def test_out_of_reach_shows_where_and_how_far(serve_session, open_ui, tmp_path):
    session = _at_teach(tmp_path)
    app = serve_session(session)
    ui = open_ui(app.url)
    ui.step("4.1")
    teach = app.panels["Teach locations"]
    layer = teach.reach
    ui.fill("Name", "P1")
    ui.expand("From the robot or by numbers", ui.button("Teach this pose"))
    target_mm = (900.0, 100.0, 100.0)
    ui.fill_vec("Position (mm)", target_mm)
    ui.click("Teach this pose")
    ui.wait_text(re.compile(r"Could not do that"))
    reach = arm_reach(session.robot)
    beyond_mm = reach.beyond_world(np.array(target_mm) / 1000.0, session.T_world_base()) * 1000
    assert beyond_mm > 100  # the target is far out: the figure below is no rounding artefact
    said = ui.wait_text(re.compile(r"P1: \d+ mm beyond the arm's reach")).inner_text()
    shown_mm = float(re.search(r"P1: (\d+) mm beyond", said).group(1))
    assert abs(shown_mm - beyond_mm) <= 0.5  # the page rounds to whole millimetres
    # In the scene: the red target at the typed point, labelled, and the reach sphere.
    assert {"sphere", "rings", "target", "label"} <= set(layer._nodes)  # noqa: SLF001
    assert np.allclose(layer._nodes["target"].position, np.array(target_mm) / 1000.0,  # noqa: SLF001
                       atol=1e-6)
    assert layer.shown is not None and f"{shown_mm:.0f} mm beyond" in layer.shown.label
    assert abs(layer.shown.radius - reach.radius) < 1e-12
    assert "P1" not in session.locations
    ui.page.wait_for_timeout(1500)  # let the browser draw the scene for the picture
    print(f"out-of-reach screenshot: {ui.shot('out-of-reach')}")
    handles = list(layer._nodes.values())  # noqa: SLF001
    # The next teach that succeeds: the drawing and the line are gone, P1 is taught.
    ui._type(ui.row("Position (mm)").locator("input").first, "300")  # noqa: SLF001 - x only
    ui.click("Teach this pose")
    ui.wait_cell("P1")
    assert layer.shown is None and not layer._nodes  # noqa: SLF001
    assert all(h._impl.removed for h in handles)  # noqa: SLF001
    # The page drops the refused line once the next teach lands (a round trip, not instant).
    ui.page.get_by_text(re.compile(r"mm beyond the arm's reach")).first.wait_for(
        state="hidden", timeout=15_000)
    _wait_value(ui, "Name", "P2")
