"""URDF robots: loading, mesh paths, FK against pinocchio, batch FK, the description."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import trimesh
from urdf_builders import (
    PANDA_URDF,
    POS_TOL,
    SHARE,
    UR5_URDF,
    _arm_urdf,
    _pin_fk,
    _random_q,
)

from assistant.robots.batch_chain import BatchChain, ChainJoint, JointKind, sincos
from assistant.robots.catalog import RobotModelError, RobotSpec, ToolSpec
from assistant.robots.model import ShapeKind, Tool
from assistant.robots.urdf_parse import COLLISION_FACE_LIMIT, TCP_FRAME
from assistant.robots.urdf_robot import URDFRobot
from assistant.transforms import make_T, rot_x, rot_y


# ------------------------------------------------------------------------------ loading
def test_ur5_frames_joints_and_limits(ur5):
    assert ur5.base_link == "world"  # the root
    assert ur5.tool_link == "ee_link"  # end of the longest chain (first in file order)
    assert ur5.joint_names == ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
                               "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
    assert np.allclose(ur5.limits.upper, [2 * np.pi, 2 * np.pi, np.pi, 2 * np.pi, 2 * np.pi,
                                          2 * np.pi], atol=1e-9)
    assert np.allclose(ur5.limits.velocity, [3.15, 3.15, 3.15, 3.2, 3.2, 3.2])
    names = [lk.name for lk in ur5.links]
    assert names == ["world", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
                     "wrist_2_link", "wrist_3_link"]
    # base_link's mesh merged into the root; ee_link's box into wrist_3_link
    kinds = [[s.kind for s in lk.collision] for lk in ur5.links]
    assert kinds[0] == [ShapeKind.MESH]
    assert kinds[-1] == [ShapeKind.MESH, ShapeKind.BOX]
    assert all(lk.visual is not None and len(lk.visual.faces) > 100 for lk in ur5.links)


def test_panda_fingers_locked_and_merged_into_the_hand_link(panda):
    assert panda.dof == 7 and len(panda.links) == 8
    assert set(panda.locked_positions) == {"panda_finger_joint1", "panda_finger_joint2"}
    assert panda.locked_positions["panda_finger_joint1"] == 0.0
    # link7 + hand mesh + 2 x 4 finger boxes
    kinds = [s.kind for s in panda.links[-1].collision]
    assert kinds.count(ShapeKind.MESH) == 2 and kinds.count(ShapeKind.BOX) == 8
    # panda_joint4's range excludes 0: the lower/upper come straight from the URDF
    assert panda.limits.lower[3] == pytest.approx(-3.0718)
    assert panda.limits.upper[3] == pytest.approx(-0.0698)


def test_default_tool_of_panda_includes_the_finger_joint():
    robot = URDFRobot.from_file(PANDA_URDF, load_visual=False)
    assert robot.tool_link == "panda_leftfinger"
    assert robot.joint_names[-1] == "panda_finger_joint1"
    assert robot.limits.upper[-1] == pytest.approx(0.04)
    assert all(lk.visual is None for lk in robot.links)


OPEN_HAND = {"panda_finger_joint1": 0.03, "panda_finger_joint2": 0.03}


@pytest.mark.parametrize("which", ["ur5", "panda", "panda_open"])
def test_collision_shapes_sit_where_pinocchio_puts_the_urdf_geometry(which, request):
    """Merged/re-expressed shapes, placed by link_poses, equal pinocchio's geometry placements."""
    locked = OPEN_HAND if which == "panda_open" else {}
    if which == "panda_open":
        robot = URDFRobot.from_file(PANDA_URDF, tool_link="panda_hand", load_visual=False,
                                    locked_positions=OPEN_HAND)
        assert robot.locked_positions == OPEN_HAND
    else:
        robot = request.getfixturevalue(which)
    urdf = UR5_URDF if which == "ur5" else PANDA_URDF
    model = pin.buildModelFromUrdf(str(urdf))
    geom = pin.buildGeomFromUrdf(model, str(urdf), pin.COLLISION, package_dirs=[str(SHARE)])
    data, gdata = model.createData(), geom.createData()
    for q in _random_q(robot, 3, seed=4):
        qf = pin.neutral(model)
        for name, v in list(zip(robot.joint_names, q, strict=True)) + list(locked.items()):
            qf[model.joints[model.getJointId(name)].idx_q] = v
        pin.updateGeometryPlacements(model, data, geom, gdata, qf)
        ref = [gdata.oMg[i].homogeneous for i in range(len(geom.geometryObjects))]
        frames = robot.link_poses(q)
        ours = [frames[k] @ s.T_link_shape for k, lk in enumerate(robot.links)
                for s in lk.collision]
        assert len(ours) == len(ref)
        for T in ref:
            assert min(np.abs(T - O).max() for O in ours) < 1e-9


