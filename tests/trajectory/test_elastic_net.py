"""Elastic net on the real RV-2AJ: straighter and shorter paths, never into forbidden space."""

from __future__ import annotations

import numpy as np
import pytest
from traj_builders import TABLE, box, box_distance, densify, ik_path

from assistant.collision.checker import CollisionChecker
from assistant.progress import Cancelled, Progress
from assistant.trajectory.elastic_net import (
    ElasticNetParams,
    StopReason,
    relax,
    run_elastic_net,
    turn_angles,
)
from assistant.trajectory.fit_growth import fit_primitives
from assistant.trajectory.particles import Particles
from assistant.trajectory.primitives import FitParams, PrimitiveKind

Z = 0.25  # working height of these tests (m), well inside the RV-2AJ's reach


@pytest.fixture(scope="module")
def free_checker(rv2aj):
    return CollisionChecker(rv2aj, [TABLE])


def _zigzag(rng, n=15):
    y = np.linspace(-0.15, 0.15, n)
    pts = np.stack([0.27 + rng.uniform(-0.03, 0.03, n), y + rng.uniform(-0.01, 0.01, n),
                    Z + rng.uniform(-0.03, 0.03, n)], axis=1)
    pts[0], pts[-1] = [0.27, -0.15, Z], [0.27, 0.15, Z]
    return pts


def _chord_distance(P):
    a, b = P[0], P[-1]
    u = (b - a) / np.linalg.norm(b - a)
    X = P - a
    return np.linalg.norm(X - np.outer(X @ u, u), axis=1)


def test_noisy_zigzag_becomes_straight_and_shorter(rv2aj, free_checker, rng):
    Q = ik_path(rv2aj, _zigzag(rng))
    res = run_elastic_net(rv2aj, Q, validity=free_checker,
                          params=ElasticNetParams(stage1_iterations=300, stage2_iterations=150))
    P0, P = res.initial.points, res.particles.points
    assert res.particles.tcp_length() < 0.8 * res.initial.tcp_length()
    chord = np.linalg.norm(P[-1] - P[0])
    assert res.particles.tcp_length() < chord * 1.001
    assert _chord_distance(P).max() < 0.002 < _chord_distance(P0).max()
    assert np.degrees(turn_angles(P)).max() < 2.0
    # Start and goal are fixed; every particle is a real configuration that reaches its point.
    assert np.array_equal(res.particles.joints[0], Q[0])
    assert np.array_equal(res.particles.joints[-1], Q[-1])
    assert np.allclose(rv2aj.batch_fk(res.particles.joints).positions, P, atol=1e-9)
    assert free_checker.is_valid_batch(res.particles.joints).all()
    # Neighbouring particles keep neighbouring arm configurations (no branch jumps).
    assert np.abs(np.diff(res.particles.joints, axis=0)).max() < 0.3
    # Spacing evened out.
    sp = res.particles.spacing()
    assert sp.max() / sp.min() < 1.1


def test_wall_between_start_and_goal_is_never_crossed(rv2aj, free_checker):
    """A plate between start and goal: the path must stay around its end, however hard the
    shrink force pulls towards the straight line through it."""
    wall_c, wall_s, margin = np.array([0.22, 0.0, Z]), np.array([0.16, 0.01, 0.3]), 0.03

    def allowed(points):
        return box_distance(points, wall_c, wall_s) >= margin

    # Searched path: out to x = 0.40, around the wall's end (x = 0.30), back in.
    s = np.linspace(0.0, 1.0, 14)
    pts = np.stack([0.22 + 0.18 * np.sin(np.pi * s), -0.15 + 0.30 * s, np.full_like(s, Z)], 1)
    Q = ik_path(rv2aj, pts)
    assert allowed(rv2aj.batch_fk(Q).positions).all()
    res = run_elastic_net(rv2aj, Q, allowed=allowed, validity=free_checker,
                          params=ElasticNetParams(stage1_iterations=300, stage2_iterations=200))
    P = res.particles.points
    assert allowed(P).all()
    assert res.rejected_moves > 0  # the wall really was in the way
    dense = densify(P)
    assert box_distance(dense, wall_c, wall_s).min() > 0.0
    # It crosses y = 0 only beyond the wall's end, on the allowed side.
    k = int(np.nonzero(np.diff(np.sign(P[:, 1])) != 0)[0][0])
    f = -P[k, 1] / (P[k + 1, 1] - P[k, 1])
    x_cross = P[k, 0] + f * (P[k + 1, 0] - P[k, 0])
    assert x_cross > 0.30 + margin - 0.005
    assert res.particles.tcp_length() < res.initial.tcp_length()


