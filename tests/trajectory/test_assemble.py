"""Assembly on the RV-2AJ: motions with poses and joints, dense paths, exact verification."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from traj_builders import TABLE, box, box_distance, ik_path

from assistant.collision.checker import CollisionChecker
from assistant.mission.motion import MotionKind
from assistant.trajectory.assemble import (
    AssemblyParams,
    _end_joints,
    assemble_trajectory,
    trajectory_from_joint_path,
    verify,
)
from assistant.trajectory.elastic_net import ElasticNetParams
from assistant.trajectory.fit_growth import fit_primitives
from assistant.trajectory.particles import Particles
from assistant.trajectory.primitives import FitParams
from assistant.transforms import axis_angle

Z = 0.20
FAR_BOX = ("far", [-0.30, -0.30, 0.15], [0.10, 0.10, 0.10])


def _corner_nodes(spacing=0.01, radius=0.06):
    """Line along +y, 90 deg arc turning towards -x, line along -x; horizontal, at height Z."""
    y = np.arange(-0.12, 0.0 + 1e-9, spacing)
    l1 = np.stack([np.full_like(y, 0.32), y, np.full_like(y, Z)], 1)
    a = np.linspace(0.0, np.pi / 2, int(round(np.pi / 2 * radius / spacing)) + 1)[1:]
    arc = np.stack([0.32 - radius + radius * np.cos(a), radius * np.sin(a), np.full_like(a, Z)], 1)
    x = np.arange(0.32 - radius - spacing, 0.14 - 1e-9, -spacing)
    l2 = np.stack([x, np.full_like(x, radius), np.full_like(x, Z)], 1)
    return np.concatenate([l1, arc, l2])


@pytest.fixture(scope="module")
def corner(rv2aj):
    nodes = _corner_nodes()
    Q = ik_path(rv2aj, nodes)
    P = np.asarray(rv2aj.batch_fk(Q).positions)
    fit = fit_primitives(P, FitParams(tolerance=0.001))
    return Particles(P, Q), fit


def test_known_trajectory_is_assembled_and_verified(rv2aj, corner):
    particles, fit = corner
    checker = CollisionChecker(rv2aj, [TABLE, box(*FAR_BOX)])
    res = assemble_trajectory(rv2aj, fit, particles, checker)
    assert res.ok, res.report.reason
    traj = res.trajectory
    kinds = [m.kind for m in traj.motions]
    assert kinds == [MotionKind.LINEAR, MotionKind.CIRCULAR, MotionKind.LINEAR]
    prev = traj.start
    for m, prim in zip(traj.motions, fit.primitives, strict=True):
        Q = m.joint_path
        assert np.array_equal(Q[0], prev.q) and np.array_equal(Q[-1], m.target.q)
        for wp in (m.target, m.via) if m.via is not None else (m.target,):
            assert np.allclose(wp.T_base_tool, rv2aj.fk(wp.q), atol=1e-12)
        tcp = np.asarray(rv2aj.batch_fk(Q).positions)
        assert prim.distance(tcp).max() < 1e-6  # the arm really follows the primitive
        assert np.linalg.norm(np.diff(tcp, axis=0), axis=1).max() <= 0.005 + 1e-6
        assert np.abs(np.diff(Q, axis=0)).max() <= 0.1
        assert np.linalg.norm(m.target.position - prim.end) < 1e-6
        prev = m.target
    arc_motion = traj.motions[1]
    assert np.linalg.norm(arc_motion.via.position - fit.primitives[1].via) < 1e-6
    assert traj.motions[0].blend_radius == 0.0  # line -> arc is tangent: nothing to blend
    r = res.report
    assert r.primitive_counts == {"linear": 2, "circular": 1}
    assert callable(r.tcp_measure)  # measured when first read, then kept
    dense_tcp = np.asarray(rv2aj.batch_fk(traj.dense_joint_path()).positions)
    assert r.tcp_length == np.linalg.norm(np.diff(dense_tcp, axis=0), axis=1).sum()
    assert r.tcp_measure == r.tcp_length
    assert r.tcp_length == pytest.approx(fit.length, rel=1e-3)
    assert r.joint_length > 0.5
    tcp = np.asarray(rv2aj.batch_fk(traj.dense_joint_path()).positions)
    assert 0.0 < r.min_clearance <= box_distance(tcp, FAR_BOX[1], FAR_BOX[2]).min()
    assert r.max_deviation == fit.max_deviation <= 0.001
    assert r.fallbacks == ()


def test_clearance_is_measured_once_when_first_read(rv2aj, corner):
    """The report carries the measurement, not the figure, until someone reads it; then
    the figure is the checker's own for the dense path and is not measured again."""
    particles, fit = corner
    checker = CollisionChecker(rv2aj, [TABLE, box(*FAR_BOX)])
    asked: list[int] = []

    class Counting:
        def check_path(self, path, max_step=None, trusted=None):
            return checker.check_path(path, max_step, trusted)

        def min_clearance_along(self, path, max_step=0.01):
            asked.append(len(path))
            return checker.min_clearance_along(path, max_step)

    res = assemble_trajectory(rv2aj, fit, particles, Counting())
    assert res.ok and asked == [] and callable(res.report.clearance)
    dense = res.trajectory.dense_joint_path()
    expected = checker.min_clearance_along(list(dense), 0.01)
    assert res.report.min_clearance == expected > 0.0
    assert res.report.min_clearance == expected and asked == [len(dense)]
    assert f"min clearance {expected * 1000:.1f} mm" in res.report.describe()
    no_obstacles = assemble_trajectory(rv2aj, fit, particles, CollisionChecker(rv2aj, []))
    assert no_obstacles.ok and no_obstacles.report.min_clearance is None


