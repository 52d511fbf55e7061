"""The run the operator watches in the real page (issue 49): no surprise motion, and the
program's pace.

- After the last Collision! the arm's TCP never comes back to a taught location it had
  already reached and left (no work repeated, no drive back to the start).
- At 1x real time the final program, driven once when the holder asks, lasts the cycle time
  step 7 predicts, within 10 %: the simulated robot follows the program's speeds,
  accelerations and gripper times, not the joints' limits.
"""

from __future__ import annotations

import time

import pytest
from run_watch import Watch, program_seconds, revisits, taught_points
from thesis_page import press_collision_at_each_halt
from web_ui import UI

from assistant.session import Session
from workflow.machine import Mode

pytestmark = pytest.mark.browser

#: Planning, a run at 1x with its halts and the final drive on a loaded 2-core machine.
LONG_MS = 240_000


def test_after_the_last_collision_nothing_is_repeated_and_1x_is_the_programs_pace(
        serve_session, open_ui, tmp_path):
    session = Session.from_sample("thesis_rv2aj", tmp_path / "s")
    session.goto("explore")
    session.build_world()
    session.goto("plan")
    watch = Watch(session)
    app = serve_session(session)
    ui: UI = open_ui(app.url)
    ui.step("6")
    ui.click("Plan")
    ui.wait_enabled("Execute on the robot", timeout=LONG_MS)
    assert ui.row("Simulation speed").locator("input").first.input_value() == "1x real time"
    assert session.link_settings.time_scale == 1.0
    ui.click("Execute on the robot")
    presses = press_collision_at_each_halt(ui, lambda: ui.page.keyboard.press("Space"))
    ui.wait_text("Goal reached: the robot is at P10", timeout=LONG_MS)
    assert presses > 0 and len(watch.collisions) == presses  # the hidden O3 was met

    taught = taught_points(session)
    assert {"P1", "P10"} <= set(taught)
    assert revisits(watch, taught, watch.collisions[-1]) == []

    # The holder drives the final program once, at 1x real time.
    n_before = len(watch.poses)
    ui.wait_enabled("Drive the final program once", timeout=LONG_MS)
    ui.click("Drive the final program once")
    deadline = time.monotonic() + LONG_MS / 1000
    while len(watch.poses) == n_before or session.machine.mode != Mode.IDLE:
        assert time.monotonic() < deadline, "the final program was not driven to its end"
        time.sleep(0.1)
    assert session.final_driven() is True, (session.last_run, watch.notices[-5:])
    ui.click("Next")
    ui.wait_enabled("Download", timeout=LONG_MS)
    predicted = session.program.cycle_time.total_s
    ran = program_seconds(watch, taught["P1"], taught["P10"], n_before)
    print(f"final drive P1 -> P10 at 1x: {ran:.2f} s, predicted {predicted:.2f} s")
    assert ran == pytest.approx(predicted, rel=0.10), (ran, predicted)
