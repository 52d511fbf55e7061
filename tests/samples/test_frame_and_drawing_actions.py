"""Operator actions the sample cells need: 3-point frame calibration, placing on a frame,
pen drawings on a frame, sample robots by relative URDF path, export in a work frame."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from assistant.mission.model import SegmentKind
from assistant.robots.catalog import RobotSpec
from assistant.session import Session, SessionError
from assistant.session.events import Notice
from assistant.session.frames import frame_from_three_points
from assistant.session.script import parse_script, run_action
from assistant.session.types import sample_robot_spec
from assistant.trajectory.application import BezierMode
from assistant.trajectory.bezier_drawings import drawing
from assistant.transforms import pose_from_mm_deg

SAMPLES = Path(__file__).resolve().parents[2] / "sample_cells"


@pytest.fixture
def session(tmp_path) -> Session:
    """Thesis robot (RV-2AJ), one box, in step 3.1 (place)."""
    s = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                            with_mission=False)
    s.next()
    s.add_primitive("box", (0.3, 0.3, 0.02), name="pallet", role="fixture",
                    T_world_object=pose_from_mm_deg([300, 0, -10, 0, 0, 0]))
    s.next()
    return s


def _points_of(T: np.ndarray, ox: float, oy: float) -> np.ndarray:
    """Origin, a point on +x (ox along) and one in the XY plane (oy along +y) of frame T."""
    P = np.array([[0, 0, 0, 1], [ox, 0, 0, 1], [0.03, oy, 0, 1]], dtype=float)
    return (P @ T.T)[:, :3]


def test_three_points_give_back_the_frame_they_were_measured_on():
    rng = np.random.default_rng(3)
    for _ in range(20):
        T = pose_from_mm_deg(np.r_[rng.uniform(-400, 400, 3), rng.uniform(-180, 180, 3)])
        o, x, xy = _points_of(T, rng.uniform(0.05, 0.3), rng.uniform(0.05, 0.3))
        cal = frame_from_three_points("F", o, x, xy)
        np.testing.assert_allclose(cal.T_world_frame, T, atol=1e-9)
        assert cal.tilt == pytest.approx(np.arccos(np.clip(T[2, 2], -1, 1)), abs=1e-9)


def test_a_level_and_a_tilted_plane():
    level = frame_from_three_points("L", [0.3, 0, 0], [0.5, 0, 0], [0.3, 0.2, 0])
    assert level.tilt == pytest.approx(0.0, abs=1e-12)
    # 2 mm rise over 200 mm along x: atan(0.01) = 0.573 deg
    tilted = frame_from_three_points("T", [0.3, 0, 0], [0.5, 0, 0.002], [0.3, 0.2, 0])
    assert np.degrees(tilted.tilt) == pytest.approx(np.degrees(np.arctan(0.01)), abs=1e-9)
    assert "tilted 0.57 deg" in tilted.describe()


@pytest.mark.parametrize("pts, why", [
    (([0, 0, 0], [0.01, 0, 0], [0, 0.1, 0]), "within 20 mm"),
    (([0, 0, 0], [0.1, 0, 0], [0.2, 0.01, 0]), "almost on one line"),
    (([0, 0, 0], [0.1, 0, 0], [-0.2, -0.001, 0]), "almost on one line"),
])
def test_ill_conditioned_points_are_refused(pts, why):
    with pytest.raises(SessionError, match=why):
        frame_from_three_points("F", *[np.array(p, float) for p in pts])


def test_calibrate_from_taught_locations_is_undoable_and_saved(session):
    s = session
    T_true = pose_from_mm_deg([200, -80, 60, 2.0, 1.0, -1.5])
    o, x, xy = _points_of(T_true, 0.12, 0.15)
    notes = []
    s.bus.subscribe(lambda e: notes.append(e) if isinstance(e, Notice) else None)
    for name, p in (("C1", o), ("C2", x)):
        T = np.eye(4)
        T[:3, :3] = np.diag([1.0, -1.0, -1.0])
        T[:3, 3] = p
        s.teach(name, T)
    cal = s.calibrate_frame("PALLET", "C1", "C2", xy)  # names and a plain point mix
    np.testing.assert_allclose(s.cell.frames["PALLET"], T_true, atol=1e-9)
    np.testing.assert_allclose(cal.T_world_frame, T_true, atol=1e-9)
    assert any("frame PALLET calibrated" in n.message for n in notes)
    assert "PALLET" in Session.load(s.folder).cell.frames
    s.undo()
    assert "PALLET" not in s.cell.frames
    s.redo()
    np.testing.assert_allclose(s.cell.frames["PALLET"], T_true, atol=1e-9)
    # Re-calibration replaces the frame.
    s.calibrate_frame("PALLET", o, x + [0, 0, 0.001], xy)
    assert not np.allclose(s.cell.frames["PALLET"], T_true, atol=1e-6)
    with pytest.raises(SessionError, match="no location named 'C9'"):
        s.calibrate_frame("OTHER", "C9", "C2", xy)
    assert "OTHER" not in s.cell.frames


def test_place_in_frame_composes_the_frame_and_the_pose(session):
    s = session
    T = pose_from_mm_deg([250, -100, 5, 2.0, 1.0, -1.5])
    s.calibrate_frame("PALLET", *_points_of(T, 0.2, 0.15))
    T_fo = pose_from_mm_deg([120, 120, -20, 0, 0, 0])
    s.place_object_in_frame("pallet", "PALLET", T_fo)
    np.testing.assert_allclose(s.cell.objects["pallet"].T_world_object, T @ T_fo, atol=1e-12)
    with pytest.raises(SessionError, match="no frame named 'NOPE'"):
        s.place_object_in_frame("pallet", "NOPE", T_fo)


def test_a_drawing_is_lift_line_bezier_chain_lift_line_on_the_frame(session):
    s = session
    T = pose_from_mm_deg([250, -100, 5, 2.0, 1.0, -1.5])
    s.calibrate_frame("PALLET", *_points_of(T, 0.2, 0.15))
    s.goto("teach.paths")
    path = s.add_drawing("FRAME1", "PALLET", 1, at=(0.12, 0.1), angle=np.radians(90),
                         lift=0.04, speed=0.1)
    chain = drawing(1)
    kinds = [seg.kind for seg in path.segments]
    assert kinds == [SegmentKind.LINE] + [SegmentKind.BEZIER] * len(chain.segments) + \
        [SegmentKind.LINE]
    T_fw = np.linalg.inv(T)
    pts = np.array([p for seg in path.segments[1:-1] for p in seg.points])
    local = pts @ T_fw[:3, :3].T + T_fw[:3, 3]
    np.testing.assert_allclose(local[:, 2], 0.0, atol=1e-12)  # on the paper
    # The drawing's first point, turned by 90 deg and moved to `at`.
    p0 = chain.segments[0].control[0]
    np.testing.assert_allclose(local[0, :2], [0.12 - p0[1], 0.1 + p0[0]], atol=1e-12)
    down = path.segments[0]
    np.testing.assert_allclose(down.start - down.end, 0.04 * T[:3, 2], atol=1e-12)
    np.testing.assert_allclose(path.segments[-1].end - path.segments[-1].start,
                               0.04 * T[:3, 2], atol=1e-12)
    np.testing.assert_allclose(path.R_world_tool[:, 2], -T[:3, 2], atol=1e-12)  # pen in
    assert path.speed == pytest.approx(0.1)
    assert s.mission.paths[-1].name == "FRAME1"
    with pytest.raises(SessionError, match="drawings 1..9"):
        s.add_drawing("D10", "PALLET", 10)
    with pytest.raises(SessionError, match="exists already"):
        s.add_drawing("FRAME1", "PALLET", 2)
    with pytest.raises(SessionError, match="1 \\+ 3k"):
        s.add_drawing("BAD", "PALLET", np.zeros((5, 2)))
    assert [p.name for p in s.mission.paths] == ["FRAME1"]
    s.undo()
    assert not s.mission.paths


def test_script_verbs_take_mm_and_names(session, tmp_path):
    script = tmp_path / "s.yaml"
    script.write_text(
        "actions:\n"
        "  - calibrate_frame: {name: PAL, origin: [300, 0, 0], x_point: [500, 0, 2],\n"
        "                      xy_point: [300, 200, 0]}\n"
        "  - place_in_frame: {object: pallet, frame: PAL, pose: [150, 100, -20, 0, 0, 0]}\n"
        "  - goto: teach.paths\n"
        "  - add_drawing: {name: KEYS, frame: PAL, drawing: 4, at: [100, 100], lift_mm: 30,\n"
        "                  speed_mm_s: 80, after: [{wait_s: 0.5}], tool_angle_deg: 180}\n"
        "  - add_drawing: {name: V, frame: PAL, points: [[0, 0], [10, 0], [20, 10], [30, 30]]}\n")
    for a in parse_script(script).actions:
        run_action(session, a, tmp_path, script)
    T = session.cell.frames["PAL"]
    np.testing.assert_allclose(T[:3, 3], [0.3, 0.0, 0.0])
    np.testing.assert_allclose(session.cell.objects["pallet"].T_world_object[:3, 3],
                               (T @ [0.15, 0.1, -0.02, 1.0])[:3])
    keys, v = session.mission.paths
    assert keys.speed == pytest.approx(0.08) and keys.actions_after[0].seconds == 0.5
    # the pen turned half a turn about itself: tool x against the frame's x, still into it
    np.testing.assert_allclose(keys.R_world_tool[:, 0], -T[:3, 0], atol=1e-12)
    np.testing.assert_allclose(keys.R_world_tool[:, 2], -T[:3, 2], atol=1e-12)
    np.testing.assert_allclose(v.R_world_tool[:, 0], T[:3, 0], atol=1e-12)
    assert len(v.segments) == 3 and v.segments[1].kind == SegmentKind.BEZIER
    np.testing.assert_allclose(v.segments[1].end, (T @ [0.03, 0.03, 0.0, 1.0])[:3])


def test_relative_urdf_paths_of_a_sample_resolve_in_its_folder_then_robot_data(tmp_path):
    (tmp_path / "arm.urdf").write_text("<robot/>")
    spec = RobotSpec(kind="urdf", urdf_path="arm.urdf")
    assert sample_robot_spec(spec, tmp_path).urdf_path == str((tmp_path / "arm.urdf").resolve())
    ur5 = RobotSpec(kind="urdf",
                    urdf_path="example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    found = Path(sample_robot_spec(ur5, tmp_path).urdf_path)
    assert found.is_absolute() and found.is_file() and found.name == "ur5_robot.urdf"
    with pytest.raises(SessionError, match="missing.urdf.*not found"):
        sample_robot_spec(RobotSpec(kind="urdf", urdf_path="missing.urdf"), tmp_path)
    absolute = RobotSpec(kind="urdf", urdf_path=str(tmp_path / "elsewhere.urdf"))
    assert sample_robot_spec(absolute, tmp_path) is absolute
    builtin = RobotSpec()
    assert sample_robot_spec(builtin, tmp_path) is builtin


def test_bezier_chains_are_planned_as_splines_for_a_dialect_that_writes_them(session):
    s = session
    assert s._planner_config().application.bezier_mode == BezierMode.LINEAR  # melfa
    s.export_dialect = "krl"
    assert s._planner_config().application.bezier_mode == BezierMode.SPLINE
    s.export_dialect = "rapid"
    assert s._planner_config().application.bezier_mode == BezierMode.LINEAR


def test_the_action_after_a_scripted_jog_is_never_refused_as_moving(tmp_path):
    """A long action's future resolves only after the worker has ended the moving mode, so
    the next action is accepted (here: jog, then teach from the robot pose, 30 times)."""
    s = Session.from_sample("thesis_rv2aj", None, with_objects=False, with_mission=False)
    s.next()
    s.add_primitive("box", (0.1, 0.1, 0.1), T_world_object=pose_from_mm_deg([0, 300, 50, 0,
                                                                              0, 0]))
    s.next()
    lines = []
    for i in range(30):
        lines.append(f"  - jog: {{joints_deg: [{-10 * (i % 2)}, 20, 60, 0, 0]}}\n")
        lines.append(f"  - teach_robot: T{i}\n")
    script = tmp_path / "jogs.yaml"
    script.write_text("actions:\n" + "".join(lines))
    for a in parse_script(script).actions:
        run_action(s, a, tmp_path, script)
    assert len(s.locations) == 30
