"""RoadmapPlanner on the thesis-like cell with the real FCL checker: plans, failure reasons,
operator indications with a local roadmap update."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import Obstacle
from assistant.progress import Cancelled, Progress
from assistant.roadmap.astar import SearchBudget
from assistant.roadmap.planner import PlanFailure, RoadmapConfig, RoadmapPlanner
from assistant.roadmap.voronoi import build_voronoi
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.transforms import make_T, rot_z
from assistant.world.fusion import Source
from assistant.world.model import WorldConfig, WorldModel
from assistant.world.reachability import ReachabilityConfig

Q_START = np.radians([-60.0, 30.0, 60.0, 0.0, 0.0])
Q_GOAL = np.radians([60.0, 30.0, 60.0, 0.0, 0.0])


def thesis_like() -> list[Obstacle]:
    def box(name, c, s):
        return Obstacle(name, make_T(p=c), (CollisionShape(ShapeKind.BOX, tuple(s)),))

    return [box("O1", [0.28, -0.12, 0.10], [0.10, 0.12, 0.20]),
            box("O2", [0.22, 0.18, 0.06], [0.16, 0.08, 0.12]),
            box("table", [0.0, 0.0, -0.011], [1.5, 1.5, 0.02])]


def make_planner(rv2aj, config: RoadmapConfig | None = None) -> RoadmapPlanner:
    """A coarse world (125 mm leaves, 62.5 mm joint steps) keeps the build under a second."""
    obs = thesis_like()
    cfg = WorldConfig(leaf=0.125, reach=ReachabilityConfig(d_step=0.0625), use_cache=False)
    planner = RoadmapPlanner(rv2aj, CollisionChecker(rv2aj, obs), WorldModel(rv2aj, obs, cfg),
                             config)
    planner.build()
    return planner


@pytest.fixture(scope="module")
def planner(rv2aj) -> RoadmapPlanner:
    return make_planner(rv2aj)


def test_thesis_query_gives_a_collision_free_joint_path(planner, rv2aj):
    plan = planner.plan(Q_START, Q_GOAL)
    assert plan.ok and plan.failure is None and plan.reason == "found"
    assert plan.searched in ("roads", "free cells")
    path = plan.joint_path
    assert np.allclose(path[0], Q_START) and np.allclose(path[-1], Q_GOAL)
    assert len(path) >= 3 and plan.expansions > 0 and plan.edge_checks >= len(path) - 1
    # exact continuous FCL check of every segment, and joint limits
    assert planner.checker.check_path(path) is None
    assert all(rv2aj.limits.contains(q) for q in path)
    # cells are the TCP leaves of the nodes; interior nodes sit in free leaves
    w = planner.world
    assert plan.cells[0] == tuple(w.grid.ijk_of_flat([w.tcp_cell(Q_START)])[0])
    free = w.free()
    assert all(free[c] for c in plan.cells[1:-1])


def test_batched_edge_check_answers_as_one_check_per_edge(planner, rv2aj):
    """The search's batched edge check (`EdgeCheck.first_invalid_fractions`) against the
    checker's own motion check edge by edge: free edges, edges into the parts (the first
    invalid fraction), an edge of one step, one batch of a single edge; and its samples
    are laid out edge after edge, k / n of the way."""
    from assistant.roadmap.edge_samples import edge_samples

    rng = np.random.default_rng(11)
    lo, hi = rv2aj.limits.lower, rv2aj.limits.upper
    # from around the start to around the goal (across the parts), or down to the table
    Q0 = np.clip(Q_START + rng.normal(0.0, 0.1, (40, 5)), lo, hi)
    Q1 = np.clip(Q_GOAL + rng.normal(0.0, 0.3, (40, 5)), lo, hi)
    Q1[::3, 1] = rng.uniform(1.2, 1.8, len(Q1[::3]))
    Q1[0] = Q0[0] + 1e-4  # one step
    edge = planner._edge
    got = edge.first_invalid_fractions(Q0, Q1)
    want = [planner.checker.first_invalid_fraction(a, b) for a, b in zip(Q0, Q1, strict=True)]
    # The same edges invalid (None: free), at the same sample k of n: its fraction k / n
    # from the batch's samples or the checker's, within a few ULPs of a number in [0, 1].
    assert [f is None for f in got] == [f is None for f in want]
    assert [f for f in got if f is not None] == pytest.approx(
        [f for f in want if f is not None], rel=0, abs=1e-15)
    assert 3 <= sum(f is not None for f in want) <= 35  # both kinds of edges
    one = edge.first_invalid_fractions(Q0[3:4], Q1[3:4])
    assert [f is None for f in one] == [want[3] is None]
    assert one[0] is None or one[0] == pytest.approx(want[3], rel=0, abs=1e-15)
    ns = planner.checker.motion_samples_between(Q0, Q1)
    Q, at, F = edge_samples(Q0, Q1, ns)
    ref_edge = [i for i, n in enumerate(ns) for _ in range(n + 1)]
    ref_F = [k / n for n in ns for k in range(n + 1)]
    assert at.tolist() == ref_edge  # edge indices: integers
    # 1e-15: k / n (one division); 1e-14 rad: a + f (b - a) on joints of a few rad - a
    # few ULPs either way
    np.testing.assert_allclose(F, ref_F, rtol=0, atol=1e-15)
    ref_Q = [Q0[i] + f * (Q1[i] - Q0[i]) for i, f in zip(ref_edge, ref_F, strict=True)]
    np.testing.assert_allclose(Q, ref_Q, rtol=0, atol=1e-14)


def test_checking_at_every_pop_plans_over_the_same_graph(rv2aj):
    """With no path-first rounds the planner's lazy A* (`astar.lazy_astar`, its expansion
    over the graph's extra nodes) plans the thesis query: a collision-free path from the
    start to the goal."""
    planner = make_planner(rv2aj, RoadmapConfig(budget=SearchBudget(path_rounds=0)))
    plan = planner.plan(Q_START, Q_GOAL)
    assert plan.ok, plan.reason
    assert np.array_equal(plan.joint_path[0], Q_START)
    assert np.array_equal(plan.joint_path[-1], Q_GOAL)
    assert len(plan.joint_path) >= 3 and plan.expansions > 0
    assert planner.checker.check_path(plan.joint_path) is None


def test_j6_is_interpolated_between_start_and_goal(planner):
    # the table fixes J6 (it cannot move a straight tool); the path must not jump to that
    # value but turn J6 smoothly from the start's to the goal's
    qs, qg = Q_START.copy(), Q_GOAL.copy()
    qs[4], qg[4] = 0.6, -0.4
    plan = planner.plan(qs, qg)
    assert plan.ok
    j6 = np.array([q[4] for q in plan.joint_path])
    assert j6[0] == pytest.approx(0.6) and j6[-1] == pytest.approx(-0.4)
    assert np.all(np.diff(j6) <= 1e-12) and len(set(np.round(j6, 9))) > 2
    assert planner.checker.check_path(plan.joint_path) is None


def test_free_joint_ramp_follows_the_weighted_length_of_the_others():
    """`free_joints.ramp_free_joints` against its definition, row by row: random paths and
    weights, one or two free joints, a path whose other joints stand still (even
    fractions); the other joints are left as they are."""
    from assistant.roadmap.free_joints import ramp_free_joints

    def reference(P, free, weights):
        P = P.copy()
        s = [0.0]
        for a, b in zip(P[:-1], P[1:], strict=True):
            s.append(s[-1] + sum((w * (y - x)) ** 2 for x, y, w, f
                                 in zip(a, b, weights, free, strict=True) if not f) ** 0.5)
        for i in range(len(P)):
            u = s[i] / s[-1] if s[-1] > 0 else i / (len(P) - 1)
            P[i, free] = P[0, free] + u * (P[-1, free] - P[0, free])
        return P

    rng = np.random.default_rng(8)
    for m in (3, 4, 9, 30):
        for free in (np.array([0, 0, 0, 0, 1], bool), np.array([0, 1, 0, 0, 1], bool)):
            P = rng.uniform(-2.0, 2.0, (m, 5))
            weights = rng.uniform(0.05, 0.5, 5)
            still = P.copy()
            still[:, ~free] = P[0, ~free]
            for path in (P, still):
                got = path.copy()
                ramp_free_joints(got, free, weights)
                # 1e-12 rad: joint ramps from a weighted length (a few products and a
                # division per row), summed in another order
                np.testing.assert_allclose(got, reference(path, free, weights), rtol=0,
                                           atol=1e-12)
                assert np.array_equal(got[:, ~free], path[:, ~free])


def test_goal_inside_an_obstacle_and_unreachable_goal_are_refused(planner, rv2aj):
    T = np.eye(4)
    T[:3, 3] = [0.28, -0.12, 0.15]  # inside O1
    q_in = rv2aj.ik(T, position_only=True).best()
    plan = planner.plan(Q_START, q_in)
    assert not plan.ok and plan.failure == PlanFailure.GOAL_IN_OBSTACLE
    assert "O1" in plan.reason
    q_far = Q_GOAL.copy()
    q_far[1] = np.radians(150.0)  # J2 beyond +120 deg
    plan = planner.plan(Q_START, q_far)
    assert plan.failure == PlanFailure.GOAL_UNREACHABLE and "J2" in plan.reason
    plan = planner.plan(q_in, Q_GOAL)
    assert plan.failure == PlanFailure.START_INVALID
    # values that are not numbers (a broken script or session file) are named as such
    plan = planner.plan(Q_START, np.full(len(Q_GOAL), np.nan))
    assert plan.failure == PlanFailure.GOAL_UNREACHABLE and "finite" in plan.reason
    assert planner.plan(np.full(len(Q_GOAL), np.inf), Q_GOAL).failure == \
        PlanFailure.START_INVALID


def test_budget_and_cancellation_end_the_search(rv2aj, planner):
    tight = make_planner(rv2aj, RoadmapConfig(budget=SearchBudget(max_expansions=2)))
    plan = tight.plan(Q_START, Q_GOAL)
    assert not plan.ok and plan.failure == PlanFailure.BUDGET
    assert plan.reason.startswith("budget exhausted")
    prog = Progress("plan")
    prog.cancel()
    with pytest.raises(Cancelled):
        planner.plan(Q_START, Q_GOAL, prog)


def _wall_in_goal(planner: RoadmapPlanner):
    """Sensor evidence fills the 26 leaves round Q_GOAL's TCP leaf; returns the update."""
    w = planner.world
    gc = w.tcp_cell(Q_GOAL)
    ijk = w.grid.ijk_of_flat([gc])[0]
    shell = np.array([ijk + [a, b, c] for a in (-1, 0, 1) for b in (-1, 0, 1)
                      for c in (-1, 0, 1) if (a, b, c) != (0, 0, 0)])
    return planner.observe(Source.SENSOR, w.grid.centres_of_ijk(shell), 1.0)