def test_moves_that_put_the_arm_in_collision_are_rejected(rv2aj):
    """No `allowed` callback at all: only the FCL validity check stands between the shrinking
    net and a box lying on the straight line."""
    obstacle = box("block", [0.27, 0.0, Z], [0.06, 0.06, 0.06])
    checker = CollisionChecker(rv2aj, [TABLE, obstacle])
    s = np.linspace(0.0, 1.0, 14)
    pts = np.stack([0.27 + 0.15 * np.sin(np.pi * s), -0.15 + 0.30 * s, np.full_like(s, Z)], 1)
    Q = ik_path(rv2aj, pts)
    assert checker.is_valid_batch(Q).all()
    params = ElasticNetParams(stage1_iterations=250, stage2_iterations=50)
    res = run_elastic_net(rv2aj, Q, validity=checker, params=params)
    assert checker.is_valid_batch(res.particles.joints).all()
    assert res.rejected_moves > 0
    # The same net without the check would have gone through the block.
    blind = run_elastic_net(rv2aj, Q, params=params)
    assert not checker.is_valid_batch(blind.particles.joints).all()


def test_the_net_wraps_an_obstacle_in_a_line_an_arc_and_a_line(rv2aj, free_checker):
    centre, radius = np.array([0.27, 0.0, Z]), 0.08

    def allowed(points):
        return np.linalg.norm(points - centre, axis=1) >= radius

    s = np.linspace(0.0, 1.0, 12)
    pts = np.stack([0.27 + 0.15 * np.sin(np.pi * s), -0.18 + 0.36 * s, np.full_like(s, Z)], 1)
    res = run_elastic_net(rv2aj, ik_path(rv2aj, pts), allowed=allowed, validity=free_checker)
    P = res.particles.points
    assert allowed(P).all()
    fit = fit_primitives(P, FitParams(tolerance=0.002))
    assert [p.kind for p in fit.primitives] == [PrimitiveKind.LINE, PrimitiveKind.ARC,
                                               PrimitiveKind.LINE]
    arc = fit.primitives[1]
    # The arc hugs the forbidden ball, bending around its centre.
    assert radius - 0.005 < np.linalg.norm(arc.via - centre) < radius + 0.01
    assert np.linalg.norm(arc.centre - centre) < 0.03


def test_exploring_keeps_the_roads_clearance_final_pulls_taut(rv2aj, free_checker):
    """Low shrink while exploring: the smoothed road keeps away from what is known to be
    occupied; high shrink for the final path: it pulls tight around it."""
    centre, radius = np.array([0.27, 0.0, Z]), 0.05

    def allowed(points):
        return np.linalg.norm(points - centre, axis=1) >= radius

    s = np.linspace(0.0, 1.0, 12)
    pts = np.stack([0.27 + 0.15 * np.sin(np.pi * s), -0.18 + 0.36 * s, np.full_like(s, Z)], 1)
    Q = ik_path(rv2aj, pts)
    budget = dict(stage1_iterations=100, stage2_iterations=100)
    explore = run_elastic_net(rv2aj, Q, allowed=allowed, validity=free_checker,
                              params=ElasticNetParams.exploring(**budget))
    final = run_elastic_net(rv2aj, Q, allowed=allowed, validity=free_checker,
                            params=ElasticNetParams.final(**budget))

    def clearance(r):
        return np.linalg.norm(r.particles.points - centre, axis=1).min() - radius

    assert clearance(explore) > 0.05
    assert 0.0 <= clearance(final) < 0.01
    assert final.particles.tcp_length() < explore.particles.tcp_length()
    assert explore.particles.tcp_length() < 0.99 * explore.initial.tcp_length()


