"""Teach and plan share one self-collision/obstacle truth per arm.

Over every arm of the suite (UR3/5/10, Panda, SO-100 from example-robot-data, every arm of
the robot catalogue - KUKA KR 6 R900 sixx, ABB IRB 1200, FANUC LR Mate 200iD - and the
built-in RV-2AJ): poses of random postures are taught
through the session, then handed to the planner's start/goal check (`MissionPlanner._solve`,
the call `plan_mission` makes) with the cell's objects. A pose teach accepts silently the
planner solves; one teach refuses (the arm touches itself in every posture) the planner
calls a self-collision, naming the same links in the same words; one teach keeps with a
warning (inside a cell object) the planner calls in collision.
"""

from __future__ import annotations

import numpy as np
import pytest

from assistant.planning import MissionPlanner
from assistant.planning.locations import LocationError, LocationProblem
from assistant.robots.catalog import CATALOG, RobotSpec, ToolSpec, installed_robot_urdf
from assistant.session import Session
from assistant.session.events import Notice
from assistant.session.types import SessionError
from assistant.transforms import make_T

ERD = "example-robot-data/robots/"
ARMS = {
    "UR3": ("ur_description/urdf/ur3_robot.urdf", None),
    "UR5": ("ur_description/urdf/ur5_robot.urdf", None),
    "UR10": ("ur_description/urdf/ur10_robot.urdf", None),
    "Panda": ("panda_description/urdf/panda.urdf", "panda_hand"),
    "SO-100": ("so_arm_description/urdf/so100.urdf", None),  # as the set-up page loads it
    "RV-2AJ": (None, None),
    **{key: (None, None) for key in CATALOG},  # the industrial arms of the robot catalogue
}
POSTURES = 10


def arm_spec(name: str) -> RobotSpec:
    rel, tool_link = ARMS[name]
    tool = ToolSpec.straight(0.06 if name == "SO-100" else 0.1, 0.015)
    if name == "RV-2AJ":
        return RobotSpec(kind="rv2aj", tool=tool)
    if name in CATALOG:
        return RobotSpec(kind=name, tool=tool)
    urdf, share = installed_robot_urdf(ERD + rel)
    return RobotSpec(kind="urdf", urdf_path=str(urdf), package_dirs=(str(share),),
                     tool_link=tool_link, tool=tool)


def session_with(tmp_path, name: str) -> Session:
    s = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                            with_mission=False)
    s.goto("setup")
    s.choose_robot(arm_spec(name))
    return s


@pytest.mark.parametrize("arm", list(ARMS))
def test_what_teach_accepts_plan_accepts(tmp_path, arm):
    s = session_with(tmp_path, arm)
    robot = s.robot
    reach = float(np.max(np.linalg.norm(robot.batch_fk(
        np.random.default_rng(0).uniform(robot.limits.lower, robot.limits.upper,
                                         (200, robot.dof))).positions, axis=1)))
    s.goto("cad")
    # a post beside the arm: some postures reach through it
    s.add_primitive("box", (0.2 * reach, 0.2 * reach, 2.0 * reach), name="post",
                    T_world_object=make_T(np.eye(3), s.T_world_base()[:3, 3]
                                          + [0.45 * reach, 0.0, reach]))
    s.goto("teach.locations")
    notices: list[str] = []
    s.bus.subscribe(lambda ev: notices.append(ev.message) if isinstance(ev, Notice) else None)
    planner = MissionPlanner(robot, s.cell.collision_objects_in_base(), None, None)
    rng = np.random.default_rng(58)
    verdicts = {"accepted": 0, "refused": 0, "warned": 0}
    for k in range(POSTURES):
        q = rng.uniform(robot.limits.lower, robot.limits.upper)
        T = s.T_world_base() @ robot.fk(q)
        name = f"P{k}"
        before = len(notices)
        try:
            loc = s.teach(name, T)
        except SessionError as exc:
            verdicts["refused"] += 1
            assert "would touch itself" in str(exc)
            with pytest.raises(LocationError) as planned:
                planner._solve(_location(name, T), s.T_world_base(), s.current_joints())
            assert planned.value.problem == LocationProblem.SELF_COLLISION
            continue
        warned = [m for m in notices[before:] if "inside an obstacle" in m]
        if warned:
            verdicts["warned"] += 1
            with pytest.raises(LocationError) as planned:
                planner._solve(loc, s.T_world_base(), s.current_joints())
            assert planned.value.problem == LocationProblem.IN_COLLISION
            assert str(planned.value) in warned[0]
            continue
        verdicts["accepted"] += 1
        assert planner.checker.is_valid(loc.q_hint)
        # the planner from elsewhere: another seed, the taught posture only as a fallback
        solved = planner._solve(loc, s.T_world_base(), np.zeros(robot.dof)
                                if robot.limits.contains(np.zeros(robot.dof))
                                else robot.limits.lower + 0.5 * (robot.limits.upper
                                                                 - robot.limits.lower))
        assert planner.checker.is_valid(solved.q)
    assert verdicts["accepted"] > 0, verdicts


def _location(name, T):
    from assistant.mission.model import Location

    return Location(name, T)


def test_teach_refuses_a_self_colliding_pose_in_operator_words(tmp_path):
    """A UR5 posture whose forearm lies in its upper arm: every IK solution of that pose
    self-collides (checked here), so teach refuses it, naming the links as J-links."""
    s = session_with(tmp_path, "UR5")
    robot = s.robot
    planner = MissionPlanner(robot, [], None, None)
    rng = np.random.default_rng(3)
    for _ in range(400):
        q = rng.uniform(robot.limits.lower, robot.limits.upper)
        res = robot.ik(robot.fk(q), q)
        if res.ok and not planner.checker.is_valid_batch(np.array(res.solutions)).any():
            break
    else:
        pytest.fail("no pose of a self-colliding UR5 posture in 400 samples")
    s.goto("cad")
    s.add_primitive("box", (0.1, 0.1, 0.1), T_world_object=make_T(np.eye(3), [2.0, 2.0, 0.05]))
    s.goto("teach.locations")
    with pytest.raises(SessionError, match=r"would touch itself .*the J\d link"):
        s.teach("A", s.T_world_base() @ robot.fk(q))
    assert "A" not in s.locations