@pytest.mark.parametrize("fallback", [True, False])
def test_goal_walled_in_by_observations_is_in_another_free_region(rv2aj, fallback):
    """Said once the roads hold no path (with or without the free-cell searches after)."""
    planner = make_planner(rv2aj, RoadmapConfig(fallback_to_free_cells=fallback))
    upd = _wall_in_goal(planner)
    assert len(upd.world.occupancy_flipped) > 0
    assert planner.voronoi.same_as(build_voronoi(planner.labels.source,
                                                 planner.world.reachable()))
    plan = planner.plan(Q_START, Q_GOAL)
    assert not plan.ok and plan.failure == PlanFailure.NO_PATH_REGIONS
    assert plan.reason == "no path: start and goal are in different free regions"


def test_a_walled_in_goal_is_known_cut_off_without_searching_the_start_side(rv2aj):
    """The goal's flood (`astar_kernel`) runs out within the goal's own leaf: the search
    ends after at most one expansion per position there, where the A* alone closed every
    node the start's roads reach (3391 on this cell)."""
    planner = make_planner(rv2aj, RoadmapConfig(fallback_to_free_cells=False))
    _wall_in_goal(planner)
    cells, offsets, _ = planner.world.cell_positions_shared()
    i = np.searchsorted(cells, planner.world.tcp_cell(Q_GOAL))
    in_goal_leaf = int(offsets[i + 1] - offsets[i]) if cells[i] == \
        planner.world.tcp_cell(Q_GOAL) else 0
    plan = planner.plan(Q_START, Q_GOAL)
    assert not plan.ok and plan.failure == PlanFailure.NO_PATH_REGIONS
    assert plan.expansions <= in_goal_leaf + 1 < 100