def test_mesh_shapes_are_the_files_scaled(tmp_path):
    mesh = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    mesh.export(tmp_path / "box.stl")
    xml = _arm_urdf(collision='<mesh filename="box.stl" scale="0.1 0.2 0.5"/>')
    robot = URDFRobot.from_string(xml, base_dir=tmp_path)
    shape = robot.links[1].collision[0]
    assert shape.kind == ShapeKind.MESH
    assert np.allclose(shape.mesh.extents, [0.1, 0.4, 1.5])


def test_large_collision_mesh_becomes_its_convex_hull(tmp_path):
    ball = trimesh.creation.icosphere(subdivisions=5, radius=0.05)  # 20480 faces
    ball.vertices[:, 2] *= 1.0 + 0.3 * np.sin(7 * ball.vertices[:, 0] / 0.05)  # not convex
    assert len(ball.faces) > COLLISION_FACE_LIMIT
    ball.export(tmp_path / "big.stl")
    robot = URDFRobot.from_string(_arm_urdf(collision='<mesh filename="big.stl"/>',
                                            visual='<mesh filename="big.stl"/>'),
                                  base_dir=tmp_path)
    coll = robot.links[1].collision[0].mesh
    assert coll.is_convex and len(coll.faces) < len(ball.faces)
    assert np.allclose(coll.bounds, ball.bounds, atol=1e-9)
    assert len(robot.links[1].visual.faces) == len(ball.faces)  # drawing keeps the detail


# ------------------------------------------------------------------------------ mesh paths
def test_package_uri_resolves_through_package_dirs_and_ros_layout(tmp_path):
    pkg = tmp_path / "ws" / "src" / "my_arm"
    (pkg / "meshes").mkdir(parents=True)
    (pkg / "urdf").mkdir()
    trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(pkg / "meshes" / "l.stl")
    xml = _arm_urdf(collision='<mesh filename="package://my_arm/meshes/l.stl"/>')
    (pkg / "urdf" / "arm.urdf").write_text(xml)
    # ROS layout: the package is an ancestor of the URDF folder
    r1 = URDFRobot.from_file(pkg / "urdf" / "arm.urdf")
    # elsewhere, with package_dirs naming the folder that holds the package
    other = tmp_path / "copy.urdf"
    other.write_text(xml)
    r2 = URDFRobot.from_file(other, package_dirs=[tmp_path / "ws" / "src"])
    for r in (r1, r2):
        assert np.allclose(r.links[1].collision[0].mesh.extents, 0.1)
    with pytest.raises(RobotModelError, match="mesh file not found"):
        URDFRobot.from_file(other)


def test_relative_and_file_uri_paths(tmp_path):
    (tmp_path / "m").mkdir()
    trimesh.creation.box(extents=(0.2, 0.2, 0.2)).export(tmp_path / "m" / "a.stl")
    rel = URDFRobot.from_string(_arm_urdf(collision='<mesh filename="m/a.stl"/>'),
                                base_dir=tmp_path)
    uri = URDFRobot.from_string(
        _arm_urdf(collision=f'<mesh filename="file://{tmp_path}/m/a.stl"/>'), base_dir="/")
    for r in (rel, uri):
        assert np.allclose(r.links[1].collision[0].mesh.extents, 0.2)


