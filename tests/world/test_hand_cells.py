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
from assistant.world.hand_kernel import hand_blocked, hand_blocked_numpy
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
    monkeypatch.undo()
    clear = _clear_rows(panda, hand, grid, R)  # the compiled test against numpy's points
    assert [g for g, c in zip(got, clear, strict=True) if c] == \
        [w for w, c in zip(want, clear, strict=True) if c] and 0 < sum(got)
    assert clear.mean() > 0.9
    centres = grid.origin + (np.stack(np.unravel_index(np.flatnonzero(mask), (grid.n,) * 3),
                                      axis=1) + 0.5) * grid.leaf
    tcp = panda.batch_fk(R).positions
    d = np.linalg.norm(tcp[:, None] - centres[None], axis=2).min(axis=1)
    assert posed == [int((d <= 0.25 + grid.leaf * np.sqrt(3) / 2 + 1e-6).sum())] and \
        posed[0] < len(R)


def _clear_rows(panda, hand: HandCells, grid: OctreeGrid, R: np.ndarray,
                tol: float = 1e-9) -> np.ndarray:
    """Rows none of whose hand points (nor its TCP) lies within `tol` of a leaf boundary or
    of the reach: there compiled and numpy arithmetic (~1e-15 m apart) decide alike."""
    F = panda.batch_link_poses(R)[:, hand._link]
    P = np.einsum("nmij,mj->nmi", F[..., :3, :3], hand._local) + F[..., :3, 3]
    tcp = np.asarray(panda.batch_fk(R).positions)
    pts = np.concatenate([P, tcp[:, None]], axis=1)
    f = (pts - grid.origin) / grid.leaf
    off_faces = (np.abs(f - np.rint(f)) * grid.leaf > tol).all(axis=(1, 2))
    d = np.linalg.norm(P - tcp[:, None], axis=2)
    off_reach = (np.abs(d - hand.config.reach) > tol).all(axis=1)
    return off_faces & off_reach


def test_the_compiled_hand_test_is_its_numpy_form(panda, grid):
    """`hand_kernel.hand_blocked` and its numpy fallback give the same answer on random
    postures and masks (where no point lies within rounding of a leaf face or the reach)."""
    rng = np.random.default_rng(8)
    R = rng.uniform(panda.limits.lower, panda.limits.upper, (400, panda.dof))
    hand = HandCells(panda, grid, first_link=2)
    frames = panda.batch_link_poses(R)
    tcp = np.ascontiguousarray(panda.batch_fk(R).positions)
    clear = _clear_rows(panda, hand, grid, R)
    assert clear.mean() > 0.9
    answers = []
    for density in (0.001, 0.01, 0.1):
        mask = rng.random(grid.n_cells) < density
        a = np.zeros(len(R), dtype=bool)
        b = np.zeros(len(R), dtype=bool)
        args = (frames, hand._link, hand._local, tcp, hand.config.reach ** 2,
                np.asarray(grid.origin, dtype=float), float(grid.leaf), int(grid.n), mask)
        hand_blocked(*args, a)
        hand_blocked_numpy(*args, b)
        assert (a[clear] == b[clear]).all()
        answers.append(a.mean())
    assert 0.0 < min(answers) and max(answers) < 1.0  # both answers are asked for