def test_search_grids_follow_every_change_of_the_world(rv2aj):
    """The remembered squeeze and penalty grids of the searches (`_search_grids`) are those
    of the world as it is now: after sensor observations (a new occupancy grid) and after a
    collision indication (also a new selection of positions)."""
    planner = make_planner(rv2aj)
    w = planner.world

    def fresh():
        squeeze = (w.occupied() | (w.reachable() & ~w.has_valid())).reshape(-1)
        return (squeeze, planner.config.occupancy_penalty * w.occupancy().reshape(-1),
                w.free().reshape(-1), w.has_valid().reshape(-1))

    def same_as_fresh() -> bool:
        g = planner._search_grids()
        got = (g.squeeze, g.penalty, g.free, g.offers)
        return all(np.array_equal(a, b) for a, b in zip(got, fresh(), strict=True))

    assert same_as_fresh()
    before = planner._search_grids()
    cells = np.flatnonzero(w.free().reshape(-1))[:40]
    planner.observe(Source.SENSOR, w.grid.centres_of_ijk(w.grid.ijk_of_flat(cells)), 1.0)
    assert same_as_fresh() and not np.array_equal(before.penalty,
                                                  planner._search_grids().penalty)
    assert not np.array_equal(before.free, planner._search_grids().free)
    planner.add_collision(np.radians([0.0, 40.0, 70.0, 0.0, 0.0]))
    assert same_as_fresh()
    assert planner.plan(Q_START, Q_GOAL).ok


