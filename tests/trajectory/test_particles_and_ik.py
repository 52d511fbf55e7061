"""Particles from a searched joint path, and the seeded position IK that maps moves back."""

from __future__ import annotations

import numpy as np
import pytest
from traj_builders import ik_path

from assistant.trajectory.particles import densify_joint_path, resample_joint_path
from assistant.trajectory.position_ik import BatchPositionIK, PositionIKParams


@pytest.fixture(scope="module")
def coarse_path(rv2aj):
    """Like an A* path: a few configurations, TCP jumps of several centimetres between them."""
    pts = np.array([[0.25, -0.15, 0.2], [0.32, -0.05, 0.3], [0.30, 0.08, 0.22],
                    [0.22, 0.15, 0.28]])
    return ik_path(rv2aj, pts)


def test_resampled_particles_are_even_and_real(rv2aj, coarse_path):
    parts = resample_joint_path(rv2aj, coarse_path, 0.02)
    assert np.array_equal(parts.joints[0], coarse_path[0])
    assert np.array_equal(parts.joints[-1], coarse_path[-1])
    assert np.allclose(rv2aj.batch_fk(parts.joints).positions, parts.points, atol=1e-12)
    sp = parts.spacing()
    assert abs(sp.mean() - 0.02) < 0.003
    assert sp.max() / sp.min() < 1.3


def test_densified_path_has_short_chords_and_keeps_the_configurations(rv2aj, coarse_path):
    Q, P = densify_joint_path(rv2aj, coarse_path, 0.004)
    assert np.linalg.norm(np.diff(P, axis=0), axis=1).max() <= 0.004
    for q in coarse_path:  # the searched configurations are still on the path
        assert np.min(np.linalg.norm(Q - q, axis=1)) < 1e-12


def _offset_robot(offset: bool):
    from assistant.robots.model import Tool
    from assistant.robots.rv2aj import RV2AJ, RV2AJConfig

    T = np.eye(4)
    T[:3, 3] = [0.03, 0.0, 0.08]
    return RV2AJ(RV2AJConfig(tool=Tool("offset", T) if offset else Tool.straight(0.1)))


@pytest.mark.parametrize("offset", [False, True])
def test_densify_keeps_the_rows_and_shortens_every_chord_within_its_passes(offset,
                                                                           monkeypatch):
    """Random joint paths, done in one pass or several, or still long when the passes run
    out (one pass allowed); a tool with and without an offset from the flange axis: every
    input row is kept in order, the points are the rows' FK, and with every pass allowed
    no chord is longer than the step."""
    import assistant.trajectory.particles as particles

    robot = _offset_robot(offset)
    rng = np.random.default_rng(3)
    lo, hi = robot.limits.lower, robot.limits.upper
    ends = set()
    for passes in (1, particles._PASSES):
        monkeypatch.setattr(particles, "_PASSES", passes)
        for n in (2, 3, 5, 9):
            for step in (0.001, 0.005, 0.05):
                Q = rng.uniform(lo, hi, (n, 5))
                got_q, got_p = densify_joint_path(robot, Q, step)
                rows = [int(np.flatnonzero((got_q == q).all(axis=1))[0]) for q in Q]
                assert rows == sorted(rows) and rows[0] == 0 and rows[-1] == len(got_q) - 1
                # 1e-12 m: the same FK, batched or row by row (~1e-16 relative per product)
                np.testing.assert_allclose(got_p, robot.batch_fk(got_q).positions, rtol=0,
                                           atol=1e-12)
                long = np.linalg.norm(np.diff(got_p, axis=0), axis=1).max() > step
                ends.add((passes, long))
    assert {(1, True), (6, False)} <= ends


