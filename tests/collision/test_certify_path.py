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


def test_a_face_plane_clears_a_row_only_where_fcl_finds_the_pair_apart(exact):
    """`_outside_box` (every vertex beyond one face plane of a box) on uniform postures, for
    every robot shape against each box obstacle without a margin and against the box that
    holds every other robot shape: wherever it clears a row, FCL's distance is positive;
    and it clears many rows (what saves the FCL tests). FCL's distance of the closest
    cleared pair is above its own tolerance (the plane's gap is > 1 um by construction)."""
    import fcl

    from assistant.collision.certify_path import (
        _corners,
        _pair_apart,
        _Poser,
        beyond_a_face,
    )

    robot = exact.robot
    rng = np.random.default_rng(9)
    Q = np.ascontiguousarray(rng.uniform(robot.limits.lower, robot.limits.upper,
                                         size=(60, robot.dof)))
    frames = np.ascontiguousarray(exact._link_frames(Q), dtype=float)
    pose = _Poser(exact, frames)
    rows = np.arange(len(Q))
    cleared = checked = 0
    for s in range(len(exact._rshapes)):
        if _corners(exact)[s] is None or exact._rshapes[s].link == 0:
            continue
        for e, es in enumerate(exact._env):
            free = beyond_a_face(exact, frames, rows, s, e)
            assert not free.any() or exact._env_exact[e]  # boxes without a margin only
            for k in np.flatnonzero(free):
                d = fcl.distance(pose(s, int(k)), es.obj, exact._dreq, fcl.DistanceResult())
                assert d > 0.0, (s, e, int(k), d)
            cleared += int(free.sum())
            checked += len(rows)
    for a, b in exact._self_pairs:
        free = _pair_apart(exact, frames, rows, a, b)
        for k in np.flatnonzero(free):
            assert not pose.pair_touches(a, b, int(k)), (a, b, int(k))
            d = fcl.distance(pose(a, int(k)), pose(b, int(k)), exact._dreq,
                             fcl.DistanceResult())
            assert d > 0.0, (a, b, int(k), d)
        cleared += int(free.sum())
        checked += len(rows)
    assert cleared > checked // 4, (cleared, checked)


def test_a_path_above_the_table_is_certified_without_fcl_tests_of_the_table(exact,
                                                                          monkeypatch):
    """A UR5 / Panda path whose links pass the table closely but above it: the table rows
    are cleared by its top face plane, not by FCL (before: one FCL test or distance per
    sample of each such link); a path into the table is still refused where brute-force
    FCL first finds it touching."""
    import assistant.collision.certify_path as cp

    robot = exact.robot
    exact = CollisionChecker(robot, _cell(robot)[:1]).exact_only()  # the table alone
    table = exact.obstacle_names.index("table")
    asked: list[int] = []
    real_touch, real_dist = cp._env_touches, cp._env_distance

    def touches(checker, pose, k, i, es):
        asked.append(checker._env.index(es))
        return real_touch(checker, pose, k, i, es)

    def distance(checker, pose, k, i, es):
        asked.append(checker._env.index(es))
        return real_dist(checker, pose, k, i, es)

    monkeypatch.setattr(cp, "_env_touches", touches)
    monkeypatch.setattr(cp, "_env_distance", distance)
    from assistant.session.home import raised_posture

    q0 = raised_posture(robot)  # a UR's shoulder and upper arm 30 mm above the table
    q1 = q0.copy()
    q1[0] = 1.5
    path = np.array([q0, q1])
    S, F, _ = exact._path_samples(path, None)
    Qs = path[S] + F[:, None] * (path[np.minimum(S + 1, 1)] - path[S])
    truth = [exact.in_collision_naive(q) for q in Qs]
    assert not any(truth)
    assert first_contact(exact, path) is None
    assert table not in asked, asked
    # lowered into the table: refused at brute force's first touching sample
    down = q1.copy()
    down[1] = 1.0 if robot.dof == 6 else 1.7
    path = np.array([q1, down])
    S, F, _ = exact._path_samples(path, None)
    Qs = path[S] + F[:, None] * (path[np.minimum(S + 1, 1)] - path[S])
    truth = np.array([exact.in_collision_naive(q) for q in Qs])
    assert truth.any()
    assert first_contact(exact, path) == int(np.argmax(truth))


def test_the_face_plane_fallback_agrees_with_the_kernel():
    """`face_planes.vertices_beyond`'s numpy fallback (run while the kernel is compiled in
    the background) clears the same rows: random boxes and point sets placed so that about
    half the rows are cleared; rows within 1e-9 m of the slack are left out (the two sum
    the same products in another order, rounding ~1e-16 m)."""
    from scipy.spatial.transform import Rotation

    from assistant.collision.face_planes import vertices_beyond, vertices_beyond_numpy

    rng = np.random.default_rng(5)
    n = 400
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = Rotation.random(n, random_state=1).as_matrix()
    T[:, :3, 3] = rng.uniform(-0.6, 0.6, size=(n, 3))
    Rb = Rotation.random(n, random_state=2).as_matrix()
    cb = rng.uniform(-0.1, 0.1, size=(n, 3))
    h = np.array([0.2, 0.15, 0.1])
    V = rng.normal(scale=0.08, size=(300, 3))
    got, ref = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    vertices_beyond(T, Rb, cb, h, V, 1e-6, got)
    vertices_beyond_numpy(T, Rb, cb, h, V, 1e-6, ref)
    assert 0.2 * n < int(ref.sum()) < 0.8 * n
    Y = np.einsum("nij,kj->nik", np.swapaxes(Rb, 1, 2) @ T[:, :3, :3], V) + np.einsum(
        "nji,nj->ni", Rb, T[:, :3, 3] - cb)[:, :, None]
    gap = np.concatenate([Y.min(axis=2) - h, -Y.max(axis=2) - h], axis=1).max(axis=1)
    clear = np.abs(gap - 1e-6) > 1e-9
    assert np.array_equal(got[clear], ref[clear])
