"""MissionExecutor with the simulated robot on a virtual clock (real FCL, real roadmap, hidden
obstacles): repairs on indications with a back-off, hysteresis on shorter paths, budgets,
collisions on the work itself, a lost link resumed, cancellation - each ends with a reason."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from planning_fixtures import box, make_planner, sim_robot, tcp_points

from assistant.collision.checker import CollisionChecker
from assistant.links.link import LinkEvent, LinkEventKind
from assistant.mission.model import Location
from assistant.planning.config import ExecutionConfig
from assistant.planning.execution import EndReason, MissionExecutor
from assistant.progress import Progress

QUICK = ExecutionConfig(plan_final=False)


@pytest.fixture
def planner(scenario, robot):
    """A fresh world per test: execution records evidence into it."""
    return make_planner(robot, scenario.known_obstacles())


@pytest.fixture(scope="module")
def first_plan(scenario, robot):
    p = make_planner(robot, scenario.known_obstacles())
    plan = p.plan_mission(scenario.mission, np.eye(4), np.zeros(5), exploring=True)
    assert plan.ok
    return plan


def hidden_on(robot, plan, piece: int, frac: float, size=0.05, above=0.0):
    """A box around the TCP (or `above` it) of the plan's piece at `frac` of its path."""
    D = plan.pieces[piece].dense()
    p = tcp_points(robot, D[int(frac * (len(D) - 1))][None])[0] + [0.0, 0.0, above]
    return box("hidden", p, [size] * 3)


def test_indication_is_repaired_with_a_back_off(planner, robot, first_plan, scenario):
    hidden = hidden_on(robot, first_plan, 0, 0.5)
    link = sim_robot(robot, [hidden], first_plan.locations["P1"])
    ex = MissionExecutor(planner, link)
    rep = ex.run(scenario.mission, np.eye(4), plan=first_plan)
    assert rep.end == EndReason.COMPLETED, rep.describe()
    assert rep.collision_indications >= 1 and rep.replans >= 1 and rep.backoffs >= 1
    assert len(planner.world.collisions) == rep.collision_indications
    assert rep.replan_seconds and rep.median_replan_seconds > 0
    assert all(r <= t for r, t in zip(rep.replan_roadmap_seconds, rep.replan_seconds,
                                       strict=True))
    assert rep.executed_tcp_length > rep.backoff_tcp_length > 0
    # transfer 2 was checked against the new evidence, still valid: kept (hysteresis)
    assert rep.switches == 0
    assert "SEAM -> P10: re-checked against new evidence, still valid: kept" in rep.log
    # the run ends at the goal with the final plan made and not driven (no work repeated)
    assert not rep.final_validated and rep.final_plan is not None and rep.final_plan.ok
    assert np.allclose(link.current_joints(), first_plan.locations["P10"], atol=1e-6)
    # driven once when the operator asks: it runs clean and is free against everything
    rep = ex.drive_final()
    assert rep.end == EndReason.COMPLETED and rep.final_validated, rep.describe()
    everything = CollisionChecker(robot, scenario.known_obstacles() + [hidden])
    assert everything.check_path(list(rep.final_plan.trajectory.dense_joint_path())) is None
    assert np.allclose(link.current_joints(), first_plan.locations["P10"], atol=1e-6)
    assert "backing off" in rep.describe()


def test_a_shorter_path_replaces_a_valid_one_past_the_hysteresis(planner, robot, first_plan,
                                                                  scenario):
    # evidence from transfer 1 changes the world before transfer 2, whose plan stays valid;
    # with a negative hysteresis any re-planned path counts as shorter enough
    hidden = hidden_on(robot, first_plan, 0, 0.5)
    link = sim_robot(robot, [hidden], first_plan.locations["P1"])
    cfg = ExecutionConfig(plan_final=False, hysteresis_m=-1.0, hysteresis_ratio=-1.0)
    rep = MissionExecutor(planner, link, cfg).run(scenario.mission, np.eye(4),
                                                  plan=first_plan)
    assert rep.end == EndReason.COMPLETED, rep.describe()
    assert rep.collision_indications >= 1 and rep.switches == 1
    assert "switched to the re-planned path" in rep.describe()


def test_indication_and_replan_budgets_end_the_run(planner, robot, first_plan, scenario):
    hidden = hidden_on(robot, first_plan, 0, 0.5)
    link = sim_robot(robot, [hidden], first_plan.locations["P1"])
    cfg = ExecutionConfig(max_indications=0, plan_final=False)
    rep = MissionExecutor(planner, link, cfg).run(scenario.mission, np.eye(4), plan=first_plan)
    assert rep.end == EndReason.INDICATION_BUDGET and not rep.resumable
    assert "more than 0 collision indications" in rep.reason
    link = sim_robot(robot, [hidden], first_plan.locations["P1"])
    cfg = ExecutionConfig(max_replans=0, plan_final=False)
    rep = MissionExecutor(planner, link, cfg).run(scenario.mission, np.eye(4), plan=first_plan)
    assert rep.end == EndReason.REPLAN_BUDGET and "P1 -> SEAM" in rep.reason


