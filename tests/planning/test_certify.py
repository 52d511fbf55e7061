"""A mesh arm's transfer is certified by the exact check alone, and planned again with exact
checks only when that refuses (`planning.certify`) - shown with a fast model made wrong."""

from __future__ import annotations

import numpy as np
import pytest
from planning_fixtures import box as _box
from planning_fixtures import ur5_with_tool

from assistant.collision.checker import CollisionChecker
from assistant.planning import MissionPlanner
from assistant.roadmap.planner import RoadmapPlanner
from assistant.world.model import WorldConfig, WorldModel
from assistant.world.reachability import ReachabilityConfig


@pytest.fixture(scope="module")
def cell():
    ur5 = ur5_with_tool()
    obstacles = [_box("table", (0.2, 0.0, -0.011), (1.2, 1.2, 0.02)),
                 _box("post", (0.45, 0.0, 0.3), (0.08, 0.08, 0.6))]
    cfg = WorldConfig.for_robot(ur5, reach=ReachabilityConfig(samples=1 << 15,
                                                              focus_samples=1 << 15),
                                use_cache=False)
    world = WorldModel(ur5, obstacles, cfg)
    q_s = np.radians([-40.0, -100.0, 100.0, -90.0, -90.0, 0.0])
    q_g = np.radians([40.0, -100.0, 100.0, -90.0, -90.0, 0.0])
    world.anchors = np.array([q_s, q_g])
    checker = CollisionChecker(ur5, obstacles)
    roadmap = RoadmapPlanner(ur5, checker, world)
    roadmap.build()
    planner = MissionPlanner(ur5, obstacles, world, roadmap, checker)
    return ur5, planner, q_s, q_g


def _truly_free(planner, dense) -> bool:
    """Brute-force FCL (the robot's own kinematics, every pair) at every dense sample."""
    return not any(planner.checker.in_collision_naive(q) for q in dense)


def _wrong_everywhere(monkeypatch, fast) -> None:
    """The fast model calls everything free and far from everything."""
    monkeypatch.setattr(fast, "is_valid_samples",
                        lambda Q, groups=None, **k: fast.robot.limits.contains_batch(
                            np.atleast_2d(Q)))
    monkeypatch.setattr(fast, "in_collision_batch",
                        lambda Q: np.zeros(len(np.atleast_2d(Q)), dtype=bool))
    monkeypatch.setattr(fast, "is_valid_batch_margin",
                        lambda Q, certified=None: (fast.robot.limits.contains_batch(
                            np.atleast_2d(Q)), np.full(len(np.atleast_2d(Q)), 10.0)))
    monkeypatch.setattr(fast, "min_clearance_along", lambda path, max_step=0.01: 1.0)
    monkeypatch.setattr(fast, "keeps_clearance", lambda *a, **k: True)


def test_a_transfer_is_certified_without_a_repair_when_the_fast_model_is_right(cell):
    ur5, planner, q_s, q_g = cell
    res = planner.plan_transfer(q_s, q_g, label="round the post")
    assert res.ok, res.report.reason
    assert not any("exact checks only" in n for n in res.report.notes)
    assert _truly_free(planner, res.piece.dense())


def test_a_wrong_fast_model_is_caught_by_the_certificate_and_the_transfer_repaired(
        cell, monkeypatch):
    ur5, planner, q_s, q_g = cell
    # the straight joint move sweeps the arm through the post (brute-force FCL)
    f = np.linspace(0.0, 1.0, 41)[:, None]
    assert not _truly_free(planner, q_s + f * (q_g - q_s))
    _wrong_everywhere(monkeypatch, planner.checker.fast)
    # the prefiltered checks believe the fast model: the straight move looks free
    assert planner.checker.check_path(np.array([q_s, q_g])) is None
    assert planner.checker.exact_only().check_path(np.array([q_s, q_g])) is not None
    res = planner.plan_transfer(q_s, q_g, label="round the post")
    assert res.ok, res.report.reason
    notes = " ".join(res.report.notes)
    assert "planned again with exact checks only" in notes and "refuses" in notes, notes
    assert _truly_free(planner, res.piece.dense())
    # and the planner's checks are its own again after the repair
    assert planner.checker.fast is not None and planner.screen.checker is planner.checker.fast