@pytest.mark.parametrize("offset", [False, True])
def test_resampled_particles_are_even_along_the_path_and_keep_its_ends(offset):
    """Densified random joint paths, spacings that give one particle gap or many, lengths
    half-way between two counts, a path with repeated rows (zero-length segments): the
    first and last rows are kept exactly, the points are the joints' FK, and no gap is
    longer than the path's length shared evenly (plus the chord's sag)."""
    import assistant.trajectory.particles as particles

    robot = _offset_robot(offset)
    rng = np.random.default_rng(5)
    lo, hi = robot.limits.lower, robot.limits.upper
    paths = [rng.uniform(lo, hi, (n, 5)) for n in (2, 3, 5, 9) for _ in range(3)]
    paths.append(np.repeat(paths[2], 2, axis=0))
    gaps = set()
    for Q0 in paths:
        _, P = particles.densify_joint_path(robot, Q0, 0.002)
        length = float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())
        for spacing in (0.005, 0.02, 0.3, 10.0, length / 2.5, length / 3.5):
            got = particles.resample_joint_path(robot, Q0, spacing)
            # the length as the resampling measures it (densified to spacing / 8)
            _, P = particles.densify_joint_path(robot, Q0, spacing / 8.0)
            total = float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())
            assert np.array_equal(got.joints[0], Q0[0]) and np.array_equal(got.joints[-1],
                                                                           Q0[-1])
            np.testing.assert_allclose(got.points, robot.batch_fk(got.joints).positions,
                                       rtol=0, atol=1e-12)  # the same FK, see above
            n_gap = len(got) - 1
            assert n_gap == max(1, round(total / spacing)) or abs(
                (total / spacing) % 1.0 - 0.5) < 1e-9  # a half-way length may round either way
            # each gap spans at most total / n of the densified polyline; inside a chord
            # (<= spacing / 8) the joint interpolation sags off it by far less than 5 %
            assert got.spacing().max() <= 1.05 * total / n_gap + 1e-9
            gaps.add(n_gap)
    assert 1 in gaps and max(gaps) > 50


def test_small_moves_are_solved_next_to_the_seeds(rv2aj, coarse_path, rng):
    parts = resample_joint_path(rv2aj, coarse_path, 0.02)
    ik = BatchPositionIK(rv2aj)
    targets = parts.points + rng.uniform(-0.004, 0.004, parts.points.shape)
    res = ik.solve(targets, parts.joints)
    assert res.ok.all()
    reached = np.asarray(rv2aj.batch_fk(res.joints).positions)
    assert np.linalg.norm(reached - targets, axis=1).max() < 1e-6
    assert np.abs(res.joints - parts.joints).max() < 0.1


def test_nullspace_pull_moves_free_joints_towards_the_reference(rv2aj, coarse_path):
    """The TCP target is the same; only the joints a position leaves free (tool pitch, J6)
    follow the reference."""
    q = coarse_path[1]
    target = np.asarray(rv2aj.batch_fk(q[None]).positions)
    ref = q + np.array([0.0, 0.0, 0.0, 0.2, 0.3])  # another pitch and roll
    free = BatchPositionIK(rv2aj, PositionIKParams(nullspace_gain=0.0))
    pulled = BatchPositionIK(rv2aj, PositionIKParams(nullspace_gain=0.5))
    a = free.solve(target, q[None], ref[None])
    b = pulled.solve(target, q[None], ref[None])
    assert a.ok[0] and b.ok[0]
    assert np.allclose(a.joints[0], q)  # already there: nothing to do without the pull
    assert np.linalg.norm(b.joints[0] - ref) < np.linalg.norm(q - ref)
    assert np.linalg.norm(rv2aj.fk(b.joints[0])[:3, 3] - target[0]) < 1e-6


def test_unreachable_or_jumping_targets_are_refused(rv2aj, coarse_path):
    ik = BatchPositionIK(rv2aj, PositionIKParams(max_joint_jump=0.05))
    q = coarse_path[:2]
    P = np.asarray(rv2aj.batch_fk(q).positions)
    targets = np.array([[2.0, 0.0, 0.3], P[1] + [0.0, 0.06, 0.0]])  # out of reach; too far
    res = ik.solve(targets, q)
    assert not res.ok.any()
    assert np.array_equal(res.joints, q)  # refused rows keep their seeds


