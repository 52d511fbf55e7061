"""The joint-space RRT-Connect fallback and the re-plan's retreat rules (issue 32).

A toy joint space (2 joints, a wall with one gap) stands in for the arm: the search and its
shortcut are about joint vectors and a motion check, not about the robot. Every assertion is
about what holds whatever the random draws: each returned edge passed the check, the ends
are the query's, a blocked query returns None within its budgets, equal seeds equal paths.
"""

from __future__ import annotations

import numpy as np
import pytest

from assistant.planning.backoff import leads_on, retreat_candidates
from assistant.planning.joint_rrt import RRTParams, rrt_connect

LO, HI = np.array([-1.0, -1.0]), np.array([1.0, 1.0])
W = np.ones(2)


def wall_free(gap: tuple[float, float] | None):
    """Motion check: a wall at x = 0 from y = -1 to 1, open on `gap` (None: closed)."""
    calls = []

    def free(a, b):
        calls.append(1)
        a, b = np.asarray(a), np.asarray(b)
        n = max(2, int(np.ceil(np.abs(b - a).max() / 0.005)) + 1)
        P = a + np.linspace(0, 1, n)[:, None] * (b - a)
        near = np.abs(P[:, 0]) < 0.05
        if gap is not None:
            near &= ~((P[:, 1] > gap[0]) & (P[:, 1] < gap[1]))
        return not near.any()

    return free, calls


def test_a_straight_free_move_is_the_answer_at_once():
    free, calls = wall_free((-2.0, 2.0))  # no wall at all
    res = rrt_connect([-0.5, 0.0], [0.5, 0.0], LO, HI, free, W)
    assert res.found and len(res.path) == 2 and res.checks == 1 and len(calls) == 1


def test_the_path_goes_through_the_gap_and_every_edge_is_free():
    free, _ = wall_free((0.6, 0.8))
    res = rrt_connect([-0.5, -0.5], [0.5, -0.5], LO, HI, free, W, RRTParams(seed=3))
    assert res.found
    P = np.array(res.path)
    assert np.array_equal(P[0], [-0.5, -0.5]) and np.array_equal(P[-1], [0.5, -0.5])
    assert all(free(a, b) for a, b in zip(P[:-1], P[1:], strict=True))
    crossing = [(a, b) for a, b in zip(P[:-1], P[1:], strict=True) if a[0] * b[0] < 0]
    assert crossing, "the path crosses the wall"
    for a, b in crossing:  # where it crosses x = 0, it is in the gap
        y = a[1] + (b[1] - a[1]) * (-a[0]) / (b[0] - a[0])
        assert 0.6 < y < 0.8
    # shortcut: far fewer vertices than tree steps of 0.12 over the ~2.6 it travels
    assert len(P) <= 6


def test_equal_seeds_give_equal_paths_and_other_seeds_still_succeed():
    free, _ = wall_free((0.6, 0.8))
    a = rrt_connect([-0.5, -0.5], [0.5, -0.5], LO, HI, free, W, RRTParams(seed=7))
    b = rrt_connect([-0.5, -0.5], [0.5, -0.5], LO, HI, free, W, RRTParams(seed=7))
    assert a.found and b.found and len(a.path) == len(b.path)
    assert all(np.array_equal(x, y) for x, y in zip(a.path, b.path, strict=True))
    assert all(rrt_connect([-0.5, -0.5], [0.5, -0.5], LO, HI, free, W,
                           RRTParams(seed=s)).found for s in range(5))


def test_a_closed_wall_returns_none_within_the_check_budget():
    free, calls = wall_free(None)
    res = rrt_connect([-0.5, 0.0], [0.5, 0.0], LO, HI, free, W,
                      RRTParams(max_samples=300, max_checks=500))
    assert not res.found and res.path is None
    assert res.checks == len(calls) <= 500 + 1  # the last connect may finish its step
    assert res.samples <= 300


# ------------------------------------------------------------------ retreat rules
def test_retreat_candidates_go_back_by_arm_travel_then_to_the_drive_start():
    E = np.stack([np.linspace(0, 1, 101), np.zeros(101)], axis=1)  # 0.01 travel per step
    radii = np.array([1.0, 1.0])
    assert retreat_candidates(E, 80, radii) == [80, 75, 65, 0]
    assert retreat_candidates(E, 3, radii) == [3, 0]
    assert retreat_candidates(E, 0, radii) == [0]


def test_a_replan_that_sets_off_into_the_contact_leads_on():
    E = np.stack([np.linspace(0, 0.5, 11), np.zeros(11)], axis=1)  # driving +x, stopped
    radii = np.ones(2)
    stop = E[-1]
    onwards = np.array([stop, stop + [0.1, 0.02], stop + [0.2, 0.1]])
    back = np.array([stop, stop - [0.1, 0.0], stop + [-0.1, 0.3]])
    sideways = np.array([stop, stop + [0.02, 0.2]])
    assert leads_on(E, onwards, radii)
    assert not leads_on(E, back, radii)
    assert not leads_on(E, sideways, radii)
    assert not leads_on(E[-1:], onwards, radii)  # no drive direction known: not refused


def test_the_segment_box_test_is_exact_where_samples_miss_a_corner():
    """`WorldModel.segment_meets_recorded_collision` against a fine sampling of random
    segments through random boxes (3 joints, one the table does not vary)."""
    from types import SimpleNamespace

    from assistant.world.model import RecordedCollision, WorldModel

    rng = np.random.default_rng(5)
    table = SimpleNamespace(counts=np.array([9, 9, 1]), step=np.array([0.1, 0.2, 0.3]))
    box_q = np.array([0.0, 0.0, 5.0])
    world = SimpleNamespace(
        table=table, config=SimpleNamespace(indication=SimpleNamespace(joint_steps=1.5)),
        collisions=[RecordedCollision(box_q, np.zeros(0, dtype=np.int64))])
    half = np.array([0.15, 0.3])
    agree = hits = 0
    for _ in range(400):
        a, b = rng.uniform(-0.6, 0.6, 3), rng.uniform(-0.6, 0.6, 3)
        t = np.linspace(0.0, 1.0, 20001)[:, None]
        P = a + t * (b - a)
        sampled = bool(np.all(np.abs(P[:, :2] - box_q[:2]) <= half - 1e-6, axis=1).any())
        exact = WorldModel.segment_meets_recorded_collision(world, a, b)
        strictly_out = not np.all(np.abs(P[:, :2] - box_q[:2]) <= half + 1e-6, axis=1).any()
        assert exact or not sampled, (a, b)
        assert not exact or not strictly_out, (a, b)
        agree += 1
        hits += exact
    assert agree == 400 and 40 < hits < 360  # both answers occur
    assert not WorldModel.segment_meets_recorded_collision(world, [0.0, 0.0, 0.0],
                                                           [0.0, 0.0, 0.0], frozenset({0}))


def test_the_progress_callback_sees_the_budget_and_can_cancel():
    from assistant.progress import Cancelled, Progress

    free, _ = wall_free(None)
    seen = []
    res = rrt_connect([-0.5, 0.0], [0.5, 0.0], LO, HI, free, W,
                      RRTParams(max_samples=50, max_checks=100), seen.append)
    assert not res.found and len(seen) == res.samples
    assert seen == sorted(seen) and 0.0 <= seen[0] and seen[-1] < 1.0
    p = Progress("search")
    p.cancel()
    with pytest.raises(Cancelled):
        rrt_connect([-0.5, 0.0], [0.5, 0.0], LO, HI, free, W, None,
                    lambda f: p.update(f, "searching"))
