"""A run at a human pace in the real page: the speed is chosen with its unit, a greyed button
says why, the robot halts at the hidden obstacle until the operator presses Collision!, the
page counts the moves as report.json does, and the run ends with "Goal reached" (once) and the
learnt obstacle drawn as a solid of the cells it made occupied."""

from __future__ import annotations

import time

import pytest
from thesis_page import press_collision_at_each_halt
from web_ui import UI

from assistant.session import Session

#: Planning and a run with three collision indications on a loaded 2-core machine.
LONG_MS = 180_000

pytestmark = pytest.mark.browser


def test_a_run_at_the_chosen_pace_ends_with_the_goal_and_the_learnt_obstacle(
        serve_session, open_ui, tmp_path):
    session = Session.from_sample("thesis_rv2aj", tmp_path / "s")
    session.goto("explore")
    session.build_world()
    session.goto("plan")
    app = serve_session(session)
    ui: UI = open_ui(app.url)
    ui.step("6")
    ui.wait_text("Execute: plan the mission first")  # a greyed button says why
    ui.click("Plan")
    ui.wait_enabled("Execute on the robot", timeout=LONG_MS)
    ui.wait_text("Mission planned: ")
    n = sum(session.trajectory.primitive_counts().values())
    ui.wait_text(f"Mission planned: {n} moves")  # report.json's count, not the drawing's
    assert ui.row("Simulation speed").locator("input").first.input_value() == "1x real time"
    ui.choose("Simulation speed", "20x real time")  # this test's robot need not be watched
    deadline = time.monotonic() + 60  # a wait for the server to hear it, never a timing
    while session.link_settings.time_scale != 20.0 and time.monotonic() < deadline:
        ui.page.wait_for_timeout(100)
    assert session.link_settings.time_scale == 20.0
    # the plan's own announcement may still be up (its notification closes on a timer that
    # a hovering pointer pauses): only a second one would be wrong
    announced = ui.page.get_by_text("The mission is planned").count()
    ui.click("Execute on the robot")
    # The page's robot halts at the hidden O3 until the operator presses Collision! (Space).
    # The step heading says the robot stopped (not "is moving"); no notification repeats it.
    def halted_once() -> None:
        ui.wait_text("The robot has stopped against something the model does not know.")
        assert ui.page.locator(".mantine-Notification-root",
                               has_text="stopped against").count() == 0
        # the finished phase does not linger: the plan's "Done" line went when the run began
        ui.page.wait_for_function(
            "() => !document.body.innerText.includes('The mission is planned')",
            timeout=30_000, polling=200)

    presses = press_collision_at_each_halt(ui, lambda: ui.page.keyboard.press("Space"),
                                           first=halted_once)
    ui.wait_text("Goal reached: the robot is at P10", timeout=LONG_MS)
    assert presses == session.counters.collision_indications
    ui.shot("6-goal")
    assert session.counters.collision_indications > 0  # the hidden O3 was met
    app.wait_idle(10)
    world = app.scene_layers.world
    assert world.learnt_drawn > 0 and "learnt" in world._nodes  # noqa: SLF001
    view = session.learnt_view()  # the learnt cells without the arm where it stands
    assert view is not None and len(view.centres) == world.learnt_drawn
    # One message per outcome: the run's final plan is not announced as "planned" again.
    assert ui.page.get_by_text("The mission is planned").count() <= announced


def test_the_simulation_speed_is_checked_and_kept_where_the_robot_stands(tmp_path):
    from assistant.session import SessionError

    session = Session.from_sample("thesis_rv2aj", tmp_path / "s")
    try:
        link = session.link()
        q = link.current_joints() + 0.1
        link.set_joints(q)
        session.set_simulation_speed(5.0)
        assert session.link_settings.time_scale == 5.0
        assert session.counters.operator_actions == 1
        new = session.link()  # made again with the new clock, where the robot stood
        assert new is not link and new.clock.time_scale == 5.0
        assert abs(new.current_joints() - q).max() < 1e-12  # the same numbers, kept as is
        for bad in (0.0, -1.0, 1000.0):
            try:
                session.set_simulation_speed(bad)
            except SessionError as exc:
                assert "times real time" in str(exc)
            else:
                raise AssertionError(f"{bad}x was accepted")
        assert session.link_settings.time_scale == 5.0
    finally:
        session.close()