def test_closed_form_ik_lands_on_the_targets_next_to_the_seeds(rv2aj, rng):
    """The RV-2AJ's batched closed form: exact, on the seed's J1 side and elbow, and the
    free pitch pulled towards the reference."""
    lim = rv2aj.limits
    seeds = rng.uniform(lim.lower * 0.8, lim.upper * 0.8, size=(400, 5))
    targets = rv2aj.batch_fk(seeds).positions + rng.uniform(-0.004, 0.004, (400, 3))
    ref = seeds + np.array([0.0, 0.0, 0.0, 0.15, 0.0])  # another tool pitch
    Q, ok = rv2aj.batch_position_ik(targets, seeds, ref, gain=0.5, max_jump=0.25)
    assert ok.mean() > 0.95
    reached = rv2aj.batch_fk(Q[ok]).positions
    assert np.linalg.norm(reached - targets[ok], axis=1).max() < 1e-9
    assert lim.contains_batch(Q[ok]).all()
    assert np.abs(Q[ok] - seeds[ok]).max() <= 0.25
    assert np.all(np.sign(Q[ok, 2]) == np.sign(seeds[ok, 2]))  # same elbow
    pitch = lambda q: q[:, 1] + q[:, 2] + q[:, 3]  # noqa: E731
    moved = np.abs(pitch(Q[ok]) - pitch(ref[ok])) < np.abs(pitch(seeds[ok]) - pitch(ref[ok]))
    assert moved.mean() > 0.9
    assert np.array_equal(Q[~ok], seeds[~ok])  # refused rows keep their seeds


def test_closed_form_ik_turns_the_pitch_away_from_a_joint_limit(rv2aj):
    """At the seed's pitch the target needs J5 beyond its limit: a nearby pitch is found (the
    old fallback scanned pitches in Python per particle)."""
    seed = np.array([0.2, 0.6, 1.0, np.radians(89.0), 0.0])
    p = rv2aj.batch_fk(seed[None]).positions[0]
    # raise the target: at the seed's pitch J2/J3 open up and J5 must exceed +90 deg
    target = p + np.array([0.0, 0.0, 0.004])
    _, fixed_ok = rv2aj.batch_position_ik(target[None], seed[None], None, gain=0.0,
                                          max_jump=0.25, pitch_window=0.0)
    Q, ok = rv2aj.batch_position_ik(target[None], seed[None], None, gain=0.0, max_jump=0.25)
    assert not fixed_ok[0]
    assert ok[0] and rv2aj.limits.contains(Q[0])
    assert np.linalg.norm(rv2aj.batch_fk(Q[:1]).positions[0] - target) < 1e-9
    assert 0.0 < seed[1:4].sum() - Q[0, 1:4].sum() < np.radians(5.0)  # a nearby pitch


def test_off_axis_tools_use_the_general_method(rv2aj, coarse_path):
    T = np.eye(4)
    T[:3, 3] = [0.03, 0.0, 0.1]  # TCP off the flange axis: no closed form
    robot = rv2aj.with_tool(T)
    parts = resample_joint_path(robot, coarse_path, 0.02)
    assert robot.batch_position_ik(parts.points, parts.joints) is None
    res = BatchPositionIK(robot).solve(parts.points + 0.002, parts.joints)
    assert res.ok.all()
    assert np.linalg.norm(robot.batch_fk(res.joints).positions - parts.points - 0.002,
                          axis=1).max() < 1e-6