def test_collision_indication_updates_roads_locally_and_the_new_plan_avoids_it(rv2aj):
    planner = make_planner(rv2aj)
    before = planner.plan(Q_START, Q_GOAL)
    assert before.ok
    q_hit = before.joint_path[len(before.joint_path) // 2]
    upd = planner.add_collision(q_hit)
    w = planner.world
    hit_cell = w.tcp_cell(q_hit)
    assert hit_cell in upd.world.observed_cells.tolist()
    assert planner.labels.source.reshape(-1)[hit_cell] > 0
    assert not upd.rebuilt and len(upd.roadmap_changed) > 0
    # the local update equals a rebuild from the same sources
    assert planner.voronoi.same_as(build_voronoi(planner.labels.source, w.reachable()))
    after = planner.plan(Q_START, Q_GOAL)
    assert after.ok
    assert not w.near_recorded_collision(np.array(after.joint_path)).any()
    assert planner.checker.check_path(after.joint_path) is None
    assert hit_cell not in [w.grid.flat_of_ijk(np.array([c]))[0] for c in after.cells]
    # the robot, stopped at q_hit among the cells it just marked, can plan its way out
    out = planner.plan(q_hit, Q_GOAL)
    assert out.ok and np.allclose(out.joint_path[0], q_hit)
    assert planner.checker.check_path(out.joint_path) is None
    assert not w.near_recorded_collision(np.array(out.joint_path[1:])).any()


def test_cancelled_indication_leaves_world_and_roads_consistent(rv2aj):
    planner = make_planner(rv2aj)
    q = np.radians([30.0, 40.0, 50.0, 20.0, 0.0])
    prog = Progress("indication")
    prog.cancel()
    with pytest.raises(Cancelled):
        planner.add_collision(q, prog)
    w = planner.world
    # the evidence is kept, no invalidated posture is offered, the roads match the world
    assert len(w.collisions) == 1 and w.occupied().reshape(-1)[w.tcp_cell(q)]
    _, _, Q = w.cell_positions()
    assert not w.near_recorded_collision(Q).any()
    assert planner.voronoi.same_as(build_voronoi(planner.labels.source, w.reachable()))
    assert planner.labels.source.reshape(-1)[w.tcp_cell(q)] > 0
    assert planner.plan(Q_START, Q_GOAL).ok


def test_a_point_taught_on_a_part_is_a_valid_goal(planner, rv2aj):
    # TCP 2 mm above O2's top face, tool pointing down: the leaf is partly filled by O2
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T[:3, 3] = [0.22, 0.18, 0.122]
    q_on = rv2aj.ik(T).best(Q_GOAL)
    w = planner.world
    assert w.occupied().reshape(-1)[w.tcp_cell(q_on)]
    assert planner.checker.is_valid(q_on)
    plan = planner.plan(Q_START, q_on)
    assert plan.ok, plan.reason
    assert planner.checker.check_path(plan.joint_path) is None


def test_a_start_taught_between_the_table_and_a_part_is_left_diagonally(rv2aj, monkeypatch):
    """TCP 52 mm above the table, beside a box: the start cell's face neighbours are table and
    box, so every step out is a corner squeeze. A terminal the rule leaves without an edge is
    exempt from it (found as the generated benchmark cell 128, where OMPL found a path and we
    answered "no path")."""
    from assistant.roadmap import graph

    def box(name, c, yaw, s):
        return Obstacle(name, make_T(rot_z(yaw), np.array(c)),
                        (CollisionShape(ShapeKind.BOX, tuple(s)),))

    obs = [box("table", [0.0, 0.0, -0.01], 0.0, [1.2, 1.2, 0.02]),
           box("B1", [0.3004, -0.1332, 0.115], 2.8921, [0.0804, 0.048, 0.2301]),
           box("B2", [0.4129, 0.0277, 0.0802], 2.5749, [0.0813, 0.127, 0.1604])]
    q_s = np.array([-0.0936, 1.372, 1.6217, -0.483, 3.0333])
    q_g = np.array([1.1368, 1.4233, 0.9457, 0.2648, 1.7441])
    checker = CollisionChecker(rv2aj, obs)
    planner = RoadmapPlanner(rv2aj, checker, WorldModel(rv2aj, obs, WorldConfig()))
    planner.build()
    assert rv2aj.fk(q_s)[2, 3] < 0.06 and checker.is_valid(q_s)
    exempted = []
    over = graph.JointGraph.over  # how the planner makes its search graphs

    def spy(*a, **k):
        exempted.append(tuple(k.get("squeeze_exempt", ())))
        return over(*a, **k)

    monkeypatch.setattr(graph.JointGraph, "over", staticmethod(spy))
    plan = planner.plan(q_s, q_g)
    assert plan.ok, plan.reason
    assert checker.check_path(plan.joint_path) is None
    start_cell = planner.world.tcp_cell(q_s)
    assert exempted[:2] == [(), (start_cell,)]  # cut off, so exempt - the start cell only
    assert plan.searched == "roads" and plan.edge_checks < 100
    # Never lifting the rule, the start stays cut off.
    monkeypatch.setattr(graph.JointGraph, "over", staticmethod(
        lambda *a, **k: over(*a, **{**k, "squeeze_exempt": ()})))
    cut_off = planner.plan(q_s, q_g)
    assert not cut_off.ok and cut_off.failure == PlanFailure.NO_PATH


def test_search_masks_are_the_set_operations_on_the_grids():
    """The compiled query masks (`search_masks`) against the numpy set logic they replace:
    random label/free/offers/CAD grids, terminals inside and at the grid's faces and
    corners, escape radius 0 to 3."""
    from assistant.roadmap.search_masks import search_masks

    rng = np.random.default_rng(12)
    n = 12
    for trial in range(60):
        lab = rng.integers(-2, 6, n ** 3).astype(np.int32)
        free, offers, cad = (rng.random((3, n ** 3)) < [[0.5], [0.6], [0.3]])
        corner = [0, n - 1][trial % 2]
        sc = int(rng.integers(n ** 3)) if trial % 3 else (corner * n + corner) * n + corner
        gc = int(rng.integers(n ** 3))
        r, s_lab, g_lab = trial % 4, 4, 5
        escape = np.zeros((n, n, n), bool)
        for cell, only_cad in ((sc, False), (gc, True)):
            i, j, k = cell // (n * n), (cell // n) % n, cell % n
            box = np.zeros((n, n, n), bool)
            if r > 0:
                box[max(0, i - r):i + r + 1, max(0, j - r):j + r + 1,
                    max(0, k - r):k + r + 1] = True
            box = box.reshape(-1) & offers & (cad if only_cad else True)
            escape |= box.reshape(n, n, n)
        escape = escape.reshape(-1)
        want_free = free | escape
        want_free[[sc, gc]] = True
        roads = (lab == -1) | (lab == s_lab) | (lab == g_lab)
        want = (roads & want_free) | escape
        got, got_free = search_masks(lab, -1, s_lab, g_lab, free, offers, cad, n, sc, gc, r)
        assert np.array_equal(got, want) and np.array_equal(got_free, want_free)
        assert want.any() and not want.all()


def test_a_goal_in_a_leaf_an_indication_marked_is_judged_by_its_posture_box(rv2aj):
    """An indication marks every leaf the arm filled when it was stopped; the contact is in
    one of them, so a goal whose TCP lies in such a leaf is refused only if its posture is in
    the recorded posture box (as a CAD leaf is judged by the exact check). Another posture
    with its TCP in the same leaf, outside that box, is a valid goal."""
    planner = make_planner(rv2aj)
    q_hit = np.array(planner.plan(Q_START, Q_GOAL).joint_path)[5]
    planner.add_collision(q_hit)
    w = planner.world
    gc, sc = w.tcp_cell(q_hit), w.tcp_cell(Q_START)
    assert w.occupied().reshape(-1)[gc] and w.object_ids().reshape(-1)[gc] <= 0
    assert any(gc in rc.cells for rc in w.collisions)
    rng = np.random.default_rng(7)
    candidates = q_hit + rng.uniform(-0.6, 0.6, (4000, len(q_hit)))
    away = ~w.near_recorded_collision(candidates)
    q_other = next(q for q in candidates[away] if w.tcp_cell(q) == gc
                   and rv2aj.limits.contains(q) and planner.checker.is_valid(q))
    assert planner._check_terminals(Q_START, q_other, sc, gc) is None
    refused = planner._check_terminals(Q_START, q_hit, sc, gc)
    assert refused is not None and refused.failure == PlanFailure.GOAL_IN_OBSTACLE
    assert "recorded collision" in refused.reason
