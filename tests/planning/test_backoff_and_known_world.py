"""Back-off geometry on hand-made joint paths, and the known-world checks (recorded collision
postures refused by the net's validity and the verifier, the start's box exempt)."""

from __future__ import annotations

import numpy as np
import pytest
from planning_fixtures import make_planner

from assistant.planning.backoff import path_travel, retreat_index, splice
from assistant.planning.known_world import KnownValidity, KnownVerifier, WorldAllowed
from assistant.planning.scenario import load_scenario

RADII = np.array([0.5, 0.4, 0.2, 0.1, 0.05])


def line(a, b, n):
    return np.asarray(a, float) + np.linspace(0, 1, n)[:, None] * (np.asarray(b, float)
                                                                   - np.asarray(a, float))


def test_splice_backs_off_to_the_last_shared_posture():
    a, m, stop = [0, 0, 0, 0, 0], [0.4, 0, 0, 0, 0], [0.8, 0, 0, 0, 0]
    executed = line(a, stop, 41)
    # the new plan retraces to m, then turns away in J2
    new = np.concatenate([line(stop, m, 21), line(m, [0.4, 0.5, 0, 0, 0], 26)[1:]])
    sp = splice(executed, new, RADII, tolerance=0.005)
    assert sp.backs_off
    assert np.allclose(sp.backoff[0], stop) and np.allclose(sp.backoff[-1], m)
    assert np.allclose(sp.continuation[0], m) and np.allclose(sp.continuation[-1], new[-1])
    # the back-off is the executed path reversed: the same postures, in reverse
    assert np.allclose(sp.backoff, executed[20:][::-1])
    whole = sp.path()
    assert np.allclose(whole[0], stop) and np.allclose(whole[-1], new[-1])
    assert path_travel(RADII, whole) <= path_travel(RADII, new) + 0.005


def test_splice_without_shared_postures_continues_directly():
    executed = line([0, 0, 0, 0, 0], [0.8, 0, 0, 0, 0], 41)
    new = line([0.8, 0, 0, 0, 0], [0.8, 0.6, 0, 0, 0], 30)  # turns away at once
    sp = splice(executed, new, RADII)
    assert not sp.backs_off and np.array_equal(sp.path(), new)
    assert sp.executed_index == -1


def test_retreat_index_is_the_last_posture_before_the_blocked_tail():
    assert retreat_index(np.zeros((6, 5)), [False, False, True, False, True, True]) == 3
    assert retreat_index(np.zeros((3, 5)), [True, True, True]) == 0
    assert retreat_index(np.zeros((3, 5)), [False, False, False]) == 2


@pytest.fixture(scope="module")
def planner():
    sc = load_scenario()
    return make_planner(sc.cell.robot(), sc.known_obstacles())


def test_recorded_collisions_are_refused_except_where_the_path_starts(planner):
    robot, world = planner.robot, planner.world
    q_a = np.radians([-40.0, 30.0, 60.0, 0.0, 0.0])
    q_hit = np.radians([0.0, 30.0, 60.0, 0.0, 0.0])
    q_b = np.radians([40.0, 30.0, 60.0, 0.0, 0.0])
    path = list(line(q_a, q_b, 81))
    verifier = KnownVerifier(planner.checker, world)
    assert verifier.check_path(path) is None
    allowed = WorldAllowed(world)
    assert allowed(robot.fk(q_hit)[:3, 3][None])[0]
    planner.roadmap.add_collision(q_hit)
    allowed.refresh()
    assert not allowed(robot.fk(q_hit)[:3, 3][None])[0]  # its leaf is occupied now
    hit = verifier.check_path(path)
    assert hit is not None
    seg, mc = hit
    assert 30 <= seg <= 40 and "recorded collision 1" in mc.report.describe()
    # a path that starts in the box may leave it; one that ends in it may not
    out = list(line(q_hit, q_b, 41))
    assert verifier.check_path(out) is None
    assert verifier.check_path(out[::-1]) is not None
    validity = KnownValidity(planner.checker, world)
    assert not validity.is_valid(q_hit) and validity.is_valid(q_a)
    exempt = KnownValidity(planner.checker, world, world.recorded_collisions_at(q_hit))
    assert exempt.is_valid(q_hit)
    # the motion enters the posture box (half-width joint_steps grid steps in J1) first;
    # samples are half a grid step apart
    half = world.config.indication.joint_steps * world.table.step[0]
    span = q_b[0] - q_a[0]
    entry = 0.5 - half / span
    f = validity.first_invalid_fraction(q_a, q_b)
    assert entry <= f <= entry + 0.5 * world.table.step[0] / span + 1e-9