def _reference_position_ik(robot, targets, seeds, pitch, q6, max_jump, offsets):
    """The numpy formulation the compiled loop replaced: every candidate pitch of every
    row evaluated, the first that works (pulled pitch, then the offsets in order) taken."""
    from assistant.robots.rv2aj import L1, L2, L3, L6, _wrap

    cand = np.concatenate([pitch[:, None], pitch[:, None] + offsets[None]], axis=1)
    q1s = seeds[:, 0]
    face = np.arctan2(targets[:, 1], targets[:, 0])
    a = q1s + _wrap(face - q1s)
    b = q1s + _wrap(face + np.pi - q1s)
    q1 = np.where(np.abs(a - q1s) <= np.abs(b - q1s), a, b)
    r = targets[:, 0] * np.cos(q1) + targets[:, 1] * np.sin(q1)
    le = L6 + float(robot.T_flange_tool[2, 3])
    wr = r[:, None] - le * np.sin(cand)
    wz = (targets[:, 2] - L1)[:, None] - le * np.cos(cand)
    D = (wr * wr + wz * wz - L2 * L2 - L3 * L3) / (2.0 * L2 * L3)
    ac = np.arccos(np.clip(D, -1.0, 1.0))
    s3 = seeds[:, 2:3]
    q3 = np.where(np.abs(ac - s3) <= np.abs(-ac - s3), ac, -ac)
    q2 = np.arctan2(wr, wz) - np.arctan2(L3 * np.sin(q3), L2 + L3 * np.cos(q3))
    q2 = seeds[:, 1:2] + _wrap(q2 - seeds[:, 1:2])
    q5 = seeds[:, 3:4] + _wrap(cand - q2 - q3 - seeds[:, 3:4])
    Q = np.stack([np.broadcast_to(q1[:, None], q2.shape), q2, q3, q5,
                  np.broadcast_to(q6[:, None], q2.shape)], axis=2)
    lim = robot.limits
    ok = (np.abs(D) <= 1.0) & np.all((Q >= lim.lower - 1e-9) & (Q <= lim.upper + 1e-9), axis=2)
    ok &= np.abs(Q - seeds[:, None, :]).max(axis=2) <= max_jump
    found = ok.any(axis=1)
    out = seeds.copy()
    out[found] = Q[found, np.argmax(ok, axis=1)[found]]
    return out, found, np.argmax(ok, axis=1)


def test_closed_form_ik_takes_the_nearest_working_pitch(rv2aj, rng):
    """The compiled loop stops at the first pitch that works; the numpy formulation it
    replaced evaluated them all: the same joints row for row, including rows that needed
    the search (targets raised or lowered next to J5's limits)."""
    lim = rv2aj.limits
    seeds = rng.uniform(lim.lower * 0.95, lim.upper * 0.95, size=(3000, 5))
    seeds[:1000, 3] = np.sign(seeds[:1000, 3]) * np.radians(89.0)  # J5 at its limit
    targets = rv2aj.batch_fk(seeds).positions + rng.uniform(-0.006, 0.006, (3000, 3))
    ref = seeds + rng.normal(0.0, 0.2, (3000, 5))
    Q, ok = rv2aj.batch_position_ik(targets, seeds, ref, gain=0.5, max_jump=0.25)
    s_seed = seeds[:, 1:4].sum(1)
    pitch = s_seed + 0.5 * ((ref[:, 1:4].sum(1) - s_seed + np.pi) % (2 * np.pi) - np.pi)
    q6 = seeds[:, 4] + 0.5 * (ref[:, 4] - seeds[:, 4])
    step, n = np.radians(1.0), int(np.floor(np.radians(40.0) / np.radians(1.0)))
    offsets = np.stack([np.arange(1, n + 1) * step, -np.arange(1, n + 1) * step], 1).ravel()
    Q_ref, ok_ref, which = _reference_position_ik(rv2aj, targets, seeds, pitch, q6, 0.25,
                                                  offsets)
    assert np.array_equal(ok, ok_ref)
    np.testing.assert_allclose(Q, Q_ref, rtol=0, atol=1e-12)
    searched = ok_ref & (which > 0)
    assert searched.sum() > 50 and (~ok_ref).sum() > 50  # both the search and refusals
