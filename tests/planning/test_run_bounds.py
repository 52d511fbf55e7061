"""Every run ends within its bound (`planning.run_bounds`): a re-plan that would search on
is ended at the run's planning deadline with the reason, and the progress line names the
indications so far and the planning time left."""

from __future__ import annotations

import time

import numpy as np
import pytest
from planning_fixtures import box, make_planner, sim_robot, tcp_points

from assistant.planning.config import ExecutionConfig
from assistant.planning.execution import EndReason, MissionExecutor
from assistant.planning.run_bounds import PlanningTimeUp, RunBounds
from assistant.progress import Progress

#: What a run may overrun its planning bound by: the learning of one indication and one
#: progress period of the search (milliseconds idle), with room for a busy shared machine.
SLACK_S = 10.0


@pytest.fixture(scope="module")
def first_plan(scenario, robot):
    p = make_planner(robot, scenario.known_obstacles())
    plan = p.plan_mission(scenario.mission, np.eye(4), np.zeros(5), exploring=True)
    assert plan.ok
    return plan


def test_the_progress_line_names_the_indications_and_the_planning_left():
    b = RunBounds(20, 120.0)
    b.used = 25.0
    assert b.line("re-planning", 3) == "re-planning - indication 3 of 20, 95 s of planning left"
    b.used = 130.0
    assert b.left() == 0.0
    with pytest.raises(PlanningTimeUp):
        b.check()


def test_a_real_search_is_ended_at_the_deadline(scenario, robot, first_plan):
    planner = make_planner(robot, scenario.known_obstacles())
    pieces = first_plan.pieces
    q_s, q_g = pieces[0].q_start, pieces[-1].q_end
    spent = RunBounds(20, 1e-9)  # the deadline has passed: the search's first word ends it
    with pytest.raises(PlanningTimeUp):
        planner.plan_transfer(q_s, q_g, exploring=True,
                              progress=spent.progress(Progress(), "re-planning", lambda: 1))


def test_a_run_that_hits_the_planning_bound_ends_with_its_reason_within_it(
        scenario, robot, first_plan):
    planner = make_planner(robot, scenario.known_obstacles())
    D = first_plan.pieces[0].dense()
    p = tcp_points(robot, D[len(D) // 2][None])[0]
    link = sim_robot(robot, [box("hidden", p, [0.05] * 3)], first_plan.locations["P1"])
    bound = 2.0
    ex = MissionExecutor(planner, link, ExecutionConfig(plan_final=False,
                                                        max_planning_seconds=bound))

    def endless(q_start, q_goal, *, progress=None, **kw):
        """A search that never ends by itself, reporting progress as every search does."""
        assert progress is not None, "a re-plan was started without the run's deadline"
        x = np.zeros(64)
        give_up = time.perf_counter() + bound + 6 * SLACK_S  # the test fails, never hangs
        while time.perf_counter() < give_up:
            x = np.sin(x + 1.0)  # work, not a sleep
            progress.update(0.5, "searching roads")
        raise AssertionError("the re-plan was not ended at the run's deadline")

    planner.plan_transfer = endless
    lines: list[str] = []
    t0 = time.perf_counter()
    rep = ex.run(scenario.mission, np.eye(4), Progress(
        "execute", lambda ev: lines.append(ev.message), min_interval_s=0.0), plan=first_plan)
    wall = time.perf_counter() - t0
    assert rep.end == EndReason.PLANNING_BUDGET, rep.describe()
    assert "2 s of planning are used up" in rep.reason and "1 collision indication" in rep.reason
    assert rep.collision_indications == 1 and not rep.resumable
    assert ex.bounds.used <= bound + SLACK_S
    assert wall <= bound + 2 * SLACK_S  # the drive runs on a virtual clock
    assert any("re-planning - indication 1 of 20" in m and "s of planning left" in m
               for m in lines), lines[-5:]
    assert any(m.startswith("driving P1 -> SEAM - indication 0 of 20") for m in lines)
