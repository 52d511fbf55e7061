"""The RV-2AJ's batched IK candidates stand in for `ik` pose by pose, and `follow_poses` gives
the same joints and failures with them as with the scalar IK alone."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from assistant.robots.model import Tool
from assistant.robots.rv2aj import RV2AJ, RV2AJConfig
from assistant.trajectory.cartesian_follow import follow_poses, poses_from, slerp_rotations
from assistant.transforms import (
    axis_angle,
    axis_angle_batch,
    pose_from_xyz_rpy,
    rot_y,
    rot_y_batch,
    rot_z,
    rot_z_batch,
    rotation_angle,
)


def _poses(robot: RV2AJ, rng: np.random.Generator, n: int) -> np.ndarray:
    """Reachable poses tilted off the arm plane, J6 around +-180 deg (two copies), and
    poses out of reach."""
    Q = rng.uniform(robot.limits.lower, robot.limits.upper, size=(n, 5))
    Q[: n // 4, 4] = rng.choice([-1.0, 1.0], n // 4) * np.radians(rng.uniform(165, 195, n // 4))
    T = np.array([robot.fk(q) for q in Q])
    tilt = n // 2
    for k in range(n // 4, tilt):  # a turn about a random axis: off the arm plane
        turn = pose_from_xyz_rpy([0, 0, 0], rng.uniform(-0.4, 0.4, 3))[:3, :3]
        T[k, :3, :3] = turn @ T[k, :3, :3]
    T[tilt : tilt + n // 8, :3, 3] *= 3.0  # out of reach
    return T


def test_candidates_are_the_scalar_ik_solutions(rv2aj, rng):
    T = _poses(rv2aj, rng, 400)
    c = rv2aj.ik_candidates_batch(T)
    assert c is not None and c.exact.all()
    for i, Ti in enumerate(T):
        res = rv2aj.ik(Ti)
        if res.nearest_T_base_tool is not None:  # ORIENTATION: the batch projected it
            assert c.projected[i]
            want = res.nearest_T_base_tool
            assert c.angle[i] == pytest.approx(
                rotation_angle(want[:3, :3].T @ Ti[:3, :3]), abs=1e-9)
            res = rv2aj.ik(want)
        else:
            assert not c.projected[i]
        got = c.joints[i][c.valid[i]]
        assert len(got) == len(res.solutions), i
        for q in res.solutions:
            assert np.abs(got - q).max(axis=1).min() < 1e-12
    # The sample has every kind: projected, unreachable, and J6 with two copies.
    assert c.projected.any() and (~c.valid.any(axis=1)).any()
    assert (c.valid.sum(axis=1) > 2).any()


def test_candidates_give_the_scalar_ik_reason_for_no_solution(rv2aj, rng):
    """Where the batch finds no solution, its reason is `ik`'s message word for word (out
    of reach, or the limits the first two arm configurations break), for the pose `ik`
    answers last (turned into the arm plane if needed)."""
    T = _poses(rv2aj, rng, 400)
    c = rv2aj.ik_candidates_batch(T)
    kinds = set()
    for i in np.flatnonzero(~c.valid.any(axis=1)):
        res = rv2aj.ik(T[i])
        if res.nearest_T_base_tool is not None:
            res = rv2aj.ik(res.nearest_T_base_tool)
        assert not res.ok
        assert c.reason(i, T[i], rv2aj.limits, rv2aj.joint_names) == res.message
        kinds.add(res.failure)
    assert len(kinds) == 2  # both reasons were compared


def test_off_axis_tool_and_j1_axis_poses_are_left_to_the_scalar_ik():
    skew = RV2AJ().with_tool(pose_from_xyz_rpy([0.01, 0.0, 0.1], [0.0, 0.0, 0.0]))
    assert skew.ik_candidates_batch(np.eye(4)[None]) is None
    robot = RV2AJ(RV2AJConfig(tool=Tool.straight(0.1)))
    on_axis = robot.fk(np.zeros(5))  # straight up: the TCP is on the J1 axis
    assert not robot.ik_candidates_batch(on_axis[None]).exact[0]


class _ScalarOnly:
    """The same robot without the batch: follow_poses takes the scalar IK for every pose."""

    def __init__(self, robot):
        self._robot = robot

    def __getattr__(self, name):
        if name == "ik_candidates_batch":
            raise AttributeError(name)
        return getattr(self._robot, name)


def _random_move(robot: RV2AJ, rng: np.random.Generator, n: int):
    """A straight TCP move of n poses from a random posture q0 to another one's pose."""
    q0 = rng.uniform(robot.limits.lower, robot.limits.upper)
    T0, T1 = robot.fk(q0), robot.fk(rng.uniform(robot.limits.lower, robot.limits.upper))
    u = np.linspace(0.0, 1.0, n)
    pts = T0[:3, 3] + u[:, None] * (T1[:3, 3] - T0[:3, 3])
    return q0, poses_from(pts, slerp_rotations(T0[:3, :3], T1[:3, :3], u))


