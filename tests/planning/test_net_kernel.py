"""The elastic net's compiled move test (`trajectory.net_kernel`) against its numpy path.

Both must give the same net bit for bit, with every test the kernel folds in taking part:
octree leaves (a recorded collision occupies its leaf), the position IK, joint limits, the
recorded collision's posture box, margin certificates, the broad phase with `min_gap`, and
FCL for the moves the broad phase cannot clear.
"""

from __future__ import annotations

import numpy as np
import pytest
from planning_fixtures import box, make_planner

import assistant.trajectory.elastic_net as en
from assistant.planning.known_world import KnownValidity, WorldAllowed
from assistant.trajectory.elastic_net import ElasticNetParams
from assistant.trajectory.net_forces import propose_moves
from assistant.trajectory.net_stage import NEEDS_FCL
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
def test_compiled_moves_give_the_numpy_net_bit_for_bit(scenes, monkeypatch, recorded, grid,
                                                       min_gap, midpoints):
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
    runs = []  # the compiled runs of sweeps (`net_stage`); sweeps needing FCL come back
    run_sweeps = en.run_sweeps

    def counting_runs(*args):
        out = run_sweeps(*args)
        runs.append(out[0])
        return out

    monkeypatch.setattr(en, "run_sweeps", counting_runs)
    near = planner.world.near_recorded_collision
    refused_by_box = []

    def counting(Qr, exclude=frozenset()):
        out = near(Qr, exclude)
        refused_by_box.append(int(out.sum()))
        return out

    monkeypatch.setattr(planner.world, "near_recorded_collision", counting)
    fast, fast_stages = _run(planner, Q, True, min_gap, grid, monkeypatch, midpoints)
    calls = len(statuses)
    assert runs, "the compiled sweeps were not used"
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
        # sweeps the compiled run handed back, and FCL decided moves in them
        assert NEEDS_FCL in runs and (np.concatenate(statuses) == en.ASK_FCL).any()


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


def _reference_iterate(self, stage, lam):
    """`_Net.iterate` as numpy calls, before its bookkeeping was compiled (`net_sweep`)."""
    P0, p = self.P, self.p
    idx, D, trial = propose_moves(P0, stage, lam, p.c_equidistance, p.c_rotation,
                                  p.c_shrink, p.c_line_shrink, p.stage1_shrink, p.r_max,
                                  p.r_min, p.max_move)
    live = en.row_norms(D) > 0.0
    idx, D = idx[live], D[live]
    if not len(idx):
        return 0.0, 0, 0
    pinned = self._pinned[idx]
    D[pinned] *= 0.5
    trial[idx[pinned]] = P0[idx[pinned]] + D[pinned]
    ok = self.try_moves(idx, D, trial)
    refused = ~ok & pinned
    retry = np.nonzero(~ok & ~pinned)[0]
    if len(retry):
        D[retry] *= 0.5
        trial[idx[retry]] = P0[idx[retry]] + D[retry]
        ok2 = self.try_moves(idx[retry], D[retry], trial)
        ok[retry[ok2]] = True
        refused[retry[~ok2]] = True
    self._pinned[:] = False
    self._pinned[idx[refused]] = True
    self.rejected += int(refused.sum())
    accepted = int(ok.sum())
    self.accepted += accepted
    E = float(en.row_norms(D[ok]).sum()) / max(1, len(P0) - 2)
    return E, accepted, len(idx)


@pytest.mark.parametrize("compiled", [True, False])
def test_compiled_sweep_bookkeeping_gives_the_numpy_net_bit_for_bit(scenes, monkeypatch,
                                                                    compiled):
    """The sweep's proposals, pinned halves, retries and re-pinning (`net_sweep`), and the
    runs of sweeps in one compiled call (`net_stage`), against the numpy form they
    replaced, with either move test."""
    planners, Q = scenes
    planner = planners[True]
    pins = []
    repin = en.repin

    def counting(ok, pin, retry, ok2, idx, pinned):
        pins.append((int(pin.sum()), len(retry)))
        return repin(ok, pin, retry, ok2, idx, pinned)

    # with compiled moves: the runs of sweeps in one call (`net_stage`), as the planner
    # runs them, then sweep by sweep (counting pins and retries)
    runs = [_run(planner, Q, compiled, 0.01, True, monkeypatch)] if compiled else []
    monkeypatch.setattr(en, "COMPILED_SWEEPS", False)
    monkeypatch.setattr(en, "repin", counting)
    runs.append(_run(planner, Q, compiled, 0.01, True, monkeypatch))
    monkeypatch.setattr(en._Net, "iterate", _reference_iterate)
    slow, slow_stages = _run(planner, Q, compiled, 0.01, True, monkeypatch)
    for fast, fast_stages in runs:
        _same_stages(fast_stages, slow_stages)
        _same_net(fast, slow)
        assert (fast.rejected, fast.accepted) == (slow.rejected, slow.accepted)
    # pinned particles and retried moves both occurred
    assert sum(a for a, _ in pins) > 0 and sum(b for _, b in pins) > 0