def test_trajectory_through_a_box_is_refused(rv2aj, corner):
    """A post the planner did not know stands in the arc (tall enough to reach the tool's
    body, which ends short of the TCP): the exact check refuses the result."""
    particles, fit = corner
    size = (0.03, 0.03, 0.10)
    hidden = box("hidden", [0.302, 0.042, Z + 0.04], size)
    checker = CollisionChecker(rv2aj, [TABLE, hidden])
    res = assemble_trajectory(rv2aj, fit, particles, checker)
    assert not res.ok and res.trajectory is None
    f = res.report.failure
    # The flange (radius 32 mm) meets the post near the end of the first line or on the arc.
    assert (f.motion_index, f.motion_kind) in ((0, "linear"), (1, "circular"))
    assert 0.0 < f.fraction < 1.0
    assert "hidden" in f.description and "hidden" in res.report.reason
    assert box_distance(f.tcp_position, hidden.T_base_object[:3, 3], size)[0] < 0.05
    assert res.candidate is not None  # kept for display only


def test_a_hit_on_the_last_motion_is_placed_as_a_motion_by_motion_check_would(rv2aj, corner):
    """Verification checks the whole dense path at once; the failure it reports must name
    the motion, fraction and posture that checking each motion's own path finds."""
    particles, fit = corner
    size = (0.03, 0.03, 0.10)
    post = box("post", [0.20, 0.06, Z + 0.04], size)
    clear = assemble_trajectory(rv2aj, fit, particles, None).trajectory
    checker = CollisionChecker(rv2aj, [TABLE, post])
    res = verify(rv2aj, clear, checker)
    assert not res.ok
    f = res.report.failure
    paths = [m.joint_path for m in clear.motions]
    hits = [checker.check_path(list(Q)) for Q in paths]
    i = next(k for k, h in enumerate(hits) if h is not None)
    seg, mc = hits[i]
    assert (f.motion_index, f.motion_kind) == (i, "linear") and i == 2
    assert f.fraction == pytest.approx((seg + mc.first_invalid_fraction) / (len(paths[i]) - 1))
    q = paths[i][seg] + mc.first_invalid_fraction * (paths[i][seg + 1] - paths[i][seg])
    assert np.allclose(f.q, q)
    assert "post" in f.description