def test_collision_on_the_application_path_stops_the_mission(planner, robot, first_plan,
                                                             scenario):
    # the tool's body ends 2 cm above the TCP (touching the work is not a collision)
    hidden = hidden_on(robot, first_plan, 1, 0.5, size=0.03, above=0.035)
    link = sim_robot(robot, [hidden], first_plan.locations["P1"])
    rep = MissionExecutor(planner, link, QUICK).run(scenario.mission, np.eye(4),
                                                    plan=first_plan)
    assert rep.end == EndReason.MISSION_COLLIDES
    assert "SEAM" in rep.reason and "re-teach" in rep.reason
    assert rep.collision_indications == 1 and len(planner.world.collisions) == 1


def test_a_plan_that_cannot_be_made_ends_before_moving(planner, robot, scenario):
    mission = scenario.mission
    T = mission.goal.T_world_tool.copy()
    T[:3, 3] = [0.9, 0.0, 0.2]
    link = sim_robot(robot)
    rep = MissionExecutor(planner, link).run(replace(mission, goal=Location("P10", T)),
                                             np.eye(4))
    assert rep.end == EndReason.PLAN_FAILED and "P10" in rep.reason
    assert rep.executed_tcp_length == 0.0


class FlakyLink:
    """Wraps a simulated robot: the n-th move drops the connection half way."""

    def __init__(self, inner, fail_on: int):
        self.inner, self.fail_on, self.calls = inner, fail_on, 0

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def connect(self):
        self.inner.connect()

    @property
    def connected(self):
        return self.inner.connected

    def move_path(self, joint_path, *, speed_scale=1.0):
        return self.move_paced(joint_path, None, None, speed_scale=speed_scale)

    def move_paced(self, joint_path, t, hold, *, speed_scale=1.0):
        self.calls += 1
        if self.calls != self.fail_on:
            if t is None:
                return self.inner.move_path(joint_path, speed_scale=speed_scale)
            return self.inner.move_paced(joint_path, t, hold, speed_scale=speed_scale)
        half = np.asarray(joint_path)[: max(2, len(joint_path) // 2)]
        self.inner.move_path(half, speed_scale=speed_scale)
        self.inner.close()
        return LinkEvent(LinkEventKind.LINK_LOST, self.inner.current_joints(),
                         message="no reply for 1.0 s", path_index=len(half) - 1)


def test_link_lost_mid_execution_then_resume(planner, robot, first_plan, scenario):
    link = FlakyLink(sim_robot(robot, (), first_plan.locations["P1"]), fail_on=1)
    ex = MissionExecutor(planner, link, QUICK)
    rep = ex.run(scenario.mission, np.eye(4), plan=first_plan)
    assert rep.end == EndReason.LINK_LOST and rep.resumable and "resume" in rep.reason
    stopped = link.current_joints()
    assert not np.allclose(stopped, first_plan.locations["P1"])  # it had moved
    rep = ex.resume()
    assert rep.end == EndReason.COMPLETED, rep.describe()
    assert rep.resumes == 1 and link.connected
    assert np.allclose(link.current_joints(), first_plan.locations["P10"], atol=1e-6)
    with pytest.raises(RuntimeError, match="nothing to resume"):
        ex.resume()


def test_cancel_stops_the_robot_and_resume_finishes(planner, robot, first_plan, scenario):
    link = sim_robot(robot, (), first_plan.locations["P1"])
    prog = Progress("execute")
    ex = MissionExecutor(planner, link, QUICK)
    moved = []

    def cancel_after_a_few(ev):
        if ev.kind == LinkEventKind.MOVED:
            moved.append(ev)
            if len(moved) == 5:
                prog.cancel()

    link.subscribe(cancel_after_a_few)
    rep = ex.run(scenario.mission, np.eye(4), prog, plan=first_plan)
    assert rep.end == EndReason.CANCELLED and rep.resumable
    assert len(moved) <= 7  # stopped within an event or two
    rep = ex.resume(Progress("resume"))
    assert rep.end == EndReason.COMPLETED, rep.describe()


def test_a_cancelled_executor_does_not_stop_the_next_one_on_the_same_link(
        planner, robot, first_plan, scenario):
    link = sim_robot(robot, (), first_plan.locations["P1"])
    prog = Progress("execute")
    prog.cancel()
    rep = MissionExecutor(planner, link, QUICK).run(scenario.mission, np.eye(4), prog,
                                                    plan=first_plan)
    assert rep.end == EndReason.CANCELLED
    rep = MissionExecutor(planner, link, QUICK).run(scenario.mission, np.eye(4),
                                                    plan=first_plan)
    assert rep.end == EndReason.COMPLETED, rep.describe()
