"""The leaves an arm's hand fills (`world.hand_cells`): what the verifier keeps a 6- or
7-axis arm's hand out of after a collision indication.

On a real Panda from example-robot-data: exact facts only (leaf ids are integers) - every
leaf listed holds a point of the hand within the reach of the TCP, the TCP's own leaf is
one of them, leaves only the far end of the arm fills are not, and `blocked` is exactly the
overlap with a mask.
"""

from __future__ import annotations

import numpy as np
import pytest

from assistant.robots.catalog import installed_robot_urdf
from assistant.robots.urdf_robot import URDFRobot
from assistant.world.hand_cells import HandCells, HandConfig
from assistant.world.octree import OctreeGrid

PANDA_URDF = "example-robot-data/robots/panda_description/urdf/panda.urdf"


@pytest.fixture(scope="module")
def panda() -> URDFRobot:
    urdf, share = installed_robot_urdf(PANDA_URDF)
    return URDFRobot.from_file(urdf, package_dirs=[share], load_visual=False,
                               tool_link="panda_hand")


@pytest.fixture(scope="module")
def grid() -> OctreeGrid:
    return OctreeGrid.for_leaf(2.0, 0.0625)


Q = np.array([[0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8],
              [0.8, 0.2, -0.4, -1.6, 0.3, 1.7, 0.0]])


def test_the_hand_is_the_arm_near_the_tcp(panda, grid):
    hand = HandCells(panda, grid, first_link=2)
    cells = hand.cells(Q)
    assert len(cells) == 2
    for q, c in zip(Q, cells, strict=True):
        tcp = panda.fk(q)[:3, 3]
        assert grid.flat_of_points(tcp[None])[0] in c.tolist()
        assert len(c) == len(np.unique(c)) and (c >= 0).all()
        # every listed leaf is within reach of the TCP (plus the leaf's half diagonal)
        centres = grid.origin + (np.stack(np.unravel_index(c, (grid.n,) * 3), axis=1)
                                 + 0.5) * grid.leaf
        assert (np.linalg.norm(centres - tcp, axis=1)
                <= 0.25 + grid.leaf * np.sqrt(3) / 2 + 1e-9).all()
        # the shoulder (link 2's origin, ~0.33 m up the base) is not the hand
        shoulder = panda.link_poses(q)[2][:3, 3]
        assert grid.flat_of_points(shoulder[None])[0] not in c.tolist()
    # a longer reach holds at least those leaves
    wide = HandCells(panda, grid, 2, HandConfig(reach=0.4)).cells(Q)
    assert all(np.isin(a, b).all() and len(b) > len(a) for a, b in zip(cells, wide,
                                                                      strict=True))


def test_blocked_is_exactly_the_overlap_with_the_mask(panda, grid):
    hand = HandCells(panda, grid, first_link=2)
    cells = hand.cells(Q)
    mask = np.zeros(grid.n_cells, dtype=bool)
    assert not hand.blocked(Q, mask).any()
    mask[cells[0][0]] = True
    assert hand.blocked(Q, mask).tolist() == [True, bool(np.isin(cells[0][0], cells[1]))]
    mask[:] = False
    other = np.setdiff1d(cells[1], cells[0])
    assert len(other)
    mask[other] = True
    assert hand.blocked(Q, mask).tolist() == [False, True]


def test_blocked_poses_the_hand_only_where_the_tcp_comes_within_reach(panda, grid,
                                                                      monkeypatch):
    """On 300 random postures and a mask of one posture's hand leaves, `blocked` is the
    overlap of each row's `cells` with the mask (exact: leaf ids), and the link poses are
    asked only for rows whose TCP lies within reach (plus half a leaf's diagonal) of a
    masked leaf."""
    rng = np.random.default_rng(4)
    R = rng.uniform(panda.limits.lower, panda.limits.upper, (300, panda.dof))
    hand = HandCells(panda, grid, first_link=2)
    mask = np.zeros(grid.n_cells, dtype=bool)
    mask[hand.cells(Q[:1])[0]] = True
    want = [bool(mask[c].any()) for c in hand.cells(R)]
    posed: list[int] = []
    real = panda.batch_link_poses
    monkeypatch.setattr(panda, "batch_link_poses", lambda q: posed.append(len(q)) or real(q))
    got = hand.blocked(R, mask).tolist()
    assert got == want and 0 < sum(got)
    centres = grid.origin + (np.stack(np.unravel_index(np.flatnonzero(mask), (grid.n,) * 3),
                                      axis=1) + 0.5) * grid.leaf
    tcp = panda.batch_fk(R).positions
    d = np.linalg.norm(tcp[:, None] - centres[None], axis=2).min(axis=1)
    assert posed == [int((d <= 0.25 + grid.leaf * np.sqrt(3) / 2 + 1e-6).sum())] and \
        posed[0] < len(R)
