"""Operator collision indications and sensor observations change the world model."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.collision.reports import Obstacle
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.transforms import make_T
from assistant.world.cell_positions import INVALID_INDICATED
from assistant.world.fusion import Source
from assistant.world.indications import near_posture, nearby_positions
from assistant.world.model import WorldConfig, WorldModel
from assistant.world.reachability import ReachabilityConfig


@pytest.fixture
def world(rv2aj) -> WorldModel:
    table = Obstacle("table", make_T(p=[0.0, 0.0, -0.011]),
                     (CollisionShape(ShapeKind.BOX, (1.5, 1.5, 0.02)),))
    cfg = WorldConfig(leaf=0.125, reach=ReachabilityConfig(d_step=0.0625), use_cache=False)
    w = WorldModel(rv2aj, [table], cfg)
    w.build()
    return w


def test_indication_occupies_the_arm_cells_and_invalidates_nearby_postures(world, rv2aj):
    q = np.radians([20.0, 40.0, 60.0, 30.0, 0.0])
    tcp_cell = world.tcp_cell(q)
    assert world.free().reshape(-1)[tcp_cell]
    _, _, Q_before = world.cell_positions()  # (remembered until the selection changes)
    assert near_posture(world.table, Q_before, q, world.config.indication.joint_steps).any()
    change = world.indicate_collision(q)
    occ = world.occupied().reshape(-1)
    assert tcp_cell in change.observed_cells.tolist()
    assert occ[change.observed_cells].all()
    assert tcp_cell in change.occupancy_flipped.tolist()
    # cells along the forearm (elbow to wrist) are marked too, not only the TCP's
    elbow = rv2aj.link_poses(q)[3][:3, 3]
    assert world.grid.flat_of_points(elbow[None])[0] in change.observed_cells.tolist()
    # postures next to q are gone from the search, and the posture itself is remembered
    assert change.positions_invalidated > 0
    _, _, Q = world.cell_positions()
    assert not near_posture(world.table, Q, q, world.config.indication.joint_steps).any()
    assert (world.positions.state == INVALID_INDICATED).sum() == change.positions_invalidated
    # the direct box look-up finds exactly what a scan of the whole table finds
    t = world.table
    scan = np.flatnonzero(near_posture(t, t.joints(t.positions), q,
                                       world.config.indication.joint_steps))
    assert nearby_positions(t, q, world.config.indication.joint_steps).tolist() == scan.tolist()
    assert world.near_recorded_collision(q[None])[0]
    assert not world.near_recorded_collision(np.radians([[-90.0, 0, 90, 0, 0]]))[0]
    # pressing again at the same posture changes no occupancy
    again = world.indicate_collision(q)
    assert len(again.occupancy_flipped) == 0


def test_remembered_position_views_follow_every_selection_change(world):
    """`has_valid` and the shared `cell_positions` are remembered between queries: each
    change of the selection (an indication's invalidation and refill) must show at once, and
    a caller writing to the grid it got must not change the next one."""
    pos = world.positions

    def fresh() -> np.ndarray:
        m = np.zeros(world.grid.n_cells, dtype=bool)
        m[world.table.leaves[pos.n_selected > 0]] = True
        return m.reshape(world.grid.shape)

    first = world.has_valid()
    assert np.array_equal(first, fresh())
    first[:] = False
    assert np.array_equal(world.has_valid(), fresh()) and world.has_valid().any()
    shared = world.cell_positions_shared()
    assert all(np.array_equal(a, b) for a, b in zip(shared, world.cell_positions(),
                                                    strict=True))
    before = fresh()
    world.indicate_collision(np.radians([20.0, 40.0, 60.0, 30.0, 0.0]))  # refills leaves
    assert np.array_equal(world.has_valid(), fresh())
    slot = int(np.flatnonzero(pos.n_selected > 0)[0])  # a leaf loses every position
    pos.invalidate(np.arange(world.table.offsets[slot], world.table.offsets[slot + 1]))
    assert not np.array_equal(fresh(), before)
    assert np.array_equal(world.has_valid(), fresh())
    cells, offsets, Q = world.cell_positions_shared()
    assert all(np.array_equal(a, b) for a, b in zip((cells, offsets, Q),
                                                    world.cell_positions(), strict=True))
    assert len(cells) == int((pos.n_selected > 0).sum())


def test_sensor_observations_go_through_fusion_and_free_cells_refill(world):
    p = np.array([[0.30, 0.10, 0.35]])
    cell = world.grid.flat_of_points(p)[0]
    assert world.free().reshape(-1)[cell]
    first = world.observe(Source.SENSOR, p, 1.0)
    # one reading of a window-5 sensor is its own SMA: occupied at once
    assert first.occupancy_flipped.tolist() == [cell]
    for _ in range(4):
        world.observe(Source.SENSOR, p, 1.0)
    freed = None
    for k in range(5):
        ch = world.observe(Source.SENSOR, p, 0.0)
        if len(ch.occupancy_flipped):
            freed = k
    # the 1 -> 0 step costs reliability, so P falls below 0.5 before the window empties
    assert freed is not None and freed < 4
    assert world.free().reshape(-1)[cell]
    assert world.occupancy().reshape(-1)[cell] == 0.0


def test_tcp_cells_of_several_postures_are_the_cells_one_by_one(world, rv2aj):
    """`tcp_cells` (one batch FK) equals `tcp_cell` row by row, including a TCP outside the
    octree, and gives -1 for a posture that is not all finite."""
    rng = np.random.default_rng(2)
    Q = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, (30, 5))
    Q[3] = np.nan
    got = world.tcp_cells(Q)
    want = np.array([world.tcp_cell(q) if np.isfinite(q).all() else -1 for q in Q])
    # Leaf ids of TCPs from the batch FK (compiled) and the one-posture FK: the positions
    # agree to ~1e-16 m, so rows whose TCP lies within 1e-9 m of a leaf face are left out.
    clear = _clear_of_faces(world.grid, rv2aj, Q)
    assert clear.sum() >= 25 and clear[3]  # nearly all rows compared (and the NaN row)
    assert got[clear].tolist() == want[clear].tolist()
    assert got[3] == -1 and (got >= 0).sum() >= 20
    small = WorldModel(rv2aj, [], WorldConfig(size=0.3, leaf=0.075, use_cache=False))
    far = small.tcp_cells(Q[:5])  # the 0.3 m cube misses most TCPs
    want = np.array([small.tcp_cell(q) if np.isfinite(q).all() else -1 for q in Q[:5]])
    clear = _clear_of_faces(small.grid, rv2aj, Q[:5])
    assert clear.sum() >= 4 and far[clear].tolist() == want[clear].tolist()
    assert (far == -1).sum() >= 2


def _clear_of_faces(grid, robot, Q: np.ndarray, tol_m: float = 1e-9) -> np.ndarray:
    """Rows whose TCP lies more than `tol_m` from every leaf face (and cube face) of `grid`;
    rows that are not all finite count as clear (-1 either way)."""
    out = np.ones(len(Q), dtype=bool)
    for i, q in enumerate(Q):
        if np.isfinite(q).all():
            r = (robot.fk(q)[:3, 3] - grid.origin) / grid.leaf
            out[i] = np.abs(r - np.round(r)).min() * grid.leaf > tol_m
    return out
