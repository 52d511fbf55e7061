"""URDF robots: loading, FK against pinocchio, batch FK, numeric IK, errors; RV-2AJ's URDF."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import trimesh

from assistant.robots.batch_chain import BatchChain, ChainJoint, JointKind, sincos
from assistant.robots.catalog import RobotModelError, RobotSpec, ToolSpec, installed_robot_urdf
from assistant.robots.model import IKFailure, ShapeKind, Tool
from assistant.robots.rv2aj import RV2AJ
from assistant.robots.urdf_parse import COLLISION_FACE_LIMIT, TCP_FRAME
from assistant.robots.urdf_robot import URDFRobot
from assistant.transforms import make_T, rot_x, rot_y, rotation_angle

POS_TOL = 2e-6  # m: IK tolerance 1e-6 plus rounding
ROT_TOL = 2e-5  # rad


UR5_URDF, SHARE = installed_robot_urdf(
    "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
ROBOTS = SHARE / "example-robot-data" / "robots"
PANDA_URDF = ROBOTS / "panda_description" / "urdf" / "panda.urdf"


@pytest.fixture(scope="module")
def ur5() -> URDFRobot:
    return URDFRobot.from_file(UR5_URDF, package_dirs=[SHARE])


@pytest.fixture(scope="module")
def panda() -> URDFRobot:
    # No package_dirs: package://example-robot-data/... is found among the URDF's ancestors.
    return URDFRobot.from_file(PANDA_URDF, tool_link="panda_hand")


def _pin_fk(urdf: Path | str, robot: URDFRobot, q: np.ndarray, frame: str,
            locked: dict[str, float] | None = None, from_xml: bool = False) -> np.ndarray:
    """Reference: pinocchio's full model, chain joints at q, everything else at 0."""
    model = _pin_model(str(urdf), from_xml)
    data = model.createData()
    qf = pin.neutral(model)
    for name, v in list(zip(robot.joint_names, q, strict=True)) + list((locked or {}).items()):
        j = model.joints[model.getJointId(name)]
        if j.nq == 2:
            qf[j.idx_q:j.idx_q + 2] = np.cos(v), np.sin(v)
        else:
            qf[j.idx_q] = v
    pin.framesForwardKinematics(model, data, qf)
    T_root_base = data.oMf[model.getFrameId(robot.base_link)].homogeneous
    return np.linalg.inv(T_root_base) @ data.oMf[model.getFrameId(frame)].homogeneous


@functools.lru_cache(maxsize=8)
def _pin_model(urdf: str, from_xml: bool) -> pin.Model:
    return pin.buildModelFromXML(urdf) if from_xml else pin.buildModelFromUrdf(urdf)


def _random_q(robot, n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(robot.limits.lower, robot.limits.upper,
                                               (n, robot.dof))


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


# ------------------------------------------------------------------------------ helpers
def _arm_urdf(*, collision: str = '<cylinder radius="0.03" length="0.2"/>',
              visual: str | None = None, extra: str = "", root_offset: str = "",
              j1_type: str = "revolute", j1_axis: str = "0 0 1", j2_axis: str = "0 1 0",
              j3_type: str = "revolute",
              j3_axis: str = "0 1 0", planar: bool = False,
              j1_limit: str = '<limit lower="-2.5" upper="2.5" effort="1" velocity="2"/>'
              ) -> str:
    """A small 3-joint arm: world -> base -> l1 -> l2 -> l3 -> tip (fixed)."""
    vis = f"<visual><geometry>{visual}</geometry></visual>" if visual else ""
    lim = '<limit lower="-2" upper="2" effort="1" velocity="2"/>'
    plim = '<limit lower="-0.1" upper="0.2" effort="1" velocity="0.5"/>'
    j1_axis = "0 1 0" if planar else j1_axis
    return f"""<?xml version="1.0"?>
<robot name="arm">
  <link name="world"/>
  <joint name="mount" type="fixed"><parent link="world"/><child link="base"/>{root_offset}
  </joint>
  <link name="base"><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <joint name="j1" type="{j1_type}"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.1"/><axis xyz="{j1_axis}"/>{j1_limit if j1_type != "continuous" else ""}
  </joint>
  <link name="l1">{vis}<collision><origin xyz="0 0 0.1" rpy="0.1 0 0"/>
    <geometry>{collision}</geometry></collision></link>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0 0 0.2" rpy="0 0.3 0"/><axis xyz="{"0 1 0" if planar else j2_axis}"/>{lim}
  </joint>
  <link name="l2"><collision><origin xyz="0 0 0.15"/>
    <geometry><capsule radius="0.03" length="0.3"/></geometry></collision></link>
  <joint name="j3" type="{j3_type}"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.05 0 0.3" rpy="{"0 0 0" if planar else "1.57079632679 0 0"}"/>
    <axis xyz="{j3_axis}"/>
    {plim if j3_type == "prismatic" else lim}
  </joint>
  <link name="l3"><collision><geometry><sphere radius="0.04"/></geometry></collision></link>
  <joint name="tip_fixed" type="fixed"><parent link="l3"/><child link="tip"/>
    <origin xyz="0 0 0.08" rpy="0 0 0.5"/></joint>
  <link name="tip"/>
  {extra}
</robot>
"""
