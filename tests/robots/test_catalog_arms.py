"""The industrial arms shipped in the robot catalogue, against their makers' data sheets: the
flange where the dimension drawing puts it at all axes 0, the tool0 orientation the
controller reports there, the reach, limits and speeds as stated, and a clear zero posture.

These numbers are copied from the sheets into the test on purpose: a URDF edit that moves a
link or turns an axis fails here, not on a customer's controller."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.collision.checker import CollisionChecker
from assistant.robots.catalog import CATALOG, RobotSpec

#: Per arm: the flange (tool0) at all axes 0 in the base frame (mm, from the sheet's
#: dimensions), where tool0's z and x point there, the reach at the wrist centre (mm), the
#: limits (deg) and the speeds (deg/s).
SHEETS = {
    "kuka_kr6_r900_sixx": dict(
        flange=(25 + 455 + 420 + 80, 0, 400 + 35), z=(1, 0, 0), x=(0, 0, -1), reach=901.5,
        limits=[(-170, 170), (-190, 45), (-120, 156), (-185, 185), (-120, 120), (-350, 350)],
        speeds=[360, 300, 360, 381, 388, 615]),
    "abb_irb1200_5_09": dict(
        flange=(451 + 82, 0, 399 + 448 + 42), z=(1, 0, 0), x=(0, 0, -1), reach=901.0,
        limits=[(-170, 170), (-100, 135), (-200, 70), (-270, 270), (-130, 130), (-400, 400)],
        speeds=[288, 240, 297, 400, 405, 600]),
    "fanuc_lrmate200id": dict(
        flange=(50 + 335 + 80, 0, 330 + 330 + 35), z=(1, 0, 0), x=(0, 0, 1), reach=717.0,
        limits=[(-170, 170), (-100, 145), (-70, 205), (-190, 190), (-125, 125), (-360, 360)],
        speeds=[450, 380, 520, 550, 545, 1000]),
}
#: The URDFs give radians to 10 decimals: 1e-9 rad is far below it, far above float noise.
ANGLE_TOL = 1e-6
#: Positions are sums of a few mm-exact offsets through unit rotations: float noise ~1e-15 m.
POS_TOL_MM = 1e-6


@pytest.fixture(scope="module", params=sorted(SHEETS))
def arm(request):
    return request.param, RobotSpec(kind=request.param).build()


def test_every_catalogue_arm_has_its_sheet():
    assert set(CATALOG) == set(SHEETS)


def test_the_flange_is_where_the_sheet_puts_it_at_all_axes_zero(arm):
    key, robot = arm
    sheet = SHEETS[key]
    T = robot.fk(np.zeros(robot.dof))
    assert np.allclose(T[:3, 3] * 1000.0, sheet["flange"], atol=POS_TOL_MM)
    assert np.allclose(T[:3, 2], sheet["z"], atol=ANGLE_TOL)  # out of the flange
    assert np.allclose(T[:3, 0], sheet["x"], atol=ANGLE_TOL)  # as the controller reports


def test_limits_and_speeds_are_the_sheets(arm):
    key, robot = arm
    sheet = SHEETS[key]
    lo, hi = np.degrees(robot.limits.lower), np.degrees(robot.limits.upper)
    assert np.allclose(np.c_[lo, hi], sheet["limits"], atol=1e-6)
    assert np.allclose(np.degrees(robot.limits.velocity), sheet["speeds"], atol=1e-6)


def test_the_reach_is_the_sheets(arm):
    """The sheets' reach is the wrist centre's farthest horizontal distance from the J1 axis:
    the shoulder's offset plus the arm stretched from the shoulder (J2's axis), found over a
    sweep of the third joint (J2 does not change the distance from the shoulder)."""
    key, robot = arm
    bare = robot.with_tool(np.eye(4))
    offset, height = SHOULDER[key]
    q = np.zeros(robot.dof)
    best = 0.0
    for a3 in np.linspace(robot.limits.lower[2], robot.limits.upper[2], 4001):
        q[2] = a3
        T = bare.fk(q)
        wrist = T[:3, 3] - T[:3, 2] * FLANGE_M[key]  # on the flange axis, behind the flange
        best = max(best, float(np.hypot(wrist[0] - offset, wrist[2] - height)))
    # the sweep's step (0.07 deg on ~450 mm) misses the peak by < 0.01 mm; sheets round to 0.5
    assert abs((offset + best) * 1000.0 - SHEETS[key]["reach"]) < 1.0


#: J2's axis: forward of J1 and above the mounting face (m), from the sheets.
SHOULDER = {"kuka_kr6_r900_sixx": (0.025, 0.400), "abb_irb1200_5_09": (0.0, 0.399),
            "fanuc_lrmate200id": (0.050, 0.330)}
#: Wrist centre to flange (m), from the sheets.
FLANGE_M = {"kuka_kr6_r900_sixx": 0.080, "abb_irb1200_5_09": 0.082, "fanuc_lrmate200id": 0.080}


def test_the_zero_posture_is_clear_and_ik_finds_the_flange_again(arm):
    key, robot = arm
    q0 = np.radians([10, -20, 30, 15, 40, -25])
    rep = CollisionChecker(robot, []).check(q0)
    assert rep.valid, f"{key}: {rep}"
    T = robot.fk(q0)
    res = robot.ik(T, seed=q0 + 0.1)
    assert res.ok
    # IK converges to sub-micrometre; 1e-6 m is what the planner needs, far above it
    assert np.allclose(robot.fk(res.best(q0))[:3, 3], T[:3, 3], atol=1e-6)