def test_stop_reasons(rv2aj):
    # Evenly spaced points on a straight line: nothing to do, converges at once.
    pts = np.stack([np.full(9, 0.28), np.linspace(-0.1, 0.1, 9), np.full(9, Z)], axis=1)
    Q = ik_path(rv2aj, pts)
    res = relax(rv2aj, Particles(rv2aj.batch_fk(Q).positions, Q))
    assert res.stage1.stop == StopReason.CONVERGED and res.stage1.iterations < 5
    # Nothing allowed: every move is rejected, the particles stay.
    bent = pts.copy()
    bent[4, 0] += 0.03
    Qb = ik_path(rv2aj, bent)
    res = relax(rv2aj, Particles(rv2aj.batch_fk(Qb).positions, Qb),
                allowed=lambda p: np.zeros(len(p), dtype=bool))
    assert res.stage1.stop == StopReason.BLOCKED and res.stage1.iterations == 1
    assert np.array_equal(res.particles.joints, Qb)
    # Given room, the bent line is pulled straight: stage 1 ends as soon as it stops getting
    # shorter, well before the cap ...
    res = relax(rv2aj, Particles(rv2aj.batch_fk(Qb).positions, Qb),
                params=ElasticNetParams(stage1_iterations=2000, stage2_iterations=2000))
    assert res.stage1.stop == StopReason.TAUT and res.stage1.iterations < 200
    assert _chord_distance(res.particles.points).max() < 0.001
    # ... and without that test it runs on until it settles (mean movement below 1 um),
    # to the same straight line.
    slow = relax(rv2aj, Particles(rv2aj.batch_fk(Qb).positions, Qb),
                 params=ElasticNetParams(stage1_iterations=2000, stage2_iterations=2000,
                                         taut_length=0.0))
    assert slow.stage1.stop == StopReason.SETTLED
    assert res.stage1.iterations < slow.stage1.iterations < 2000
    assert slow.stage1.final_movement < 1e-6
    assert _chord_distance(slow.particles.points).max() < 0.001
    assert abs(slow.particles.tcp_length() - res.particles.tcp_length()) < 1e-4
    # A budget too small to settle.
    res = relax(rv2aj, Particles(rv2aj.batch_fk(Qb).positions, Qb),
                params=ElasticNetParams(stage1_iterations=3, stage2_iterations=2))
    assert res.stage1.stop == res.stage2.stop == StopReason.ITERATION_CAP
    assert res.iterations == 5


def test_cancel_stops_the_net(rv2aj, rng):
    Q = ik_path(rv2aj, _zigzag(rng))
    progress = Progress("net")
    progress.cancel()
    with pytest.raises(Cancelled):
        run_elastic_net(rv2aj, Q, progress=progress)


class _PlainValidity:
    """The same checker without the margin API: every move gets the exact check."""

    def __init__(self, checker):
        self.checker = checker

    def is_valid(self, q):
        return self.checker.is_valid(q)

    def is_valid_batch(self, Q):
        return self.checker.is_valid_batch(Q)

    def first_invalid_fraction(self, q0, q1):
        return self.checker.first_invalid_fraction(q0, q1)


