"""The cell model: objects, primitives, frames, poses in the base frame, refusals."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from assistant.cell.cad import load_cad
from assistant.cell.model import (
    DEFAULT_COLORS,
    Cell,
    CellError,
    CellObject,
    ObjectRole,
    PrimitiveKind,
    PrimitiveSpec,
)
from assistant.robots.catalog import RobotSpec, ToolSpec
from assistant.robots.model import ShapeKind
from assistant.transforms import make_T, pose_from_mm_deg, rot_z


def _T(x=0.0, y=0.0, z=0.0, yaw_deg=0.0):
    return make_T(rot_z(np.radians(yaw_deg)), np.array([x, y, z]))


def test_primitives_have_exact_collision_shapes_and_matching_display_meshes():
    box = CellObject.box("table", (1.2, 0.8, 0.05), _T(z=-0.025), role="fixture")
    cyl = CellObject.cylinder("post", 0.04, 0.3, _T(0.3, 0.2, 0.15))
    ball = CellObject.sphere("ball", 0.05, _T(0.1, -0.2, 0.3), role=ObjectRole.WORKPIECE)
    assert (box.collision[0].kind, box.collision[0].size) == (ShapeKind.BOX, (1.2, 0.8, 0.05))
    assert (cyl.collision[0].kind, cyl.collision[0].size) == (ShapeKind.CYLINDER, (0.04, 0.3))
    assert (ball.collision[0].kind, ball.collision[0].size) == (ShapeKind.SPHERE, (0.05,))
    np.testing.assert_allclose(box.display_mesh.extents, (1.2, 0.8, 0.05))
    np.testing.assert_allclose(cyl.display_mesh.extents, (0.08, 0.08, 0.3), atol=1e-3)
    assert ball.display_mesh.extents.max() == pytest.approx(0.1, rel=0.01)
    assert box.primitive == PrimitiveSpec(PrimitiveKind.BOX, (1.2, 0.8, 0.05))
    assert box.proxy_deviation_m == 0.0 and box.source is None


def test_colours_default_by_role_and_can_be_given():
    assert CellObject.box("a", (1, 1, 1)).color == DEFAULT_COLORS[ObjectRole.OBSTACLE]
    assert CellObject.box("b", (1, 1, 1), role="workpiece").color == \
        DEFAULT_COLORS[ObjectRole.WORKPIECE]
    assert CellObject.box("c", (1, 1, 1), color=(1, 2, 3)).color == (1, 2, 3)
    assert len(set(DEFAULT_COLORS.values())) == 3


@pytest.mark.parametrize("color", [(0, 0, 256), (-1, 0, 0), (1, 2), (1.5, 2, 3), "red"])
def test_bad_colour_is_refused(color):
    with pytest.raises(CellError, match="0-255"):
        CellObject.box("a", (1, 1, 1), color=color)


@pytest.mark.parametrize(("make", "match"), [
    (lambda: PrimitiveSpec("box", (1, 0, 1)), "must be > 0"),
    (lambda: PrimitiveSpec("box", (1, 1)), "needs 3"),
    (lambda: PrimitiveSpec("cone", (1, 1)), "unknown primitive"),
    (lambda: PrimitiveSpec("sphere", (float("nan"),)), "must be > 0"),
    (lambda: CellObject.box("a", (1, 1, 1), role="wall"), "unknown role 'wall'"),
    (lambda: CellObject.box("", (1, 1, 1)), "name '' is not usable"),
    (lambda: CellObject.box("a\nb", (1, 1, 1)), "not usable"),
])
def test_bad_objects_are_refused(make, match):
    with pytest.raises(CellError, match=match):
        make()


def test_add_remove_and_unique_names():
    cell = Cell()
    cell.add_object(CellObject.box("part", (1, 1, 1)))
    with pytest.raises(CellError, match="'part' already exists.*'part_2'"):
        cell.add_object(CellObject.box("part", (2, 2, 2)))
    assert cell.objects["part"].primitive.size == (1.0, 1.0, 1.0)  # unchanged
    assert cell.unique_name("part") == "part_2"
    cell.add_object(CellObject.box(cell.unique_name("part"), (1, 1, 1)))
    assert cell.unique_name("part") == "part_3"
    assert cell.unique_name("table") == "table"
    assert list(cell.objects) == ["part", "part_2"]
    removed = cell.remove_object("part")
    assert removed.name == "part" and list(cell.objects) == ["part_2"]
    with pytest.raises(CellError, match="no object named 'part' \\(objects: part_2\\)"):
        cell.remove_object("part")


def test_poses_in_the_base_frame():
    # Base 1 m along x, turned 90 degrees; an object 1 m further along world y is 1 m
    # straight ahead of the robot (its x axis).
    cell = Cell(T_world_base=_T(1.0, 0.0, 0.0, 90.0))
    cell.add_object(CellObject.box("box", (0.1, 0.1, 0.1), _T(1.0, 1.0, 0.2, 90.0)))
    cell.add_object(CellObject.sphere("ball", 0.02, _T(0.0, 0.0, 0.0)))
    T = cell.T_base_object("box")
    np.testing.assert_allclose(T[:3, 3], (1.0, 0.0, 0.2), atol=1e-12)
    np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(cell.T_base_object("ball")[:3, 3], (0.0, 1.0, 0.0), atol=1e-12)

    views = cell.collision_objects_in_base()
    assert [v.name for v in views] == ["box", "ball"]
    assert views[0].role == ObjectRole.OBSTACLE
    np.testing.assert_allclose(views[0].T_base_object, T)
    assert views[1].collision[0].kind == ShapeKind.SPHERE


def test_set_object_pose_replaces_the_object_and_refuses_bad_poses():
    cell = Cell()
    before = cell.add_object(CellObject.box("box", (0.1, 0.1, 0.1)))
    after = cell.set_object_pose("box", pose_from_mm_deg([100, 200, 300, 90, 0, 0]))
    assert before.T_world_object[0, 3] == 0.0  # old value untouched
    np.testing.assert_allclose(after.T_world_object[:3, 3], (0.1, 0.2, 0.3))
    assert cell.objects["box"] is after

    scaled = np.diag([2.0, 2.0, 2.0, 1.0])
    mirrored = np.diag([1.0, 1.0, -1.0, 1.0])
    nan = np.eye(4)
    nan[0, 3] = np.nan
    for bad, match in [(scaled, "not a proper rotation"), (mirrored, "not a proper rotation"),
                       (nan, "NaN"), (np.eye(3), "4x4"), ("pose", "4x4")]:
        with pytest.raises(CellError, match=match):
            cell.set_object_pose("box", bad)
    assert cell.objects["box"] is after
    with pytest.raises(ValueError, match="read-only"):
        after.T_world_object[0, 3] = 5.0  # poses change only through the cell
    with pytest.raises(CellError, match="no object named 'nope'"):
        cell.set_object_pose("nope", np.eye(4))


def test_frames():
    cell = Cell(T_world_base=_T(0.5, 0.0, 0.0))
    cell.add_frame("pallet", _T(0.5, 0.3, 0.1))
    np.testing.assert_allclose(cell.T_base_frame("pallet")[:3, 3], (0.0, 0.3, 0.1))
    with pytest.raises(CellError, match="already exists"):
        cell.add_frame("pallet", np.eye(4))
    cell.add_frame("pallet", _T(0.0, 0.0, 0.2), replace_existing=True)
    assert cell.frames["pallet"][2, 3] == 0.2
    cell.remove_frame("pallet")
    with pytest.raises(CellError, match="no frame named 'pallet'"):
        cell.remove_frame("pallet")


def test_robot_is_built_once_per_spec_and_shared():
    spec = RobotSpec(tool=ToolSpec.straight(0.1))
    a, b = Cell(robot_spec=spec), Cell(robot_spec=RobotSpec(tool=ToolSpec.straight(0.1)))
    assert a.robot() is b.robot()
    assert a.robot() is not Cell().robot()
    assert a.robot().dof == 5


def test_cad_object_keeps_its_source_and_proxy_deviation():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=100.0)
    imp = load_cad(sphere.export(file_type="stl"), "dome.stl", proxy_max_faces=1000)
    obj = CellObject.from_cad("dome", imp, _T(0.2, 0, 0), role="fixture")
    assert obj.display_mesh is imp.mesh and obj.collision == imp.collision
    assert obj.proxy_deviation_m == imp.proxy.deviation_m
    assert obj.source.filename == "dome.stl" and obj.source.units == "mm"
    assert obj.role == ObjectRole.FIXTURE


def test_cell_constructor_validates_its_contents():
    box = CellObject.box("a", (1, 1, 1))
    with pytest.raises(CellError, match="stored as 'b' is named 'a'"):
        Cell(objects={"b": box})
    with pytest.raises(CellError, match="robot base pose"):
        Cell(T_world_base=np.zeros((4, 4)))


def test_the_collision_checker_consumes_the_cell_view():
    # The contract with assistant.collision.checker: a box over the arm's stretched-up flange
    # (0, 0, 782 mm in the base frame) collides; the same box moved aside does not. The base is
    # moved and turned in the world so that the world -> base conversion matters.
    from assistant.collision.checker import CollisionChecker

    T_world_base = _T(1.0, 2.0, 0.5, 90.0)
    cell = Cell(T_world_base=T_world_base)
    cell.add_object(CellObject.box("hood", (0.1, 0.1, 0.05), T_world_base @ _T(z=0.8)))
    q_up = np.zeros(5)
    assert not CollisionChecker(cell.robot(), cell.collision_objects_in_base()).is_valid(q_up)
    cell.set_object_pose("hood", T_world_base @ _T(x=0.6, z=0.8))
    assert CollisionChecker(cell.robot(), cell.collision_objects_in_base()).is_valid(q_up)
