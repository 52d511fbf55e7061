"""CAD rasterisation into leaves and validation of table joint positions, checked against FCL."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import Obstacle
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.transforms import make_T, rot_z
from assistant.world.cell_positions import INVALID_CAD, VALID
from assistant.world.chain_levels import ChainValidator, link_levels
from assistant.world.model import WorldConfig, WorldModel
from assistant.world.octree import OctreeGrid
from assistant.world.rasterise import obstacle_cells
from assistant.world.reachability import ReachabilityConfig


def box(name, centre, size, R=None) -> Obstacle:
    return Obstacle(name, make_T(R=R, p=centre), (CollisionShape(ShapeKind.BOX, tuple(size)),))


def thesis_like() -> list[Obstacle]:
    return [box("O1", [0.28, -0.12, 0.10], [0.10, 0.12, 0.20]),
            box("O2", [0.22, 0.18, 0.06], [0.16, 0.08, 0.12]),
            box("table", [0.0, 0.0, -0.011], [1.5, 1.5, 0.02])]


@pytest.fixture(scope="module")
def world(rv2aj) -> WorldModel:
    cfg = WorldConfig(leaf=0.125, reach=ReachabilityConfig(d_step=0.0625), use_cache=False)
    w = WorldModel(rv2aj, thesis_like(), cfg)
    w.build()
    return w


def test_axis_aligned_box_marks_exactly_the_leaves_it_overlaps():
    g = OctreeGrid.for_leaf(2.0, 0.0625)
    ob = box("b", [0.30, -0.10, 0.20], [0.10, 0.12, 0.20])
    cells = obstacle_cells(g, ob)
    lo, hi = np.array([0.25, -0.16, 0.10]), np.array([0.35, -0.04, 0.30])
    c = g.centres_of_ijk(g.ijk_of_flat(np.arange(g.n_cells)))
    h = g.leaf / 2
    overlap = np.all((c + h > lo) & (c - h < hi), axis=1)
    assert cells.tolist() == np.flatnonzero(overlap).tolist()


def test_slanted_box_marks_fewer_leaves_than_its_bounding_box():
    g = OctreeGrid.for_leaf(2.0, 0.0625)
    ob = box("slab", [0.2, 0.2, 0.3], [0.6, 0.02, 0.3], R=rot_z(np.pi / 4))
    cells = obstacle_cells(g, ob)
    # the slab's centre plane passes through these leaves' centres
    pts = np.array([[0.2 + t, 0.2 + t, z] for t in np.linspace(-0.15, 0.15, 7)
                    for z in (0.2, 0.3, 0.4)])
    assert set(g.flat_of_points(pts).tolist()) <= set(cells.tolist())
    lo, hi = (np.array([0.2, 0.2, 0.3]) + s * np.array([0.22, 0.22, 0.15]) for s in (-1, 1))
    aabb_cells = np.prod(np.ceil((hi - lo) / g.leaf) + 1)
    assert len(cells) < 0.5 * aabb_cells


def test_rv2aj_links_are_checked_at_the_joint_that_moves_them(rv2aj):
    # base 0; turret (capsule on the J1 axis) needs no joint; upper arm q1..q2; forearm
    # q1..q3; wrist ball (on the J5 axis) q1..q3; flange + straight tool (on J6) q1..q5
    assert link_levels(rv2aj) == [0, 0, 2, 3, 3, 4]


def test_cad_cells_are_occupied_and_owned(world):
    occ = world.occupied().reshape(-1)
    ids = world.object_ids().reshape(-1)
    for i, name in enumerate(world.object_names()):
        cells = world.cad_cells[name]
        assert len(cells) and occ[cells].all()
        assert np.all((ids[cells] == i + 1) | (ids[cells] > 0))
    assert occ.sum() == len(np.unique(np.concatenate(list(world.cad_cells.values()))))
    # the planner's flat CAD mask: the same leaves, remembered
    assert np.array_equal(world.cad_leaves(), ids > 0) and world.cad_leaves().any()
    assert world.cad_leaves() is world.cad_leaves()


def test_invalid_positions_really_collide_and_valid_ones_do_not(world, rv2aj, rng):
    table, pos = world.table, world.positions
    exact = CollisionChecker(rv2aj, world.cad)
    invalid = np.flatnonzero(pos.state == INVALID_CAD)
    valid = np.flatnonzero(pos.state == VALID)
    assert len(invalid) > 100 and len(valid) > 100
    # every position marked invalid, and a sample of the valid ones, against brute-force FCL
    for sample in (invalid, rng.choice(valid, 500, replace=False)):
        Q = table.joints(table.positions[sample])
        naive = np.array([exact.in_collision_naive(q) for q in Q])
        assert naive.tolist() == (pos.state[sample] == INVALID_CAD).tolist()
    # the exact pre-test proved some collisions without FCL, and FCL settled the rest
    v = pos.validator
    assert sum(v.sure_hits.values()) > 0 and sum(v.checks.values()) > sum(v.sure_hits.values())


def test_validator_agrees_with_full_checker_on_a_fresh_sample(world, rv2aj, rng):
    table = world.table
    validator = ChainValidator(rv2aj, world.cad, table)
    ids = table.positions[rng.choice(table.n_positions, 1500, replace=False)]
    ok = validator.validate(ids)
    full = CollisionChecker(rv2aj, world.cad).in_collision_batch(table.joints(ids))
    assert ok.tolist() == (~full).tolist()
    assert 0.05 < ok.mean() < 0.95


def test_selection_keeps_the_first_valid_positions_of_each_leaf(world):
    table, pos = world.table, world.positions
    k = world.config.selection.per_cell
    cells, offsets, Q = world.cell_positions()
    assert np.all(np.diff(offsets) <= k) and np.all(np.diff(offsets) >= 1)
    for s in range(len(table.leaves)):
        sel = np.flatnonzero(pos.selected[table.offsets[s]:table.offsets[s + 1]])
        if not len(sel):
            continue
        st = pos.state[table.offsets[s]:table.offsets[s + 1]]
        assert np.all(st[sel] == VALID)
        # nothing valid was skipped before the last selected one
        assert np.count_nonzero(st[:sel[-1] + 1] == VALID) == len(sel)
    free = world.free().reshape(-1)
    assert free[cells].sum() == free.sum()


def test_build_report_and_free_cells(world):
    free = world.free()
    assert free.sum() > 50
    assert not (free & world.occupied()).any()
    assert not (free & ~world.reachable()).any()
