"""What a Collision! teaches a 6- or 7-axis arm (`world.contact_region`): on a real UR5 and
Panda from example-robot-data, the arm driven by a straight joint move into a box (real FCL
finds the contact; the arm stops at the last free sample, as the simulated robot does).

The learnt region holds neither the arm at the start of the last step nor a protected
posture's arm, holds the arm at the stop, lies at the box, and grows on a repeat."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import Obstacle
from assistant.robots.catalog import installed_robot_urdf
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.robots.urdf_robot import URDFRobot
from assistant.world.contact_region import RegionConfig, carve, grown, learn_region
from assistant.world.region_checks import RegionChecks

ARMS = {
    "ur5": ("example-robot-data/robots/ur_description/urdf/ur5_robot.urdf", "tool0",
            [0.6, -1.2, 1.4, -1.8, -1.57, 0.0], [-0.6, -1.2, 1.4, -1.8, -1.57, 0.0]),
    "panda": ("example-robot-data/robots/panda_description/urdf/panda.urdf", "panda_hand",
              [0.7, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8], [-0.7, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]),
}
CFG = RegionConfig()
BOX = 0.05


@pytest.fixture(scope="module", params=sorted(ARMS))
def arm(request):
    path, tool, qa, qb = ARMS[request.param]
    urdf, share = installed_robot_urdf(path)
    robot = URDFRobot.from_file(urdf, package_dirs=[share], load_visual=False, tool_link=tool)
    return robot, np.array(qa), np.array(qb)


def drive_into(robot, qa, qb, p):
    """The postures of the straight move qa -> qb up to the last free sample before the box
    at p, and the box's obstacle."""
    T = np.eye(4)
    T[:3, 3] = p
    box = Obstacle("box", T, (CollisionShape(ShapeKind.BOX, (BOX,) * 3),))
    mc = CollisionChecker(robot, [box]).check_motion(qa, qb)
    assert not mc.valid
    f = max(0.0, float(mc.first_invalid_fraction) - 1.0 / mc.samples)
    return qa + np.linspace(0.0, f, 60)[:, None] * (qb - qa)


def box_distance(P, p):
    """Distance of points P from the box at p (0 inside)."""
    return np.linalg.norm(np.maximum(np.abs(P - p) - BOX / 2, 0.0), axis=1)


def test_a_contact_teaches_the_swept_region_and_not_where_the_arm_was(arm):
    robot, qa, qb = arm
    p = robot.fk((qa + qb) / 2)[:3, 3]
    approach = drive_into(robot, qa, qb, p)
    checks = RegionChecks(robot, CFG.clearance)
    region, q0 = learn_region(robot, checks.arm, approach, robot.arm_radii(), 2, CFG,
                              [("B", qb)])
    assert region is not None and len(region.centres) and not region.cut_for
    regions = [(0, region)]
    # q0 is a posture the arm drove through before the stop
    assert np.isclose(np.abs(approach - q0).max(axis=1), 0.0).any()
    assert not checks.blocked(q0, regions)[0]  # the arm at the start of the last step
    assert checks.blocked(approach[-1], regions)[0]  # the arm where it stopped
    assert not checks.blocked(qb, regions)[0]  # the goal posture's links
    # at the box: the stop is one motion sample (5 mm of arm travel) short of it, and a
    # kept centre lies within a thinning cube (10 mm, diagonal 17 mm) of the swept surface
    assert box_distance(region.centres, p).min() <= 0.005 + 0.0175
    # the region is the swept sliver, not the arm: far fewer spheres than the arm fills
    assert len(region.centres) < 400


def test_a_goal_where_the_region_would_be_stays_reachable(arm):
    robot, qa, qb = arm
    p = robot.fk((qa + qb) / 2)[:3, 3]
    approach = drive_into(robot, qa, qb, p)
    checks = RegionChecks(robot, CFG.clearance)
    goal = approach[-1]  # a taught posture right where the arm stopped
    region, _ = learn_region(robot, checks.arm, approach, robot.arm_radii(), 2, CFG,
                             [("B", goal)])
    assert region is not None and region.cut_for == ["B"] and len(region.withheld)
    assert not checks.blocked(goal, [(0, region)])[0]
    # indicated there again, the withheld part is learnt: the run can name what blocks B
    again = grown(region, region, CFG, promote=True)
    assert checks.blocked(goal, [(0, again)])[0] and not len(again.withheld)


def test_indicated_again_at_the_same_place_the_region_grows(arm):
    robot, qa, qb = arm
    p = robot.fk((qa + qb) / 2)[:3, 3]
    checks = RegionChecks(robot, CFG.clearance)
    first, _ = learn_region(robot, checks.arm, drive_into(robot, qa, qb, p),
                            robot.arm_radii(), 2, CFG, [("B", qb)])
    qa2 = qa.copy()
    qa2[1] -= 0.05  # the re-plan came the same way a little higher
    second, q0 = learn_region(robot, checks.arm, drive_into(robot, qa2, qb, p),
                              robot.arm_radii(), 2, CFG, [("B", qb)])
    assert first is not None and second is not None
    assert first.distance_to(second) <= CFG.repeat_distance  # the same place
    both = carve(checks.arm, grown(first, second, CFG), CFG, [("B", qb)])
    assert both.hits == 2 and both.radius == pytest.approx(CFG.resolution + CFG.grow)
    # everything the first region held, the grown one holds (postures all around)
    rng = np.random.default_rng(0)
    Q = np.concatenate([qa + rng.normal(0.0, 0.3, (300, len(qa))),
                        np.linspace(qa, qb, 100)])
    was = checks.blocked(Q, [(0, first)])
    now = checks.blocked(Q, [(0, both)])
    assert now[was].all() and now.sum() > was.sum()
    assert not checks.blocked(qb, [(0, both)])[0]
