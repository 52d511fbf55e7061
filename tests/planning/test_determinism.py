"""The same operator actions give the same program (a browser run and a headless run are
compared byte for byte), so planning results are decided by counted budgets - iterations,
expansions, edge checks - and never by the clock. A process slowed tenfold (here: a clock that
runs ten times too fast) plans the same trajectory; a clock so fast that the wall-time safety
nets trip makes the plan fail with that reason instead of quietly changing it."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
import pytest
from planning_fixtures import make_planner

from assistant.export import export_files, program_from_trajectory
from assistant.planning.config import MissionPlannerConfig
from assistant.roadmap.planner import PlanFailure


@pytest.fixture(scope="module")
def planner(scenario):
    # the production budgets: the old 10 s smoothing budget was reached under such load
    return make_planner(scenario.cell.robot(), scenario.known_obstacles(),
                        config=MissionPlannerConfig())


def _clock_runs_fast(monkeypatch: pytest.MonkeyPatch, factor: float) -> None:
    """Make time.perf_counter and time.monotonic advance `factor` times faster than real."""
    real_pc, real_mono = time.perf_counter, time.monotonic
    pc0, mono0 = real_pc(), real_mono()
    monkeypatch.setattr(time, "perf_counter", lambda: pc0 + factor * (real_pc() - pc0))
    monkeypatch.setattr(time, "monotonic", lambda: mono0 + factor * (real_mono() - mono0))


def _program(plan, robot) -> bytes:
    files = export_files(program_from_trajectory(plan.trajectory, robot, name="SAME"), "melfa",
                         robot).files
    return b"".join(f.data for f in files)


def _transfer_seconds(plan) -> list[float]:
    return [p.seconds for p in plan.report.pieces if p.kind == "transfer"]


def test_a_slowed_process_plans_the_same_trajectory(planner, scenario, monkeypatch):
    robot = planner.robot
    T_wb = scenario.cell.T_world_base
    normal = planner.plan_mission(scenario.mission, T_wb, np.zeros(5))
    assert normal.ok, normal.report.describe()
    # At least ten times slower, and slow enough that every transfer takes over 20 s of
    # (apparent) wall time: the old 10 s smoothing budget would have cut them all short.
    factor = max(10.0, 20.0 / min(_transfer_seconds(normal)))
    _clock_runs_fast(monkeypatch, factor)
    slowed = planner.plan_mission(scenario.mission, T_wb, np.zeros(5))
    assert slowed.ok, slowed.report.describe()
    assert min(_transfer_seconds(slowed)) > 10.0
    a, b = normal.trajectory, slowed.trajectory
    assert [m.kind for m in a.motions] == [m.kind for m in b.motions]
    # a run compared with itself (same input, same process, only the clock differs): exact
    for ma, mb in zip(a.motions, b.motions, strict=True):
        assert np.array_equal(ma.target.q, mb.target.q)
        assert np.array_equal(ma.joint_path, mb.joint_path)
    assert _program(normal, robot) == _program(slowed, robot)


def test_a_tripped_safety_net_fails_loudly(planner, scenario, monkeypatch):
    normal = planner.plan_mission(scenario.mission, scenario.cell.T_world_base, np.zeros(5))
    q1, q10 = normal.locations["P1"], normal.locations["P10"]
    _clock_runs_fast(monkeypatch, 1e7)  # every microsecond of work "takes" ten seconds
    plan = planner.plan_mission(scenario.mission, scenario.cell.T_world_base, np.zeros(5))
    assert not plan.ok and plan.trajectory is None
    assert "safety limit" in plan.reason, plan.reason
    # A search stopped by the clock is no answer - neither "no path" nor a counted budget.
    # The path-first search looks at the clock between rounds (its compiled search runs a
    # round to the end, within the expansion budget), and this query's first path passes:
    # it is answered. Checking at every pop looks at the clock at every expansion.
    first = planner.roadmap.plan(q1, q10)
    assert first.ok and first.edge_checks == len(first.joint_path) - 1
    cfg = planner.roadmap.config
    monkeypatch.setattr(planner.roadmap, "config",
                        replace(cfg, budget=replace(cfg.budget, path_rounds=0)))
    search = planner.roadmap.plan(q1, q10)
    assert search.failure == PlanFailure.SAFETY_LIMIT and "safety limit" in search.reason
