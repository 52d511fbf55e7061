"""The elastic net's compiled move test (`trajectory.net_kernel`) against its numpy path.

Both must give the same net (within the rounding `_same_net` states), with every test the
kernel folds in taking part: octree leaves (a recorded collision occupies its leaf), the
position IK, joint limits, the recorded collision's posture box, margin certificates, the
broad phase with `min_gap`, and FCL for the moves the broad phase cannot clear.
"""

from __future__ import annotations

import numpy as np
import pytest
from planning_fixtures import box, make_planner

import assistant.trajectory.elastic_net as en
from assistant.planning.known_world import KnownValidity, WorldAllowed
from assistant.trajectory.elastic_net import ElasticNetParams
from assistant.trajectory.particles import resample_joint_path

Z = 0.25


def _bow_path(robot) -> np.ndarray:
    """Joints of a bow around the block (position IK, each seeded from the previous)."""
    s = np.linspace(0.0, 1.0, 14)
    pts = np.stack([0.27 + 0.15 * np.sin(np.pi * s), -0.15 + 0.30 * s, np.full_like(s, Z)], 1)
    q, out = None, []
    for p in pts:
        T = np.eye(4)
        T[:3, 3] = p
        q = robot.ik(T, q, position_only=True).best(q)
        out.append(q)
    Q = np.array(out)
    Q[:, 4] += np.linspace(-0.3, 0.3, len(Q))  # a tool roll that varies: the IK pulls it
    return Q


@pytest.fixture(scope="module")
def scenes(rv2aj):
    """A plain cell, and one where the operator flagged a collision on the bow's way back:
    its posture box and its occupied leaf refuse moves there."""
    Q = _bow_path(rv2aj)
    out = {}
    for recorded in (False, True):
        planner = make_planner(rv2aj, [box("block", [0.27, 0.0, Z], [0.06, 0.06, 0.06])])
        if recorded:
            planner.roadmap.add_collision(Q[9])
        out[recorded] = planner
    return out, Q


def _run(planner, Q, compiled: bool, min_gap: float, grid: bool, monkeypatch,
         midpoints: bool = True) -> tuple[en._Net, tuple]:
    """Both stages of the final net (`relax`), keeping the net's state for comparison."""
    monkeypatch.setattr(en, "COMPILED_MOVES", compiled)
    validity = KnownValidity(planner.checker, planner.world)
    params = ElasticNetParams.final(stage1_iterations=150, stage2_iterations=40,
                                    min_gap=min_gap, check_edge_midpoints=midpoints)
    net = en._Net(planner.robot, resample_joint_path(planner.robot, Q, params.spacing),
                  WorldAllowed(planner.world) if grid else None, validity, params)
    assert (net._kernel is not None) == compiled
    s1 = net.run_stage(1, params.stage1_iterations, None, 0, 1)
    return net, (s1, net.run_stage(2, params.stage2_iterations, None, 0, 1))


@pytest.mark.parametrize(("recorded", "grid", "min_gap", "midpoints"),
                         [(True, True, 0.01, True), (True, False, 0.0, True),
                          (False, False, 0.0, True), (False, True, 0.03, False)])
def test_compiled_moves_give_the_numpy_net(scenes, monkeypatch, recorded, grid, min_gap,
                                           midpoints):
    """With the octree's leaves or the recorded posture box the net keeps off the block;
    without them it is pulled against it, and FCL decides the moves the broad phase cannot
    clear."""
    planners, Q = scenes
    planner = planners[recorded]
    statuses: list[np.ndarray] = []
    check = en.check_moves

    def recording(*args):
        out = check(*args)
        statuses.append(out[0].copy())
        return out

    monkeypatch.setattr(en, "check_moves", recording)
    near = planner.world.near_recorded_collision
    refused_by_box = []

    def counting(Qr, exclude=frozenset()):
        out = near(Qr, exclude)
        refused_by_box.append(int(out.sum()))
        return out

    monkeypatch.setattr(planner.world, "near_recorded_collision", counting)
    fast, fast_stages = _run(planner, Q, True, min_gap, grid, monkeypatch, midpoints)
    calls = len(statuses)
    assert calls, "the compiled move test was not used"
    slow, slow_stages = _run(planner, Q, False, min_gap, grid, monkeypatch, midpoints)
    assert len(statuses) == calls  # the numpy run did not use it
    _same_stages(fast_stages, slow_stages)
    # The particles, and what the certificates and min_gap remember about each.
    _same_net(fast, slow)
    assert (fast.rejected, fast.accepted, fast.certified_moves) == (
        slow.rejected, slow.accepted, slow.certified_moves)
    # Every test took part: moves were certified and refused, the recorded posture box
    # refused some (counted in the numpy run), and FCL was asked where nothing else kept
    # the net off the block.
    assert fast.rejected > 0
    assert fast.certified_moves > 0 or min_gap > 0.01  # the margins are 1-2 cm here
    assert (sum(refused_by_box) > 0) == recorded
    if not recorded and min_gap == 0.0:
        # the broad phase could not clear some moves: FCL decided them
        assert (np.concatenate(statuses) == en.ASK_FCL).any()


def _same_stages(fast, slow) -> None:
    """The same iteration counts and stop reasons (exact: a stop would flip only for a
    movement within ~1e-16 of its threshold); the last movement E (mean move per particle,
    ~1e-5 m) within 1e-12 m - the sums of the same moves, ~1e-16 relative each."""
    assert [(s.iterations, s.stop) for s in fast] == [(s.iterations, s.stop) for s in slow]
    np.testing.assert_allclose([s.final_movement for s in fast],
                               [s.final_movement for s in slow], rtol=0, atol=1e-12)


def _same_net(fast, slow) -> None:
    """The compiled and the numpy net agree: pinned flags exactly (booleans, and the counts
    of accepted/refused moves are compared exactly by the callers: a move's acceptance would
    flip only for a trial within ~1e-12 of a margin or an obstacle, which these nets never
    produce), positions, joints and margins within 1e-9 (m, rad): each sweep adds ~1e-16
    relative differences (FMA, vector width) and the elastic forces damp them; a wrong move
    or a lost margin shows as a millimetre."""
    for name in ("P", "Q", "_ref_Q", "_ref_margin", "_gap"):
        np.testing.assert_allclose(getattr(fast, name), getattr(slow, name), rtol=0,
                                   atol=1e-9, equal_nan=True, err_msg=name)
    assert np.array_equal(fast._pinned, slow._pinned)


def test_a_refused_move_is_retried_at_half_length():
    """The numpy path's retry: a move refused at full length (and not pinned) is tested
    again at half its length; pinned or accepted rows keep theirs. (Halving is exact in
    binary floating point, so the values compare exactly.)"""
    ok = np.array([True, False, False])
    pin = np.array([False, False, True])
    idx = np.array([3, 4, 5])
    D = np.ones((3, 2))
    P = np.zeros((6, 2))
    trial = np.full((6, 2), 9.0)
    rows = en._halve_retries(ok, pin, idx, D, trial, P)
    assert rows.tolist() == [1]
    assert (D[1] == 0.5).all() and (D[[0, 2]] == 1.0).all()
    assert (trial[4] == 0.5).all() and (trial[[3, 5]] == 9.0).all()
