"""The sampled joint-position store: any arm at its own limits, within a memory budget."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import Obstacle
from assistant.roadmap.planner import RoadmapPlanner
from assistant.robots.catalog import installed_robot_urdf
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.robots.urdf_robot import URDFRobot
from assistant.world.joint_samples import SampledTable, build_samples
from assistant.world.leaf_store import WorldBudgetError
from assistant.world.model import WorldConfig, WorldModel
from assistant.world.reachability import (
    ReachabilityConfig,
    joint_reach_radii,
    load_or_build,
    store_kind,
)

UR5 = "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"
#: Small budgets: the contract, not the density, is under test (~2 s a build).
SMALL = ReachabilityConfig(samples=1 << 15, focus_samples=1 << 14)


@pytest.fixture(scope="module")
def ur5() -> URDFRobot:
    path, share = installed_robot_urdf(UR5)
    return URDFRobot.from_file(path, package_dirs=[share], tool_link="tool0")


@pytest.fixture(scope="module")
def store(ur5) -> SampledTable:
    grid = WorldConfig.for_robot(ur5).grid()
    return build_samples(ur5, grid, SMALL, joint_reach_radii(ur5))


def test_auto_keeps_the_thesis_grid_for_the_rv2aj_and_samples_a_ur5_at_its_own_limits(
        rv2aj, ur5):
    cfg = ReachabilityConfig()
    assert store_kind(rv2aj, joint_reach_radii(rv2aj), cfg) == "grid"
    assert np.degrees(ur5.limits.upper[0]) == pytest.approx(360.0)  # the URDF's own limits
    assert store_kind(ur5, joint_reach_radii(ur5), cfg) == "samples"


def test_the_octree_holds_the_whole_arm_reach(ur5, rv2aj):
    cfg = WorldConfig.for_robot(ur5)
    assert cfg.size >= 2.0 * 1.0 and cfg.grid().n == 32  # the UR5 reaches ~1.04 m with tool0
    thesis = WorldConfig.for_robot(rv2aj)
    assert (thesis.size, thesis.grid().leaf, thesis.reach.d_step) == (2.0, 0.0625, 0.03125)


def test_every_position_is_binned_in_the_leaf_of_its_tcp(ur5, store):
    ids = store.positions
    Q = store.joints(ids)
    assert ur5.limits.contains_batch(Q).all()
    # the same FK on the same numbers as the build: the same leaf, exactly
    leaf = store.grid.flat_of_points(ur5.batch_fk(Q).positions)
    assert np.array_equal(leaf, store.leaf_of_positions())
    assert np.all(np.diff(store.leaves) > 0) and store.offsets[-1] == len(ids)


def test_samples_sharing_their_first_joints_share_a_prefix(store):
    ids = store.positions[:5000]
    for n_joints in (1, 2, 3):
        key = store.prefixes(ids, n_joints)
        Q = store.prefix_configs(n_joints, key, np.zeros(store.dof))
        # the prefix decodes to the very joint values of the first n_joints (grid values)
        assert np.allclose(Q[:, :n_joints], store.joints(ids)[:, :n_joints], atol=1e-12)
        same = store.index[ids][:, :n_joints]
        _, inv = np.unique(same, axis=0, return_inverse=True)
        _, inv_key = np.unique(key, return_inverse=True)
        assert len(np.unique(inv)) == len(np.unique(inv_key))


def test_ids_in_a_box_are_exactly_those_within_the_steps(store):
    # a stored position, and postures between grid values (the sorted search's range
    # ends are then not grid values): the ids a scan of every id finds, ascending
    rng = np.random.default_rng(8)
    I = store.index.astype(float)
    varying = store.counts > 1
    for k, half in ((100, 1.5), (2000, 0.0), (40000, 3.0)):
        q = store.joints(store.positions[[k]])[0]
        if half == 3.0:
            q = q + rng.uniform(-0.5, 0.5, store.dof) * store.step
        got = store.ids_in_box(q, half)
        x = (q - store.lower) / np.where(varying, store.step, 1.0)
        # in grid steps, as the store counts them (the comparison is exact on integers
        # and the tolerance only decides the boundary of a box drawn on grid values)
        inside = np.all(np.abs(I - x)[:, varying] <= half + 1e-9, axis=1)
        assert np.array_equal(got, np.flatnonzero(inside)) and len(got) >= 1


def test_focus_adds_samples_and_leaves_list_them_nearest_to_the_anchors_first(ur5, store):
    anchors = np.radians([[-65.7, -89.8, 87.2, -87.3, -90, 0], [40.5, -89.8, 87.2, -87.3, -90, 0]])
    w = ur5.arm_radii()
    more = store.focused(ur5, anchors, 1 << 14, 0.8).toward(anchors, w)
    assert more.id_space > store.id_space and more.n_positions > store.n_positions
    for s in range(0, len(more.leaves), max(1, len(more.leaves) // 50)):
        Q = more.joints(more.positions[more.offsets[s]:more.offsets[s + 1]])
        d = np.min([np.linalg.norm((Q - a) * w, axis=1) for a in anchors], axis=0)
        assert np.all(np.diff(d) >= -1e-9)


def test_a_budget_beyond_the_memory_setting_is_refused_before_allocating(ur5, tmp_path):
    grid = WorldConfig.for_robot(ur5).grid()
    huge = ReachabilityConfig(samples=50_000_000, memory_mb=256)
    with pytest.raises(WorldBudgetError, match="memory_mb") as err:
        load_or_build(ur5, grid, huge, cache=tmp_path)
    assert "joint_samples" in str(err.value)
    # the thesis' full grid of a UR5 at +-360 deg: refused with the settings to change
    with pytest.raises(WorldBudgetError, match="store"):
        load_or_build(ur5, grid, ReachabilityConfig(store="grid"), cache=tmp_path)
    assert not list(tmp_path.rglob("*.npz"))  # nothing half-written


def test_the_sampled_store_is_cached_and_reloaded(ur5, tmp_path):
    grid = WorldConfig.for_robot(ur5).grid()
    a = load_or_build(ur5, grid, SMALL, cache=tmp_path)
    b = load_or_build(ur5, grid, SMALL, cache=tmp_path)
    assert a.kind == b.kind == "samples" and a.key == b.key
    assert np.array_equal(a.positions, b.positions) and np.array_equal(a.index, b.index)


def _box(name: str, centre, size) -> Obstacle:
    T = np.eye(4)
    T[:3, 3] = centre
    return Obstacle(name, T, (CollisionShape(ShapeKind.BOX, tuple(size)),))


def test_a_ur5_at_its_own_limits_plans_round_a_post_and_answers_a_free_move_directly(ur5):
    obstacles = [_box("table", (0.2, 0.0, -0.011), (1.2, 1.2, 0.02)),
                 _box("post", (0.45, 0.0, 0.3), (0.08, 0.08, 0.6))]
    cfg = WorldConfig.for_robot(ur5, reach=ReachabilityConfig(samples=1 << 17,
                                                              focus_samples=1 << 17),
                                use_cache=False)
    world = WorldModel(ur5, obstacles, cfg)
    q_s = np.radians([-40.0, -100.0, 100.0, -90.0, -90.0, 0.0])
    q_g = np.radians([40.0, -100.0, 100.0, -90.0, -90.0, 0.0])
    world.anchors = np.array([q_s, q_g])
    checker = CollisionChecker(ur5, obstacles)
    planner = RoadmapPlanner(ur5, checker, world)
    planner.build()
    assert world.table is not None and world.table.kind == "samples"
    assert checker.is_valid(q_s) and checker.is_valid(q_g)
    # the straight joint move sweeps the arm through the post: planned round it
    assert checker.check_path(np.array([q_s, q_g])) is not None
    plan = planner.plan(q_s, q_g)
    assert plan.ok, plan.reason
    assert plan.searched != "direct" and checker.check_path(plan.joint_path) is None
    # a long move in free space: one motion check, the straight joint move itself
    q_up = np.radians([-40.0, -90.0, 30.0, -90.0, -90.0, 0.0])
    q_far = np.radians([-120.0, -90.0, 30.0, -90.0, -90.0, 0.0])
    assert checker.check_path(np.array([q_up, q_far])) is None
    direct = planner.plan(q_up, q_far)
    assert direct.ok and direct.searched == "direct" and len(direct.joint_path) == 2
