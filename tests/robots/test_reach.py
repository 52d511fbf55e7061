"""The arm's reach sphere: centred on the shoulder, as large as the farthest TCP position, and
what it says about a target (how far beyond)."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.robots.reach import arm_reach, reach_note
from assistant.robots.rv2aj import RV2AJ

#: The ascent stops on L-BFGS-B's tolerance: 0.1 mm is far below anything the page shows.
TOL = 1e-4


def test_rv2aj_reach_is_the_stretched_arm() -> None:
    robot = RV2AJ()
    reach = arm_reach(robot)
    # The shoulder (J2) sits on J1's axis 300 mm above the base.
    assert np.allclose(reach.centre_base, [0.0, 0.0, 0.3], atol=1e-9)
    # Straight up, the arm is stretched: the farthest any TCP gets from the shoulder (the
    # triangle inequality along the links bounds every other configuration by it).
    stretched = float(np.linalg.norm(robot.fk(np.zeros(robot.dof))[:3, 3] - [0, 0, 0.3]))
    assert abs(reach.radius - stretched) < TOL
    # Remembered: the second call returns the same object (nothing computed again).
    assert arm_reach(robot) is reach


def test_a_longer_tool_reaches_farther() -> None:
    robot = RV2AJ()
    T = np.eye(4)
    T[2, 3] = 0.1
    tooled = robot.with_tool(T)
    assert arm_reach(tooled).radius > arm_reach(robot).radius + 0.1 - TOL


def test_beyond_says_how_far_and_ik_agrees() -> None:
    robot = RV2AJ()
    reach = arm_reach(robot)
    up = reach.centre_base + [0.0, 0.0, reach.radius + 0.12]
    assert abs(reach.beyond(up) - 0.12) < 1e-9
    T = np.eye(4)
    T[:3, 3] = up
    assert not robot.ik(T).ok  # beyond the sphere: refused for every orientation
    assert reach.beyond(reach.centre_base) == pytest.approx(-reach.radius)
    # In the world: the base 1 m along x.
    T_world_base = np.eye(4)
    T_world_base[0, 3] = 1.0
    assert abs(reach.beyond_world(up + [1.0, 0.0, 0.0], T_world_base) - 0.12) < 1e-9
    # The words for the operator: millimetres, and nothing when the point is within reach.
    assert reach_note(robot, up) == \
        f"120 mm beyond the arm's reach ({reach.radius * 1000:.0f} mm from the shoulder)"
    assert reach_note(robot, reach.centre_base + [0.1, 0.0, 0.0]) == ""


def test_ur5_reach_bounds_every_sample(ur5) -> None:
    reach = arm_reach(ur5)
    # J1 is the base z axis; the shoulder (J2's origin, 135.85 mm off that axis) is projected
    # onto it at its height (89.159 mm in the UR5's URDF).
    assert np.allclose(reach.centre_base, [0.0, 0.0, 0.089159], atol=1e-6)
    lo, hi = ur5.limits.lower, ur5.limits.upper
    Q = lo + np.random.default_rng(7).random((20_000, ur5.dof)) * (hi - lo)
    d = np.linalg.norm(ur5.batch_fk(Q).positions - reach.centre_base, axis=1)
    # No configuration the estimate did not see gets farther (by more than the tolerance) ...
    assert d.max() <= reach.radius + TOL
    # ... and the sphere is no larger than the chain of link lengths allows.
    frames = ur5.link_poses(np.zeros(ur5.dof))[:, :3, 3]
    chain = np.linalg.norm(np.diff(frames[2:], axis=0), axis=1).sum()
    tcp = ur5.fk(np.zeros(ur5.dof))[:3, 3]
    bound = np.linalg.norm(frames[2] - reach.centre_base) + chain + \
        np.linalg.norm(tcp - frames[-1])
    assert reach.radius <= bound + 1e-9