def test_joint_limit_violation_is_refused(rv2aj, corner):
    particles, fit = corner
    res = assemble_trajectory(rv2aj, fit, particles, None)
    assert res.ok and res.report.min_clearance is None
    traj = res.trajectory
    bad = traj.motions[2].joint_path.copy()
    bad[len(bad) // 2, 3] = rv2aj.limits.upper[3] + 0.1
    traj.motions[2] = replace(traj.motions[2], joint_path=bad)
    out = verify(rv2aj, traj, None)
    assert not out.ok and out.trajectory is None
    assert "joint limit" in out.report.reason and "J5" in out.report.reason
    assert out.report.failure.motion_index == 2


def test_a_move_that_cannot_be_followed_becomes_a_joint_move_and_says_so(rv2aj):
    """A line right past the J1 axis: the arm would have to spin J1 half a turn in a few
    millimetres, which no controller follows; the piece becomes a JOINT move."""
    pts = np.stack([np.linspace(0.12, -0.12, 13), np.full(13, 0.015), np.full(13, 0.45)], 1)
    Q = ik_path(rv2aj, pts)
    P = np.asarray(rv2aj.batch_fk(Q).positions)
    fit = fit_primitives(P, FitParams(tolerance=0.001))
    assert len(fit.primitives) == 1
    checker = CollisionChecker(rv2aj, [TABLE])
    res = assemble_trajectory(rv2aj, fit, Particles(P, Q), checker)
    assert res.ok
    m = res.trajectory.motions[0]
    assert m.kind == MotionKind.JOINT
    assert len(res.report.fallbacks) == 1 and "joint move" in res.report.fallbacks[0]
    assert np.linalg.norm(m.target.position - fit.primitives[0].end) < 1e-6
    # Its dense path is the controller's straight joint interpolation.
    d = m.joint_path - m.joint_path[0]
    span = m.joint_path[-1] - m.joint_path[0]
    f = d @ span / (span @ span)
    assert np.allclose(d, np.outer(f, span), atol=1e-12)


def test_a_checked_joint_move_is_not_checked_again_and_the_result_is_the_same(rv2aj,
                                                                             monkeypatch):
    """The joint-move fallback was checked while it was split; verification trusts those
    segments (asks the checker about the other motions only) and reports the same."""
    pts = np.stack([np.linspace(0.12, -0.12, 13), np.full(13, 0.015), np.full(13, 0.45)], 1)
    Q = ik_path(rv2aj, pts)
    P = np.asarray(rv2aj.batch_fk(Q).positions)
    fit = fit_primitives(P, FitParams(tolerance=0.001))
    checker = CollisionChecker(rv2aj, [TABLE])
    calls = []
    check_path = checker.check_path

    def recording(path, max_step=None, trusted=None):
        calls.append(None if trusted is None else np.asarray(trusted).copy())
        return check_path(path, max_step, trusted)

    monkeypatch.setattr(checker, "check_path", recording)
    res = assemble_trajectory(rv2aj, fit, Particles(P, Q), checker)
    monkeypatch.undo()
    assert res.ok and res.trajectory.motions[0].kind == MotionKind.JOINT
    # the split's check, then verification with that motion's segments trusted
    assert calls[0] is None and calls[-1] is not None and calls[-1].all()
    again = verify(rv2aj, res.trajectory, checker, fallbacks=res.report.fallbacks,
                   max_deviation=fit.max_deviation)
    assert again.report == res.report


def test_whole_pipeline_from_a_searched_path(rv2aj):
    """Searched joint path (a bow around a ball nobody may enter) -> verified trajectory."""
    centre, radius = np.array([0.27, 0.0, 0.25]), 0.08

    def allowed(points):
        return np.linalg.norm(points - centre, axis=1) >= radius

    ball = box("ball-core", centre, [0.06, 0.06, 0.06])
    checker = CollisionChecker(rv2aj, [TABLE, ball])
    s = np.linspace(0.0, 1.0, 12)
    pts = np.stack([0.27 + 0.15 * np.sin(np.pi * s), -0.18 + 0.36 * s, np.full_like(s, 0.25)], 1)
    out = trajectory_from_joint_path(
        rv2aj, ik_path(rv2aj, pts), allowed=allowed, validity=checker, verifier=checker,
        net_params=ElasticNetParams(stage1_iterations=300, stage2_iterations=300),
        fit_params=FitParams(tolerance=0.002), assembly_params=AssemblyParams(speed=0.2))
    assert out.report.ok, out.report.reason
    assert out.report.primitive_counts == {"linear": 2, "circular": 1}
    assert out.report.max_deviation <= 0.002
    assert out.report.min_clearance > 0.0
    assert out.report.tcp_length < out.net.initial.tcp_length()
    assert all(m.speed == 0.2 for m in out.trajectory.motions)


def test_a_fallbacks_end_joints_are_those_of_the_scalar_ik(rv2aj):
    """The batch answers a joint-move fallback's end pose as `ik` would: the pose, else its
    orientation turned into the arm plane, the solution nearest the reference; poses it
    cannot answer go through `ik` (position only last). Poses the batch answers with "no
    solution" go to the position alone at once: `ik` must fail on them as the batch says."""
    rng = np.random.default_rng(11)
    lo, hi = rv2aj.limits.lower, rv2aj.limits.upper
    Q = lo + rng.uniform(0.05, 0.95, (400, 5)) * (hi - lo)
    # a quarter with J3 at its upper limit (where transfers fold the arm): the shifted pose
    # breaks it in every arm configuration
    Q[300:, 2] = hi[2] - rng.uniform(0.0, 0.01, 100)
    turned = none_in_batch = 0
    for q in Q:
        T = rv2aj.fk(q)
        # tilt the orientation a little out of the arm plane half of the time
        if rng.uniform() < 0.5:
            a = rng.normal(size=3)
            a *= rng.uniform(0.02, 0.3) / np.linalg.norm(a)
            T[:3, :3] = axis_angle(a / np.linalg.norm(a), np.linalg.norm(a)) @ T[:3, :3]
        T[:3, 3] += rng.uniform(-0.01, 0.01, 3)
        q_ref = q + rng.normal(scale=0.05, size=5)
        res = rv2aj.ik(T, q_ref)
        if not res.ok and res.nearest_T_base_tool is not None:
            turned += 1
            res = rv2aj.ik(res.nearest_T_base_tool, q_ref)
        if not res.ok:
            res = rv2aj.ik(T, q_ref, position_only=True)
        got, why = _end_joints(rv2aj, T, q_ref)
        if res.ok:
            assert why == ""
            assert np.allclose(got, res.best(q_ref), atol=1e-12)
        else:
            assert got is None and why == res.message
        cands = rv2aj.ik_candidates_batch(T[None])
        if cands.exact[0] and not cands.valid[0].any():
            none_in_batch += 1
            pose = rv2aj.ik(T, q_ref)
            assert not pose.ok
            if pose.nearest_T_base_tool is not None:
                assert not rv2aj.ik(pose.nearest_T_base_tool, q_ref).ok
    assert turned > 50 and none_in_batch > 20


def test_compiled_joint_interpolation_is_the_numpy_one(rv2aj):
    """`joint_interpolation` (compiled, `joint_steps`) against its numpy form to the bit:
    long and short moves (one step), several step sizes, a move that stands still."""
    from assistant.trajectory.assemble import _joint_interpolation_numpy, joint_interpolation

    rng = np.random.default_rng(6)
    counts = set()
    for k in range(300):
        a = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper)
        b = a + rng.normal(0.0, 1.0, 5) * rng.uniform(0.0, 1.0) ** 3 if k else a.copy()
        step = float(rng.choice([0.002, 0.005, 0.01, 0.05]))
        got = joint_interpolation(rv2aj, a, b, step)
        want = _joint_interpolation_numpy(rv2aj, a, b, step)
        # the step count is an integer (random moves: no ties); 1e-14 rad: a + k/n (b - a)
        # on joints of a few rad, a few ULPs where FMA may contract the product
        assert got.shape == want.shape
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)
        counts.add(min(len(got), 3))
    assert counts == {2, 3}  # one step and several