def _assert_same_follow(a, b) -> None:
    assert (a.ok, a.fail_index, a.message) == (b.ok, b.fail_index, b.message)
    assert a.joints.shape == b.joints.shape
    assert np.abs(a.joints - b.joints).max(initial=0.0) < 1e-12
    assert a.max_orientation_correction == pytest.approx(b.max_orientation_correction, abs=1e-9)


@pytest.mark.parametrize("project", [True, False])
def test_follow_poses_is_the_same_with_the_batch(rv2aj, rng, project):
    scalar = _ScalarOnly(rv2aj)
    fails = 0
    for _ in range(60):
        q0, poses = _random_move(rv2aj, rng, 40)
        a = follow_poses(rv2aj, poses, q0, max_joint_step=0.1, project_orientation=project)
        b = follow_poses(scalar, poses, q0, max_joint_step=0.1, project_orientation=project)
        _assert_same_follow(a, b)
        fails += not a.ok
    # Both outcomes were compared (unprojected, the turned orientations fail at once).
    assert 0 < fails < 60 if project else fails == 60


class _Patchy:
    """The robot with a batch that cannot answer every third pose: follow_poses switches
    between the compiled walk and the scalar IK within one move, both ways."""

    def __init__(self, robot):
        self._robot = robot

    def ik_candidates_batch(self, T):
        c = self._robot.ik_candidates_batch(T)
        exact = c.exact.copy()
        exact[1::3] = False
        return replace(c, exact=exact)

    def __getattr__(self, name):
        return getattr(self._robot, name)


def test_follow_poses_resumes_the_walk_after_a_scalar_pose(rv2aj, rng):
    scalar, patchy = _ScalarOnly(rv2aj), _Patchy(rv2aj)
    fail_at = []
    for _ in range(60):
        q0, poses = _random_move(rv2aj, rng, 30)
        a = follow_poses(patchy, poses, q0, max_joint_step=0.1)
        b = follow_poses(scalar, poses, q0, max_joint_step=0.1)
        _assert_same_follow(a, b)
        if not a.ok and a.fail_index:
            fail_at.append(a.fail_index)
    # Failures in both places: at poses the walk handles and at poses the scalar IK does.
    assert {i % 3 == 1 for i in fail_at} == {True, False}


def test_batched_rotations_equal_the_single_ones(rng):
    angles = rng.uniform(-4.0, 4.0, 50)
    axes = rng.normal(size=(50, 3)) * rng.uniform(0.1, 3.0, (50, 1))
    axes[0] = 0.0  # no axis: identity, as axis_angle
    assert np.allclose(rot_y_batch(angles), [rot_y(a) for a in angles], atol=1e-15)
    assert np.allclose(rot_z_batch(angles), [rot_z(a) for a in angles], atol=1e-15)
    assert np.allclose(axis_angle_batch(axes, angles),
                       [axis_angle(k, a) for k, a in zip(axes, angles, strict=True)],
                       atol=1e-14)