# ------------------------------------------------------------------------------ FK
@pytest.mark.parametrize("which", ["ur5", "panda"])
def test_fk_and_batch_fk_agree_with_pinocchio(which, request):
    robot = request.getfixturevalue(which)
    urdf = UR5_URDF if which == "ur5" else PANDA_URDF
    Q = _random_q(robot, 40, seed=1)
    batch = robot.batch_fk(Q)
    links = robot.batch_link_poses(Q)
    link_names = [lk.name for lk in robot.links]
    for i, q in enumerate(Q):
        ref = _pin_fk(urdf, robot, q, robot.tool_link)
        assert np.abs(robot.fk(q) - ref).max() < 1e-9
        assert np.abs(batch.positions[i] - ref[:3, 3]).max() < 1e-9
        assert np.abs(batch.rotations[i] - ref[:3, :3]).max() < 1e-9
        single = robot.link_poses(q)
        assert np.abs(links[i] - single).max() < 1e-9
        for k in (1, robot.dof // 2, robot.dof):
            assert np.abs(single[k] - _pin_fk(urdf, robot, q, link_names[k])).max() < 1e-9


def test_batch_fk_float32_and_chunking(ur5):
    Q = _random_q(ur5, 20_000, seed=2)
    ref = ur5.batch_fk(Q)
    chunked = ur5.batch_chain.tip_poses(Q, chunk=777)
    # 1e-15 m: the same chain per row; chunking may change which vectorised or remainder
    # code path (and BLAS kernel) a row takes, a few ULPs of the < 1 m positions
    np.testing.assert_allclose(chunked.positions, ref.positions, rtol=0, atol=1e-15)
    f32 = ur5.batch_fk(Q, dtype=np.float32)
    assert f32.positions.dtype == np.float32
    assert np.abs(f32.positions - ref.positions).max() < 1e-5
    assert np.abs(f32.rotations - ref.rotations).max() < 1e-5


def test_tool_offset_and_non_root_base(tmp_path):
    """base_link below the root and a TCP offset: still equal to pinocchio."""
    xml = _arm_urdf(root_offset='<origin xyz="0.3 -0.2 0.5" rpy="0.1 0.2 0.3"/>')
    T_ft = make_T(rot_y(0.4), [0.01, 0.02, 0.15])
    robot = URDFRobot.from_string(xml, base_dir=tmp_path, base_link="base", tool_link="l3",
                                  tool=Tool("pen", T_ft))
    for q in _random_q(robot, 10, seed=3):
        ref = _pin_fk(xml, robot, q, "l3", from_xml=True) @ T_ft
        assert np.abs(robot.fk(q) - ref).max() < 1e-9
        b = robot.batch_fk(q[None])
        assert np.abs(b.positions[0] - ref[:3, 3]).max() < 1e-9
        assert np.abs(b.rotations[0] - ref[:3, :3]).max() < 1e-9


def test_continuous_prismatic_and_oblique_axes(tmp_path):
    xml = _arm_urdf(j1_type="continuous", j1_axis="0 0 -1", j2_axis="0.3 -0.5 0.8",
                    j3_type="prismatic", j3_axis="0 -1 0")
    robot = URDFRobot.from_string(xml, base_dir=tmp_path)
    assert robot.limits.lower[0] == -2 * np.pi and robot.limits.upper[0] == 2 * np.pi
    Q = _random_q(robot, 15, seed=5)
    batch = robot.batch_fk(Q)
    for i, q in enumerate(Q):
        ref = _pin_fk(xml, robot, q, robot.tool_link, from_xml=True)
        assert np.abs(robot.fk(q) - ref).max() < 1e-9
        assert np.abs(batch.positions[i] - ref[:3, 3]).max() < 1e-9
        assert np.abs(batch.rotations[i] - ref[:3, :3]).max() < 1e-9


def test_sincos_matches_numpy():
    x = np.concatenate([np.random.default_rng(0).uniform(-50, 50, 100_000),
                        np.arange(-8, 9) * np.pi / 4, [0.0, -0.0, 1e-300]])
    s, c = sincos(x)
    assert np.abs(s - np.sin(x)).max() < 4e-16
    assert np.abs(c - np.cos(x)).max() < 4e-16
    with np.errstate(invalid="ignore"):  # beyond the reduction's range: numpy's result
        s, c = sincos(np.array([1e7, np.inf]))
    assert s[0] == np.sin(1e7) and np.isnan(c[1])


def test_batch_chain_rejects_wrong_shape():
    chain = BatchChain((ChainJoint("j", JointKind.REVOLUTE, np.eye(4), np.array([0, 0, 1.0])),))
    with pytest.raises(ValueError, match=r"\(N, 1\)"):
        chain.tip_poses(np.zeros((3, 2)))


def test_arm_radii_bound_the_motion_of_the_tcp(ur5):
    """Link frames lie on their joint axes, so the base-class bound holds for URDF robots."""
    radii = ur5.arm_radii()
    assert np.all(np.isfinite(radii)) and np.all(radii > 0)
    rng = np.random.default_rng(6)
    for q in _random_q(ur5, 20, seed=7):
        dq = rng.uniform(-0.01, 0.01, ur5.dof)
        moved = np.linalg.norm(ur5.fk(q + dq)[:3, 3] - ur5.fk(q)[:3, 3])
        assert moved <= float(radii @ np.abs(dq)) + 1e-12


# ------------------------------------------------------------------------------ description
def test_with_tool_with_limits_and_hash(ur5):
    T_ft = make_T(p=[0, 0, 0.12])
    tooled = ur5.with_tool(T_ft)
    q = _random_q(ur5, 1, seed=12)[0]
    assert np.allclose(tooled.fk(q), ur5.fk(q) @ T_ft, atol=1e-12)
    lim = np.column_stack([ur5.limits.lower, ur5.limits.upper]) * 0.5
    limited = ur5.with_limits(lim)
    assert np.allclose(limited.limits.upper, lim[:, 1])
    hashes = {r.description_hash() for r in (ur5, tooled, limited)}
    assert len(hashes) == 3
    assert URDFRobot.from_file(UR5_URDF, load_visual=False).description_hash() == \
        ur5.description_hash()
    with pytest.raises(RobotModelError, match=r"shape \(6, 2\)"):
        ur5.with_limits(np.zeros((5, 2)))
    with pytest.raises(RobotModelError, match="shoulder_pan_joint"):
        ur5.with_limits(lim[:, ::-1])


def test_urdf_text_has_absolute_meshes_limits_and_tool(ur5):
    T_ft = make_T(rot_x(0.3), [0.01, 0.0, 0.1])
    lim = np.column_stack([ur5.limits.lower, ur5.limits.upper]) * 0.5
    robot = ur5.with_tool(T_ft).with_limits(lim)
    text = robot.urdf()
    assert "package://" not in text
    from lxml import etree

    root = etree.fromstring(text.encode())
    for mesh in root.iter("mesh"):
        assert Path(mesh.get("filename")).is_absolute() and Path(mesh.get("filename")).is_file()
    model = pin.buildModelFromXML(text)
    assert np.allclose(model.upperPositionLimit, lim[:, 1])
    data = model.createData()
    for q in _random_q(robot, 5, seed=13):
        pin.framesForwardKinematics(model, data, q)
        assert np.abs(data.oMf[model.getFrameId("tool")].homogeneous - robot.fk(q)).max() < 1e-9
    # and the text loads back as the same robot
    again = URDFRobot.from_string(text, base_dir="/", tool_link="tool", load_visual=False)
    q = _random_q(robot, 1, seed=14)[0]
    assert np.abs(again.fk(q) - robot.fk(q)).max() < 1e-9


def test_shared_robot_is_safe_across_threads(panda):
    """pinocchio's Data is per thread: concurrent FK/IK give the single-threaded answers."""
    from concurrent.futures import ThreadPoolExecutor

    Q = _random_q(panda, 40, seed=18)
    expected = [panda.fk(q) for q in Q]
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(panda.fk, Q))
        iks = list(pool.map(lambda q: panda.ik(panda.fk(q), seed=q, max_solutions=1), Q[:8]))
    # the same code on the same input in this process, only on other threads: exact
    assert all(np.array_equal(a, b) for a, b in zip(expected, got, strict=True))
    assert all(r.ok and np.linalg.norm(panda.fk(r.solutions[0])[:3, 3] - panda.fk(q)[:3, 3])
               < POS_TOL for r, q in zip(iks, Q[:8], strict=True))


