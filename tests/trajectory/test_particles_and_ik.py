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
