"""The learnt obstacle as the page draws it: the learnt leaves without the arm's own volume in
the posture it stands in (`session.learnt_view`)."""

from __future__ import annotations

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import Obstacle
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.session.learnt_view import SPLIT, learnt_view
from assistant.session.types import OccupiedCells
from assistant.transforms import make_T, rot_z

LEAF = 0.0625
Q_HALT = np.array([0.3, 0.4, 1.2, 0.2, 0.0])


def _cells_round_the_hand(robot, q, T_wb):
    """Three leaves in a row through the TCP at q (world frame), on a turned base."""
    R = T_wb[:3, :3]
    tcp = T_wb @ robot.fk(q)[:, 3]
    centres = np.array([tcp[:3] + R @ [dx, 0.0, 0.0] for dx in (-LEAF, 0.0, LEAF)])
    return OccupiedCells(centres, np.ones(3), LEAF, R.copy())


def test_the_sub_cells_the_arm_stands_in_are_left_out(rv2aj):
    T_wb = make_T(rot_z(0.5), [0.2, -0.1, 0.05])
    cells = _cells_round_the_hand(rv2aj, Q_HALT, T_wb)
    view = learnt_view(cells, rv2aj, Q_HALT, T_wb)
    total = 3 * SPLIT ** 3
    assert view.edge == LEAF / SPLIT
    assert 0 < view.under_arm < total and len(view.centres) == total - view.under_arm
    # Nothing drawn touches the arm where it stands (the same boxes, checked one by one)...
    box = (CollisionShape(ShapeKind.BOX, (view.edge,) * 3),)
    T_bw = np.linalg.inv(T_wb)
    drawn = [Obstacle(f"d{i}", make_T(T_bw[:3, :3] @ cells.R_world_grid,
                                      T_bw[:3, :3] @ c + T_bw[:3, 3]), box)
             for i, c in enumerate(view.centres)]
    assert CollisionChecker(rv2aj, drawn).check(Q_HALT).collision_free
    # ...and the TCP's own sub-cell is one of those left out.
    tcp = (T_wb @ rv2aj.fk(Q_HALT)[:, 3])[:3]
    assert np.abs(view.centres - tcp).max(axis=1).min() > view.edge / 2 - 1e-12


def test_with_the_arm_elsewhere_every_sub_cell_is_drawn(rv2aj):
    T_wb = np.eye(4)
    cells = _cells_round_the_hand(rv2aj, Q_HALT, T_wb)
    away = Q_HALT + np.array([2.0, 0.0, 0.0, 0.0, 0.0])  # turned round J1
    view = learnt_view(cells, rv2aj, away, T_wb)
    assert view.under_arm == 0 and len(view.centres) == 3 * SPLIT ** 3
    # the sub-cells fill the leaves exactly: their mean is the leaves' mean
    np.testing.assert_allclose(view.centres.mean(axis=0), cells.centres.mean(axis=0),
                               rtol=0, atol=1e-12)  # sums of ~200 numbers of ~0.5 m


def test_the_contact_postures_and_where_it_stands_are_all_left_out(rv2aj):
    T_wb = np.eye(4)
    cells = _cells_round_the_hand(rv2aj, Q_HALT, T_wb)
    away = Q_HALT + np.array([2.0, 0.0, 0.0, 0.0, 0.0])
    halt_only = learnt_view(cells, rv2aj, Q_HALT, T_wb)
    both = learnt_view(cells, rv2aj, np.array([away, Q_HALT]), T_wb)
    assert both.under_arm == halt_only.under_arm > 0
    np.testing.assert_array_equal(both.centres, halt_only.centres)  # the same numbers