def test_pinocchio_model_has_the_chain_and_tcp(panda):
    model = panda.pinocchio_model
    assert model.nq == 7 and list(model.names)[1:] == panda.joint_names
    data = model.createData()
    q = _random_q(panda, 1, seed=15)[0]
    pin.framesForwardKinematics(model, data, q)
    assert np.abs(data.oMf[model.getFrameId(TCP_FRAME)].homogeneous - panda.fk(q)).max() < 1e-12


def test_robot_spec_builds_a_urdf_robot():
    spec = RobotSpec(kind="urdf", urdf_path=str(UR5_URDF), package_dirs=(str(SHARE),),
                     tool_link="tool0", tool=ToolSpec.straight(0.1),
                     limits_deg=((-180, 180),) * 6)
    robot = RobotSpec.from_json(spec.to_json()).build()
    assert isinstance(robot, URDFRobot) and robot.tool_link == "tool0"
    assert np.allclose(np.degrees(robot.limits.upper), 180)
    assert robot.T_flange_tool[2, 3] == pytest.approx(0.1)
    # wrist_3 mesh + ee_link's box (a side branch, merged) + the tool's capsule
    assert len(robot.links[-1].collision) == 3
    q = np.zeros(6)
    assert np.allclose(robot.fk(q), _pin_fk(UR5_URDF, robot, q, "tool0") @ robot.T_flange_tool)


