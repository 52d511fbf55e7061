"""URDF robots: numeric IK (round trips, seeds, failures with reasons), bad URDF input named
by file, line and element, and the RV-2AJ's own URDF against its closed form."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from urdf_builders import (
    PANDA_URDF,
    POS_TOL,
    ROT_TOL,
    _arm_urdf,
    _random_q,
)

from assistant.robots.catalog import RobotModelError
from assistant.robots.model import IKFailure, Tool
from assistant.robots.rv2aj import RV2AJ
from assistant.robots.urdf_robot import URDFRobot
from assistant.transforms import make_T, rot_x, rotation_angle


# ------------------------------------------------------------------------------ IK
@pytest.mark.parametrize("which", ["ur5", "panda"])
def test_ik_round_trip_full_pose(which, request):
    robot = request.getfixturevalue(which)
    several = 0
    for q in _random_q(robot, 6, seed=8):
        T = robot.fk(q)
        res = robot.ik(T)
        assert res.ok, res.message
        several += len(res.solutions) >= 2
        for s in res.solutions:
            assert robot.limits.contains(s)
            T_s = robot.fk(s)
            assert np.linalg.norm(T_s[:3, 3] - T[:3, 3]) < POS_TOL
            assert rotation_angle(T_s[:3, :3].T @ T[:3, :3]) < ROT_TOL
        for a in range(len(res.solutions)):
            for b in range(a):
                assert np.linalg.norm(res.solutions[a] - res.solutions[b]) > 1e-3
    assert several >= 4  # restarts find distinct configurations for most targets


@pytest.mark.parametrize("which", ["ur5", "panda"])
def test_ik_position_only(which, request):
    robot = request.getfixturevalue(which)
    for q in _random_q(robot, 6, seed=9):
        p = robot.fk(q)[:3, 3]
        res = robot.ik(make_T(rot_x(1.0), p), position_only=True)  # orientation ignored
        assert res.ok, res.message
        for s in res.solutions:
            assert robot.limits.contains(s)
            assert np.linalg.norm(robot.fk(s)[:3, 3] - p) < POS_TOL


def test_ik_with_seed_returns_the_nearby_solution_first(panda):
    q = _random_q(panda, 1, seed=10)[0]
    res = panda.ik(panda.fk(q), seed=q + 0.03)
    assert res.ok
    assert np.linalg.norm(res.solutions[0] - q) < 0.1  # 7 dof: redundant, but it stays close
    one = panda.ik(panda.fk(q), seed=q + 0.03, max_solutions=1)
    assert len(one.solutions) == 1


def test_every_ik_solution_is_the_turn_of_each_joint_nearest_the_seed(ur5):
    """A UR joint spans two turns: each solution's joints are the whole-turn equivalents
    nearest the seed that the limits allow (a location is never reached a turn away)."""
    rng = np.random.default_rng(21)
    lo, hi = ur5.limits.lower, ur5.limits.upper
    seen = 0
    for _ in range(6):
        T = ur5.fk(rng.uniform(lo, hi))
        seed = rng.uniform(-1.0, 1.0, ur5.dof)
        res = ur5.ik(T, seed=seed)
        assert res.ok
        for q in res.solutions:
            seen += 1
            assert np.abs(ur5.fk(q) - T).max() < 1e-3  # still the pose
            for k in range(ur5.dof):
                # a turn nearer the seed would be within the limits: not the nearest
                for t in (-2 * np.pi, 2 * np.pi):
                    v = q[k] + t
                    if lo[k] <= v <= hi[k]:
                        assert abs(q[k] - seed[k]) <= abs(v - seed[k]) + 1e-9, (k, q, seed)
    assert seen >= 6


def test_ik_is_deterministic(ur5):
    T = ur5.fk(_random_q(ur5, 1, seed=11)[0])
    a, b = ur5.ik(T), ur5.ik(T)
    # a run compared with itself (same input, same process): exact
    assert len(a.solutions) == len(b.solutions)
    assert all(np.array_equal(x, y) for x, y in zip(a.solutions, b.solutions, strict=True))


def test_ik_accepts_a_rounded_rotation_and_refuses_a_non_rotation(ur5):
    q = _random_q(ur5, 1, seed=12)[0]
    T = ur5.fk(q)
    rounded = T.copy()
    rounded[:3, :3] = np.round(T[:3, :3], 3)  # as stored in a file with 3 decimals
    assert np.max(np.abs(rounded[:3, :3].T @ rounded[:3, :3] - np.eye(3))) > 1e-6
    res = ur5.ik(rounded, seed=q)
    assert res.ok
    assert np.allclose(ur5.fk(res.solutions[0])[:3, 3], T[:3, 3], atol=1e-4)
    skewed = T.copy()
    skewed[:3, :3] *= 1.2
    with pytest.raises(ValueError, match="not a rotation"):
        ur5.ik(skewed)


def test_ik_reach_failure_offers_nearest_pose(ur5):
    T = make_T(p=[2.0, 0.5, 0.3])
    res = ur5.ik(T)
    assert not res.ok and res.failure == IKFailure.REACH
    assert "reach" in res.message
    near = res.nearest_T_base_tool
    # the arm stretched towards the target: nearer than the home pose
    assert np.linalg.norm(near[:3, 3] - T[:3, 3]) < np.linalg.norm(
        ur5.fk(np.zeros(6))[:3, 3] - T[:3, 3])


def test_ik_joint_limit_failure_names_the_joint(ur5):
    q = np.array([1.5, -1.0, 1.2, -0.5, 1.0, 0.3])
    T = ur5.fk(q)
    narrow = np.column_stack([ur5.limits.lower, ur5.limits.upper])
    narrow[0] = (-0.1, 0.1)  # shoulder_pan cannot turn towards the target (either branch)
    res = ur5.with_limits(narrow).ik(T)
    assert res.failure == IKFailure.JOINT_LIMIT
    assert "shoulder_pan_joint" in res.message
    assert res.nearest_T_base_tool is not None


def test_ik_no_convergence_for_an_impossible_point(tmp_path):
    """A planar arm cannot leave its plane, even inside its reach."""
    robot = URDFRobot.from_string(_arm_urdf(planar=True), base_dir=tmp_path)
    res = robot.ik(make_T(p=[0.2, 0.15, 0.6]), position_only=True)
    assert res.failure == IKFailure.NO_CONVERGENCE
    assert res.nearest_T_base_tool is not None


# ------------------------------------------------------------------------------ bad input
def _write(tmp_path: Path, text: str, name: str = "bad.urdf") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_malformed_xml_names_file_and_line(tmp_path):
    p = _write(tmp_path, '<?xml version="1.0"?>\n<robot name="x">\n  <link name="a">\n'
                         '</robot>\n')
    with pytest.raises(RobotModelError) as e:
        URDFRobot.from_file(p)
    assert str(p) in str(e.value) and "malformed XML" in str(e.value)
    assert f"{p}:4:" in str(e.value)


def test_unknown_base_or_tool_link(tmp_path):
    p = _write(tmp_path, _arm_urdf())
    with pytest.raises(RobotModelError, match=r"bad\.urdf: tool link 'hand' is not in the URDF"):
        URDFRobot.from_file(p, tool_link="hand")
    with pytest.raises(RobotModelError, match=r"base link 'floor' is not in the URDF"):
        URDFRobot.from_file(p, base_link="floor")
    with pytest.raises(RobotModelError, match=r"tool link 'base' is not below base link 'l2'"):
        URDFRobot.from_file(p, base_link="l2", tool_link="base")


def test_missing_mesh_names_link_and_path(tmp_path):
    p = _write(tmp_path, _arm_urdf(collision='<mesh filename="meshes/gone.stl"/>'))
    with pytest.raises(RobotModelError) as e:
        URDFRobot.from_file(p)
    msg = str(e.value)
    assert str(p) in msg and "link 'l1'" in msg and str(tmp_path / "meshes" / "gone.stl") in msg


def test_a_mesh_path_naming_a_device_or_a_pipe_is_refused_by_what_it_is(tmp_path):
    """Issue 54: a URDF mesh path naming /dev/zero grew the process to 3.2 GB."""
    import os

    for target, what in (("/dev/zero", "character device"), (tmp_path / "m.stl", "FIFO")):
        if what == "FIFO":
            os.mkfifo(target)
        p = _write(tmp_path, _arm_urdf(collision=f'<mesh filename="{target}"/>'))
        with pytest.raises(RobotModelError) as e:
            URDFRobot.from_file(p)
        msg = str(e.value)
        assert "link 'l1'" in msg and what in msg and "not a mesh file" in msg, msg
    with pytest.raises(RobotModelError, match="character device, not a URDF file"):
        URDFRobot.from_file("/dev/zero")


def test_a_urdf_nested_too_deep_or_with_entities_is_refused(tmp_path):
    deep = _arm_urdf().replace("</robot>", "<x>" * 400 + "</x>" * 400 + "</robot>")
    with pytest.raises(RobotModelError, match="malformed XML: Excessive depth"):
        URDFRobot.from_file(_write(tmp_path, deep))
    body = _arm_urdf().split("?>", 1)[1]
    entity = ('<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY z SYSTEM "file:///dev/zero">]>'
              + body.replace('<robot name="arm">', '<robot name="&z;">'))
    with pytest.raises(RobotModelError, match="malformed XML: Attribute references external "
                                              "entity 'z'"):
        URDFRobot.from_file(_write(tmp_path, entity))


def test_chain_without_actuated_joint(tmp_path):
    p = _write(tmp_path, _arm_urdf())
    with pytest.raises(RobotModelError, match=r"no actuated joint between base link 'l3' and "
                                              r"tool link 'tip'"):
        URDFRobot.from_file(p, base_link="l3", tool_link="tip")


def test_mesh_that_does_not_load(tmp_path):
    (tmp_path / "junk.stl").write_bytes(b"solid nothing here\x00\x01\x02 not a mesh")
    p = _write(tmp_path, _arm_urdf(collision='<mesh filename="junk.stl"/>'))
    with pytest.raises(RobotModelError) as e:
        URDFRobot.from_file(p)
    assert "link 'l1'" in str(e.value) and "junk.stl" in str(e.value)


@pytest.mark.parametrize("broken, expected", [
    ('<joint name="x" type="revolute"><parent link="l3"/><child link="ghost"/></joint>',
     r"<child link='ghost'> is not a link"),
    ('<joint name="x" type="hinge"><parent link="l3"/><child link="tip"/></joint>',
     r"joint 'x' has unknown type 'hinge'"),
    ('<link name="l1"/>', r"link 'l1' is defined twice"),
    ('<link name="orphan"/>', r"exactly one root link, found 'world', 'orphan'"),
    ('<link name="odd"><collision><geometry><torus r="1"/></geometry></collision></link>'
     '<joint name="x" type="fixed"><parent link="l3"/><child link="odd"/></joint>',
     r"link 'odd': unknown geometry <torus>"),
    ('<link name="odd"><collision><origin xyz="1 2"/><geometry><sphere radius="1"/></geometry>'
     '</collision></link><joint name="x" type="fixed"><parent link="l3"/><child link="odd"/>'
     '</joint>', r"<origin xyz='1 2'> must be 3 finite numbers"),
])
def test_structural_errors_name_file_line_and_element(tmp_path, broken, expected):
    p = _write(tmp_path, _arm_urdf(extra=broken))
    with pytest.raises(RobotModelError, match=expected) as e:
        URDFRobot.from_file(p)
    assert str(e.value).startswith(str(p))


def test_revolute_without_limit_is_refused(tmp_path):
    p = _write(tmp_path, _arm_urdf(j1_limit=""))
    with pytest.raises(RobotModelError, match=r"bad\.urdf:\d+: revolute joint 'j1' needs"):
        URDFRobot.from_file(p)


def test_bad_locked_positions(tmp_path):
    with pytest.raises(RobotModelError, match=r"panda\.urdf:\d+: locked joint "
                                              r"'panda_finger_joint1': 0.5 is outside"):
        URDFRobot.from_file(PANDA_URDF, tool_link="panda_hand", load_visual=False,
                            locked_positions={"panda_finger_joint1": 0.5})
    with pytest.raises(RobotModelError, match=r"cannot lock joint 'panda_joint2': it is in the "
                                              r"arm's chain"):
        URDFRobot.from_file(PANDA_URDF, tool_link="panda_hand", load_visual=False,
                            locked_positions={"panda_joint2": 0.1})


def test_empty_geometry_is_refused(tmp_path):
    p = _write(tmp_path, _arm_urdf(collision="<!-- nothing -->"))
    with pytest.raises(RobotModelError, match=r"bad\.urdf:\d+: link 'l1': <geometry> is empty"):
        URDFRobot.from_file(p)


def test_unreadable_file(tmp_path):
    with pytest.raises(RobotModelError, match="cannot read the URDF"):
        URDFRobot.from_file(tmp_path / "nope.urdf")


# ------------------------------------------------------------------------------ RV-2AJ URDF
@pytest.mark.parametrize("tool", [Tool(), Tool("offset", make_T(rot_x(0.4), [0.02, -0.01, 0.12]))])
def test_rv2aj_urdf_loads_in_pinocchio_and_matches_its_fk(tool):
    robot = RV2AJ().with_tool(tool)
    model = pin.buildModelFromXML(robot.urdf())
    assert model.nq == 5 and list(model.names)[1:] == robot.joint_names
    data = model.createData()
    fid = model.getFrameId("tool")
    for q in _random_q(robot, 50, seed=16):
        pin.framesForwardKinematics(model, data, q)
        assert np.abs(data.oMf[fid].homogeneous - robot.fk(q)).max() < 1e-9


def test_numeric_ik_on_the_rv2aj_urdf_agrees_with_the_closed_form():
    rv = RV2AJ().with_tool(Tool.straight(0.1))
    numeric = URDFRobot.from_string(rv.urdf(), base_dir=".", tool_link="tool",
                                    load_visual=False)
    for q in _random_q(rv, 5, seed=17):
        T = rv.fk(q)
        closed, num = rv.ik(T), numeric.ik(T)
        assert closed.ok and num.ok
        for s in num.solutions:
            assert np.linalg.norm(rv.fk(s)[:3, 3] - T[:3, 3]) < POS_TOL
            assert rotation_angle(rv.fk(s)[:3, :3].T @ T[:3, :3]) < ROT_TOL
    # an orientation out of the arm plane: the 5-axis arm reaches the point, not the pose
    T = rv.fk(np.array([0.3, 0.2, 0.9, 0.4, 0.0]))
    T[:3, :3] = T[:3, :3] @ rot_x(0.5)
    res = numeric.ik(T)
    assert res.failure == IKFailure.ORIENTATION and res.nearest_T_base_tool is not None


