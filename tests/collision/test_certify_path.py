"""The certifying check by FCL distances (`collision.certify_path`) answers as brute-force FCL."""

from __future__ import annotations

import numpy as np
import pytest
from test_fast_model import _arm, _cell

from assistant.collision.certify_path import first_contact, link_radii, shape_radii
from assistant.collision.checker import CollisionChecker


@pytest.fixture(scope="module", params=("UR5", "Panda"))
def exact(request):
    arm = _arm(request.param)
    return CollisionChecker(arm, _cell(arm)).exact_only()


def test_link_and_shape_radii_bound_every_shape_and_agree_with_the_arm_radii(exact):
    robot = exact.robot
    R = link_radii(robot)
    # the arm's radius per joint is the largest over the links it moves (both are sums of
    # the same few metre-sized norms, in another order: rounding ~1e-16 m, allowed 1e-12)
    assert np.allclose(R.max(axis=1), robot.arm_radii(), rtol=1e-12, atol=1e-12)
    rng = np.random.default_rng(2)
    for q in rng.uniform(robot.limits.lower, robot.limits.upper, size=(20, robot.dof)):
        F = robot.link_poses(q)
        for k, link in enumerate(robot.links[1:], start=1):
            for s in link.collision:
                c = (F[k] @ s.T_link_shape)[:3, 3]
                for i in range(min(k, robot.dof)):
                    # joint i's axis: through link i+1's origin, along its URDF axis
                    o = F[i + 1][:3, 3]
                    z = F[i + 1][:3, :3] @ np.asarray(robot.batch_chain.joints[i].axis, float)
                    z /= np.linalg.norm(z)
                    v = c - o
                    off = float(np.linalg.norm(v - (v @ z) * z))
                    # the shape's origin within its link's bound of the axis and its own
                    # (its points within its bounding radius of it); rounding of
                    # metre-sized poses only
                    Rs = shape_radii(robot, k, s)
                    assert Rs[i] <= R[i, k] + 1e-12
                    assert off <= Rs[i] - s.bounding_radius() + 1e-9


def test_first_contact_finds_what_brute_force_fcl_finds(exact):
    robot = exact.robot
    rng = np.random.default_rng(4)
    lim = robot.limits
    seen = {True: 0, False: 0}
    for _ in range(12):
        q0 = rng.uniform(lim.lower, lim.upper)
        while not exact.is_valid(q0):
            q0 = rng.uniform(lim.lower, lim.upper)
        q1 = np.clip(q0 + rng.normal(scale=0.6, size=robot.dof), lim.lower, lim.upper)
        path = np.array([q0, 0.5 * (q0 + q1), q1])
        k = first_contact(exact, path)
        S, F, _ = exact._path_samples(path, None)
        Q = path[S] + F[:, None] * (path[np.minimum(S + 1, len(path) - 1)] - path[S])
        truth = np.array([exact.in_collision_naive(q) for q in Q])
        want = int(np.argmax(truth)) if truth.any() else None
        assert k == want, (k, want)
        assert (exact.check_path(path) is None) == (k is None)
        seen[k is None] += 1
    assert seen[True] and seen[False], seen  # free and refused paths both


def test_the_batch_quaternions_pose_as_the_matrices_do():
    """The poser's quaternions (Shepperd's method) against scipy's, on random rotations and
    the four half-turns where each branch is taken; both are well conditioned there, so
    they agree to rounding of unit-sized numbers (1e-12), up to the sign of q."""
    from scipy.spatial.transform import Rotation

    from assistant.collision.certify_path import _quaternions

    R = np.concatenate([Rotation.random(2000, random_state=3).as_matrix(),
                        np.stack([np.eye(3), np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]),
                                  np.diag([-1.0, -1, 1])])])
    q = _quaternions(R)
    ref = Rotation.from_matrix(R).as_quat()[:, [3, 0, 1, 2]]
    err = np.minimum(np.abs(q - ref).max(axis=1), np.abs(q + ref).max(axis=1))
    assert err.max() < 1e-12