@pytest.mark.parametrize("compiled", [True, False])
def test_certified_moves_give_exactly_the_exactly_checked_net(rv2aj, monkeypatch, compiled):
    """Moves that stay inside a particle's free margin skip FCL; the result must not change
    by a single bit, and the shortcut must really be taken (by the compiled move test and
    by the numpy one)."""
    import assistant.trajectory.elastic_net as en

    monkeypatch.setattr(en, "COMPILED_MOVES", compiled)
    obstacle = box("block", [0.27, 0.0, Z], [0.06, 0.06, 0.06])
    checker = CollisionChecker(rv2aj, [TABLE, obstacle])
    s = np.linspace(0.0, 1.0, 14)
    pts = np.stack([0.27 + 0.15 * np.sin(np.pi * s), -0.15 + 0.30 * s, np.full_like(s, Z)], 1)
    Q = ik_path(rv2aj, pts)
    params = ElasticNetParams(stage1_iterations=120, stage2_iterations=40)
    fast = run_elastic_net(rv2aj, Q, validity=checker, params=params)
    exact = run_elastic_net(rv2aj, Q, validity=_PlainValidity(checker), params=params)
    # Exact on any machine: both runs execute the same compiled net arithmetic in this
    # process; only which validity check answers differs, and it answers alike.
    assert np.array_equal(fast.particles.joints, exact.particles.joints)
    assert np.array_equal(fast.particles.points, exact.particles.points)
    assert (fast.rejected_moves, fast.accepted_moves) == (exact.rejected_moves,
                                                          exact.accepted_moves)
    assert exact.rejected_moves > 0  # the block was in the way: exact checks mattered too
    assert exact.certified_moves == 0
    assert fast.certified_moves > 0.2 * (fast.accepted_moves + fast.rejected_moves)


def test_min_gap_keeps_the_arm_off_the_obstacles(rv2aj):
    """Pulled taut around a block, the net touches it; with `min_gap` every particle keeps at
    least that exact clearance (the sphere gap it enforces is a lower bound of it)."""
    obstacle = box("block", [0.27, 0.0, Z], [0.06, 0.06, 0.06])
    checker = CollisionChecker(rv2aj, [TABLE, obstacle])
    s = np.linspace(0.0, 1.0, 14)
    pts = np.stack([0.27 + 0.15 * np.sin(np.pi * s), -0.15 + 0.30 * s, np.full_like(s, Z)], 1)
    Q = ik_path(rv2aj, pts)

    def clearance(res):
        return min(checker.clearance(q).distance for q in res.particles.joints[1:-1])

    taut = run_elastic_net(rv2aj, Q, validity=checker,
                           params=ElasticNetParams.final(stage1_iterations=200))
    kept = run_elastic_net(rv2aj, Q, validity=checker,
                           params=ElasticNetParams.final(stage1_iterations=200, min_gap=0.02))
    assert clearance(taut) < 0.01
    assert clearance(kept) >= 0.02
    assert checker.is_valid_batch(kept.particles.joints).all()
    # Still pulled in: shorter than the bow it started from, a little longer than touching.
    assert taut.particles.tcp_length() < kept.particles.tcp_length() < kept.initial.tcp_length()


def test_pinned_particles_are_not_retried(rv2aj, monkeypatch):
    """Against a block the same particles are refused sweep after sweep. A particle refused at
    both lengths proposes only the half move next sweep, so a sweep needs a second (retry)
    check only when a particle is refused for the first time - and the net still keeps off
    the block."""
    import assistant.trajectory.elastic_net as en

    obstacle = box("block", [0.27, 0.0, Z], [0.06, 0.06, 0.06])
    checker = CollisionChecker(rv2aj, [TABLE, obstacle])
    s = np.linspace(0.0, 1.0, 14)
    pts = np.stack([0.27 + 0.15 * np.sin(np.pi * s), -0.15 + 0.30 * s, np.full_like(s, Z)], 1)
    Q = ik_path(rv2aj, pts)
    calls, lengths = [], []
    original = en._Net.try_moves

    def counting(self, idx, D, trial):
        calls.append(len(idx))
        lengths.append(np.linalg.norm(D, axis=1))
        return original(self, idx, D, trial)

    monkeypatch.setattr(en._Net, "try_moves", counting)
    res = run_elastic_net(rv2aj, Q, validity=checker,
                          params=ElasticNetParams.final(stage1_iterations=200))
    assert checker.is_valid_batch(res.particles.joints).all()
    assert res.rejected_moves > 0.5 * res.iterations  # pressed against the block all along
    # Without pinning nearly every sweep checks twice here (169 calls in 94 sweeps); with
    # it, 137: the rest are particles refused for the first time.
    assert len(calls) < 1.6 * res.iterations
    assert all(np.all(d <= 0.005 + 1e-12) for d in lengths)


