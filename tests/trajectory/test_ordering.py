"""Mission ordering: exact equals brute force, the heuristic stays close, lazy measuring."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from assistant.mission.model import (
    ApplicationPath,
    Location,
    PathSegment,
    ResolvedMission,
    SegmentKind,
)
from assistant.trajectory.ordering import (
    Endpoint,
    JointDistance,
    OrderingParams,
    PathEnds,
    order_mission,
    order_paths,
    tcp_distance,
)
from assistant.transforms import make_T


def _instance(rng, n, p_reversible=0.6):
    paths = [PathEnds(Endpoint(rng.uniform(-0.4, 0.4, 3)), Endpoint(rng.uniform(-0.4, 0.4, 3)),
                      bool(rng.random() < p_reversible)) for _ in range(n)]
    return paths, Endpoint(rng.uniform(-0.4, 0.4, 3)), Endpoint(rng.uniform(-0.4, 0.4, 3))


def _tour_cost(paths, start, goal, order, rev, cost=tcp_distance):
    here, total = start, 0.0
    for i, r in zip(order, rev, strict=True):
        a, b = (paths[i].end, paths[i].start) if r else (paths[i].start, paths[i].end)
        if here is not None:
            total += cost(here, a)
        here = b
    return total + (cost(here, goal) if goal is not None else 0.0)


def _brute_force(paths, start, goal, cost=tcp_distance):
    """Independent reference: every order and every allowed direction."""
    best = np.inf
    for perm in itertools.permutations(range(len(paths))):
        options = [(False, True) if paths[i].reversible else (False,) for i in perm]
        for rev in itertools.product(*options):
            best = min(best, _tour_cost(paths, start, goal, perm, rev, cost))
    return best


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 6])
def test_exact_equals_brute_force(n, rng):
    for _ in range(4):
        paths, start, goal = _instance(rng, n)
        o = order_paths(paths, start, goal)
        assert o.exact and o.method == "held-karp"
        assert sorted(o.order) == list(range(n))
        assert o.cost == pytest.approx(_brute_force(paths, start, goal), abs=1e-12)
        assert o.cost == pytest.approx(_tour_cost(paths, start, goal, o.order, o.reversed))
        assert sum(o.transfer_costs) == pytest.approx(o.cost)


def test_one_way_paths_are_never_reversed(rng):
    paths, start, goal = _instance(rng, 6, p_reversible=0.0)
    o = order_paths(paths, start, goal)
    assert not any(o.reversed)
    assert o.cost == pytest.approx(_brute_force(paths, start, goal))


def test_open_ends_without_start_or_goal(rng):
    paths, _, _ = _instance(rng, 5)
    o = order_paths(paths, None, None)
    assert o.cost == pytest.approx(_brute_force(paths, None, None))


def test_heuristic_gap_on_random_instances(rng):
    gaps = []
    for _ in range(12):
        paths, start, goal = _instance(rng, 8)
        exact = order_paths(paths, start, goal)
        heur = order_paths(paths, start, goal, params=OrderingParams(exact_limit=0))
        assert not heur.exact and sorted(heur.order) == list(range(8))
        assert heur.cost == pytest.approx(_tour_cost(paths, start, goal, heur.order,
                                                     heur.reversed))
        gaps.append(heur.cost / exact.cost - 1.0)
    assert min(gaps) >= -1e-12  # nothing beats the exact solution
    assert np.mean(gaps) < 0.01 and max(gaps) < 0.05


def test_heuristic_on_a_larger_mission_beats_nearest_neighbour_alone(rng):
    paths, start, goal = _instance(rng, 14)
    heur = order_paths(paths, start, goal)
    assert heur.method == "nn+2opt+oropt"
    assert sorted(heur.order) == list(range(14))
    # Greedy nearest neighbour from the start, for comparison.
    left, here, nn = set(range(14)), start, 0.0
    while left:
        i, r = min(((i, r) for i in left for r in ((False, True) if paths[i].reversible
                                                   else (False,))),
                   key=lambda ir: tcp_distance(here, paths[ir[0]].end if ir[1]
                                               else paths[ir[0]].start))
        a, b = (paths[i].end, paths[i].start) if r else (paths[i].start, paths[i].end)
        nn += tcp_distance(here, a)
        here = b
        left.remove(i)
    nn += tcp_distance(here, goal)
    assert heur.cost < nn


def test_measured_costs_are_used_lazily_and_the_result_is_optimal(rng):
    """Planned transfers are longer than straight lines (detours around obstacles): the lazy
    loop measures only what the current best order uses and ends optimal for the measured
    costs, which brute force over the fully measured costs confirms."""
    paths, start, goal = _instance(rng, 6)
    detour = {}
    calls = []

    def measure(a: Endpoint, b: Endpoint) -> float:
        key = (tuple(a.position), tuple(b.position))
        calls.append(key)
        if key not in detour:
            detour[key] = 1.0 + 2.0 * float(rng.random() < 0.4)  # some transfers x3
        return tcp_distance(a, b) * detour[key]

    o = order_paths(paths, start, goal, measure=measure)
    assert o.all_measured and o.rounds >= 1
    assert o.measured == len(calls) < 4 * 6 * 6
    # Reference: every transfer measured (same detour factors).
    assert o.cost == pytest.approx(_brute_force(paths, start, goal, measure), rel=1e-12)
    estimated = order_paths(paths, start, goal)
    assert o.cost >= estimated.cost - 1e-12


def test_joint_distance_estimate_uses_configurations():
    est = JointDistance(np.array([1.0, 2.0]))
    a = Endpoint(np.zeros(3), np.array([0.0, 0.0]))
    b = Endpoint(np.ones(3), np.array([0.5, -0.25]))
    assert est(a, b) == pytest.approx(1.0)
    assert est(a, Endpoint(np.ones(3))) == pytest.approx(np.sqrt(3.0))


def test_order_mission_from_taught_locations():
    def line(name, a, b, reversible=False):
        return ApplicationPath(name, [PathSegment(SegmentKind.LINE,
                                                  (np.array(a, float), np.array(b, float)))],
                               reversible=reversible)

    mission = ResolvedMission(
        Location("home", make_T(p=[0.0, 0.0, 0.0])),
        Location("goal", make_T(p=[1.0, 0.0, 0.0])),
        [line("far", [0.8, 0, 0], [0.9, 0, 0]), line("near", [0.2, 0, 0], [0.1, 0, 0], True),
         line("mid", [0.5, 0, 0], [0.6, 0, 0])],
    )
    o = order_mission(mission)
    assert o.order == [1, 2, 0]
    assert o.reversed == [True, False, False]
    assert o.cost == pytest.approx(0.1 + 0.3 + 0.2 + 0.1)
