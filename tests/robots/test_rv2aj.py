"""The built-in RV-2AJ: FK check poses, batch FK, closed-form IK with honest failures."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.robots.model import IKFailure, Tool
from assistant.robots.rv2aj import RV2AJ, RV2AJConfig
from assistant.transforms import pose_from_xyz_rpy, rotation_angle


def test_check_poses_of_the_thesis_are_hit_exactly():
    robot = RV2AJ()
    assert np.allclose(robot.fk(np.zeros(5))[:3, 3], [0.0, 0.0, 0.782], atol=1e-12)
    q = np.radians([0.0, 0.0, 90.0, 0.0, 0.0])
    assert np.allclose(robot.fk(q)[:3, 3], [0.232, 0.0, 0.550], atol=1e-12)


def test_datasheet_limits_and_speeds_are_the_defaults_and_configurable():
    robot = RV2AJ()
    assert np.allclose(np.degrees(robot.limits.lower), [-150, -60, -110, -90, -200])
    assert np.allclose(np.degrees(robot.limits.upper), [150, 120, 120, 90, 200])
    assert np.all(robot.limits.velocity > 0)
    narrow = RV2AJ(RV2AJConfig(limits_deg=((-10, 10),) * 5))
    assert np.allclose(np.degrees(narrow.limits.upper), 10)
    assert robot.description_hash() != narrow.description_hash()


@pytest.mark.parametrize("tool", [None, "straight", "skew"])
def test_batch_fk_equals_single_fk(tool, rng):
    robot = RV2AJ()
    if tool == "straight":
        robot = robot.with_tool(Tool.straight(0.1))
    elif tool == "skew":
        robot = robot.with_tool(pose_from_xyz_rpy([0.01, -0.02, 0.12], [0.3, -0.2, 0.1]))
    Q = rng.uniform(robot.limits.lower, robot.limits.upper, size=(500, 5))
    single = np.array([robot.fk(q) for q in Q])
    batch = robot.batch_fk(Q)
    assert np.allclose(batch.positions, single[:, :3, 3], atol=1e-12)
    assert np.allclose(batch.rotations, single[:, :3, :3], atol=1e-12)
    b32 = robot.batch_fk(Q, dtype=np.float32)
    assert np.allclose(b32.positions, single[:, :3, 3], atol=1e-5)


def test_ik_round_trip_returns_every_branch_and_the_original(rv2aj, rng):
    Q = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, size=(300, 5))
    branches = []
    for q in Q:
        T = rv2aj.fk(q)
        res = rv2aj.ik(T)
        assert res.ok, res.message
        branches.append(len(res.solutions))
        for s in res.solutions:
            assert rv2aj.limits.contains(s)
            assert np.allclose(rv2aj.fk(s), T, atol=1e-9)
        assert min(np.linalg.norm(s - q) for s in res.solutions) < 1e-7
    # Several branches exist (elbow up/down, J1 flipped, J6 +-360) for many poses.
    assert max(branches) >= 4
    # Solutions are distinct.
    res = rv2aj.ik(rv2aj.fk(Q[0]))
    sols = np.array(res.solutions)
    d = np.linalg.norm(sols[:, None] - sols[None], axis=-1)
    assert np.all(d[~np.eye(len(sols), dtype=bool)] > 1e-6)


def test_ik_seed_orders_solutions(rv2aj):
    q = np.radians([20.0, 30.0, 60.0, 40.0, 10.0])
    res = rv2aj.ik(rv2aj.fk(q), seed=q + 0.01)
    assert np.allclose(res.solutions[0], q, atol=1e-9)
    assert np.allclose(res.best(q), q, atol=1e-9)


def test_orientation_out_of_the_arm_plane_is_refused_with_the_nearest_reachable(rv2aj):
    q = np.radians([30.0, 20.0, 70.0, 50.0, 0.0])
    T = rv2aj.fk(q)
    # Tilt the approach sideways by 15 degrees about the radial axis.
    radial = np.array([np.cos(np.radians(30)), np.sin(np.radians(30)), 0.0])
    from assistant.transforms import axis_angle

    T_bad = T.copy()
    T_bad[:3, :3] = axis_angle(radial, np.radians(15)) @ T[:3, :3]
    res = rv2aj.ik(T_bad)
    assert not res.ok
    assert res.failure == IKFailure.ORIENTATION
    assert "5 axes" in res.message
    near = res.nearest_T_base_tool
    assert near is not None
    assert np.allclose(near[:3, 3], T_bad[:3, 3], atol=1e-9)  # the TCP stays put
    # The smallest correction is the angle between the approach vector and the arm plane,
    # never more than the 15 degrees we tilted.
    normal = np.array([-radial[1], radial[0], 0.0])
    smallest = np.arcsin(abs(T_bad[:3, 2] @ normal))
    assert rotation_angle(near[:3, :3].T @ T_bad[:3, :3]) == pytest.approx(smallest, abs=1e-6)
    assert smallest <= np.radians(15)
    fixed = rv2aj.ik(near)
    assert fixed.ok
    assert np.allclose(rv2aj.fk(fixed.solutions[0]), near, atol=1e-8)


def test_unreachable_point_says_reach():
    robot = RV2AJ()
    T = pose_from_xyz_rpy([0.9, 0.0, 0.3], [0.0, np.pi / 2, 0.0])
    res = robot.ik(T)
    assert res.failure == IKFailure.REACH
    assert "reach" in res.message
    with pytest.raises(ValueError, match="reach"):
        res.best()


def test_joint_limit_failure_names_the_joint():
    robot = RV2AJ(RV2AJConfig(limits_deg=((-10, 10), (-60, 120), (-110, 120), (-90, 90),
                                          (-200, 200))))
    q = np.radians([60.0, 20.0, 70.0, 50.0, 0.0])
    T = RV2AJ().fk(q)
    res = robot.ik(T)
    assert res.failure == IKFailure.JOINT_LIMIT
    assert "J1" in res.message


def test_position_only_ik_puts_the_tcp_on_the_point(rv2aj, rng):
    for q in rng.uniform(rv2aj.limits.lower * 0.8, rv2aj.limits.upper * 0.8, size=(20, 5)):
        p = rv2aj.fk(q)[:3, 3]
        res = rv2aj.ik(rv2aj.fk(q), position_only=True)
        assert res.ok, res.message
        for s in res.solutions:
            assert np.allclose(rv2aj.fk(s)[:3, 3], p, atol=1e-7)
            assert rv2aj.limits.contains(s)


def test_arm_radii_bound_the_motion_of_every_point(rv2aj, rng):
    """A joint step moves no TCP or link point more than sum(r_i |dq_i|)."""
    r = rv2aj.arm_radii()
    for _ in range(200):
        q0 = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper)
        dq = rng.normal(scale=0.05, size=5)
        bound = float(np.sum(r * np.abs(dq)))
        moved = np.linalg.norm(rv2aj.fk(q0 + dq)[:3, 3] - rv2aj.fk(q0)[:3, 3])
        assert moved <= bound + 1e-12
        F0, F1 = rv2aj.link_poses(q0), rv2aj.link_poses(q0 + dq)
        for li, link in enumerate(rv2aj.links):
            for s in link.collision:
                c0 = (F0[li] @ s.T_link_shape)[:3, 3]
                c1 = (F1[li] @ s.T_link_shape)[:3, 3]
                assert np.linalg.norm(c1 - c0) <= bound + 1e-12


def test_urdf_has_one_revolute_joint_per_axis():
    text = RV2AJ().urdf()
    assert text.count('type="revolute"') == 5
    for name in ("J1", "J2", "J3", "J5", "J6"):
        assert f'name="{name}"' in text


def test_pinocchio_model_agrees_with_the_closed_form(rv2aj, rng):
    import pinocchio as pin

    model = rv2aj.pinocchio_model
    data = model.createData()
    fid = model.getFrameId("tool")
    for q in rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, size=(50, 5)):
        pin.framesForwardKinematics(model, data, q)
        assert np.allclose(data.oMf[fid].homogeneous, rv2aj.fk(q), atol=1e-9)


def _numpy_chain_frames(chain, q):
    """`dh.chain_frames` as numpy operations, before it used the compiled loop."""
    n = len(chain.rows)
    out = np.empty((n + 1, 4, 4))
    out[0] = np.eye(4)
    cs, sn = np.cos(q), np.sin(q)
    T = out[0]
    for i in range(n):
        Ti = T.copy()
        Ti[:, 0] = cs[i] * T[:, 0] + sn[i] * T[:, 1]
        Ti[:, 1] = -sn[i] * T[:, 0] + cs[i] * T[:, 1]
        out[i + 1] = Ti
        T = Ti @ chain.fixed_parts[i]
    return out


def test_single_pose_frames_are_the_numpy_chains_to_the_bit(rv2aj, rng):
    """The single-configuration frames (FK, link poses) come from the compiled batch loop:
    the batch's, and the numpy product chain they replaced (to the bit on our machine;
    to 1e-15 here, as numpy's 4x4 product or the compiled loop may use FMA elsewhere)."""
    from assistant.robots.dh import chain_frames

    Q = rng.uniform(rv2aj.limits.lower - 0.5, rv2aj.limits.upper + 0.5, (500, 5))
    batch = rv2aj.batch_link_poses(Q)
    for q, frames in zip(Q, batch, strict=True):
        single = chain_frames(rv2aj.chain, q)
        assert np.allclose(single, _numpy_chain_frames(rv2aj.chain, q), rtol=0, atol=1e-15)
        # the same compiled chain for one row or a batch: 1e-15 (a few ULPs of 1), as the
        # batch loop may be vectorised with a differently contracted remainder loop
        np.testing.assert_allclose(single, frames, rtol=0, atol=1e-15)
    assert np.allclose(chain_frames(rv2aj.chain, [0, 0, 0, 0, 0]),
                       _numpy_chain_frames(rv2aj.chain, np.zeros(5)), rtol=0, atol=1e-15)