@pytest.mark.parametrize("compiled", [True, False])
def test_each_stage_moves_particles_at_most_its_cap(rv2aj, free_checker, monkeypatch,
                                                    compiled):
    """Stage 1 may move a particle up to `stage1_max_move` a sweep, stage 2 `max_move`: a
    zigzag's first sweep takes moves beyond the stage-2 cap, never beyond its own, and the
    compiled and the numpy sweeps agree to the bit."""
    import assistant.trajectory.elastic_net as en

    Q = ik_path(rv2aj, _zigzag(np.random.default_rng(7)))
    caps = dict(max_move=0.004, stage1_max_move=0.012)

    def first_sweep(stage1: int, stage2: int, comp: bool) -> tuple[np.ndarray, np.ndarray]:
        monkeypatch.setattr(en, "COMPILED_MOVES", comp)
        res = run_elastic_net(rv2aj, Q, validity=free_checker, params=ElasticNetParams.final(
            stage1_iterations=stage1, stage2_iterations=stage2, taut_length=0.0, **caps))
        return res.initial.points, res.particles.points

    P0, P1 = first_sweep(1, 0, compiled)
    step = np.linalg.norm(P1 - P0, axis=1)
    assert 0.006 < step.max() <= 0.012 + 1e-9
    # stage 2 alone (stage 1 given no sweep) keeps the small cap
    P0, P2 = first_sweep(0, 1, compiled)
    assert 0.0 < np.linalg.norm(P2 - P0, axis=1).max() <= 0.004 + 1e-9
    other = first_sweep(1, 0, not compiled)[1]
    # compiled vs numpy moves: 1e-12 m, one sweep of a few products per particle (~1e-16
    # relative each); a wrong cap or force would move particles by millimetres
    np.testing.assert_allclose(P1, other, rtol=0, atol=1e-12)


def test_a_pending_move_kernel_runs_the_numpy_net(rv2aj, monkeypatch):
    """On a first run (kernels pending, `kernels.lazy`) the net takes its numpy path, not
    the move kernel's interpreted Python, and gives the net the numpy path gives: particles
    within 1e-9 rad (the same arithmetic, some of it in kernels' fallbacks, whose last bits
    may differ from compiled code)."""
    import assistant.trajectory.elastic_net as en
    from assistant.kernels import lazy

    obstacle = box("block", [0.27, 0.0, Z], [0.06, 0.06, 0.06])
    checker = CollisionChecker(rv2aj, [TABLE, obstacle])
    s = np.linspace(0.0, 1.0, 14)
    pts = np.stack([0.27 + 0.15 * np.sin(np.pi * s), -0.15 + 0.30 * s, np.full_like(s, Z)], 1)
    Q = ik_path(rv2aj, pts)
    params = ElasticNetParams(stage1_iterations=60, stage2_iterations=20)
    monkeypatch.setattr(en, "COMPILED_MOVES", False)
    numpy_net = run_elastic_net(rv2aj, Q, validity=checker, params=params)
    monkeypatch.setattr(en, "COMPILED_MOVES", True)

    def compiled_path(*args, **kwargs):
        raise AssertionError("the compiled move path ran while its kernels were pending")

    monkeypatch.setattr(en._Net, "_try_moves_compiled", compiled_path)
    lazy.set_pending(True)
    try:
        pending = run_elastic_net(rv2aj, Q, validity=checker, params=params)
    finally:
        lazy.set_pending(False)
    np.testing.assert_allclose(pending.particles.joints, numpy_net.particles.joints,
                               rtol=0, atol=1e-9)
    assert numpy_net.accepted_moves > 0
