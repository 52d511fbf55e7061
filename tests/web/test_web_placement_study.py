"""The placement study in the real page (headless Chromium): the place step's "Find a
placement" fold runs a study over a typed region, lists the ranking, draws the markers on
the table and "Move the robot here" moves the base (undoable)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from assistant.session import Session

# Here, not in tests/study: the page fixtures (one Playwright driver per test session) are
# this folder's conftest; a second driver loaded from another folder breaks every later
# browser test ("Sync API inside the asyncio loop").
pytestmark = [pytest.mark.browser, pytest.mark.slow]


def test_page_finds_a_placement_and_moves_the_robot(serve_session, open_ui):
    session = Session.from_sample("thesis_rv2aj", None)
    session.goto("place.objects")
    app = serve_session(session)
    ui = open_ui(app.url)
    ui.step("3.1")
    ui.expand("Find a placement", ui.button("Start study"))
    ui.fill_vec("From X, Y (mm)", (0, 0))
    ui.fill_vec("To X, Y (mm)", (100, 300))
    ui.fill("Step (mm)", 100)
    ui.fill("Yaw steps", 1)
    ui.click("Start study")
    ui.wait_text("8 candidates:", timeout=240_000)  # 2 x 4 positions, 1 yaw
    study = session.placement_study
    assert study is not None and study.best() is not None
    ui.wait_cell("1")  # the ranking table's first row
    markers = app.panels["Place objects"].markers
    assert markers.shown and sum(k.startswith("p") for k in markers._nodes) == 8
    ui.shot("placement-study")
    best = study.best().candidate
    T0 = session.T_world_base().copy()
    ui.click("Move the robot here")  # the best candidate is chosen first
    deadline = time.monotonic() + 30
    while np.allclose(session.T_world_base(), T0) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert np.allclose(session.T_world_base()[:2, 3], [best.x, best.y])
    ui.wait_no_errors()
    assert session.undo().startswith("move the robot base")
    assert np.allclose(session.T_world_base(), T0)
    session.close()
