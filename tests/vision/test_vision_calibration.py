"""Calibration recovers known intrinsics from rendered chessboard/ChArUco views and the known
camera pose from robot-visited points seen as a coloured marker; bad input is refused."""

from __future__ import annotations

import numpy as np
import pytest

from vision.calibration_targets import CharucoSpec, ChessboardSpec
from vision.camera_model import CameraModel
from vision.color import ColorProfile
from vision.detection import BlobDetector
from vision.errors import CalibrationError
from vision.extrinsics import calibrate_extrinsics
from vision.geometry import sphere_ray
from vision.intrinsics import calibrate_charuco, calibrate_chessboard
from vision.rigs import look_at
from vision.scene import BLUE_MARKER_BGR, BackgroundSpec, PointerScene, SensorSpec
from vision.scripted import board_poses, render_board_views
from vision.sources import SyntheticCamera

TRUE = CameraModel.from_fov(640, 480, 60.0, dist=[-0.12, 0.05, 0.0005, -0.0003, 0.0])


def _max_pixel_difference(a: CameraModel, b: CameraModel, inset: float = 0.1) -> float:
    """How far apart the two models put the same rays (pixels), over the image minus an
    `inset` border: the far corners, where no board was held, are extrapolation."""
    u, v = np.meshgrid(np.linspace(inset * 639, (1 - inset) * 639, 17),
                       np.linspace(inset * 479, (1 - inset) * 479, 13))
    px = np.column_stack([u.ravel(), v.ravel()])
    n = a.normalized(px)
    P = np.column_stack([n, np.ones(len(n))])
    return float(np.max(np.linalg.norm(b.project_camera(P) - px, axis=1)))


def _views(spec, n, seed):
    tex, w, h = spec.texture()
    poses = board_poses(TRUE, w, h, n, seed=seed)
    return render_board_views(TRUE, [spec.target(T) for T in poses], seed=seed + 100)


def test_chessboard_recovers_known_intrinsics():
    res = calibrate_chessboard(_views(ChessboardSpec(9, 6, 0.025), 12, 1), ChessboardSpec(9, 6,
                                                                                          0.025))
    assert res.n_views >= 8 and res.rms_px < 0.15
    assert res.K[0, 0] == pytest.approx(TRUE.K[0, 0], rel=0.005)
    assert res.K[1, 1] == pytest.approx(TRUE.K[1, 1], rel=0.005)
    assert np.allclose(res.K[:2, 2], TRUE.K[:2, 2], atol=2.0)
    assert _max_pixel_difference(TRUE, res.camera_model()) < 1.0
    assert _max_pixel_difference(TRUE, res.camera_model(), inset=0.0) < 2.0


def test_charuco_recovers_known_intrinsics():
    spec = CharucoSpec(7, 5, 0.035, 0.026)
    res = calibrate_charuco(_views(spec, 12, 2), spec)
    assert res.n_views >= 10 and res.rms_px < 0.25
    assert res.K[0, 0] == pytest.approx(TRUE.K[0, 0], rel=0.01)
    assert np.allclose(res.K[:2, 2], TRUE.K[:2, 2], atol=4.0)
    assert _max_pixel_difference(TRUE, res.camera_model()) < 1.0
    assert _max_pixel_difference(TRUE, res.camera_model(), inset=0.0) < 2.0


def test_too_few_views_is_a_clear_error():
    spec = ChessboardSpec(9, 6, 0.025)
    with pytest.raises(CalibrationError, match="need at least 5"):
        calibrate_chessboard(_views(spec, 3, 3), spec)
    blank = [np.full((480, 640, 3), 128, np.uint8)] * 6
    with pytest.raises(CalibrationError, match="only 0 of 6"):
        calibrate_chessboard(blank, spec)
    with pytest.raises(CalibrationError, match="no calibration images"):
        calibrate_chessboard([], spec)


def test_degenerate_views_are_refused():
    """The same square-on view six times: focal length and distance cannot be told apart."""
    spec = ChessboardSpec(9, 6, 0.025)
    tex, w, h = spec.texture()
    T = np.eye(4)
    T[:3, 3] = [-w / 2, -h / 2, 0.5]
    img = render_board_views(TRUE, [spec.target(T)], seed=4)[0]
    with pytest.raises(CalibrationError, match="degenerate"):
        calibrate_chessboard([img] * 6, spec)


def test_mixed_image_sizes_are_refused():
    spec = ChessboardSpec()
    with pytest.raises(CalibrationError, match="differ in size"):
        calibrate_chessboard([np.zeros((480, 640, 3), np.uint8),
                              np.zeros((240, 320, 3), np.uint8)], spec)


def test_extrinsics_from_a_tcp_marker_recover_the_camera_pose():
    """The robot carries a blue ball at its TCP to 12 known points; the camera sees it."""
    T_true = look_at([1.2, -0.4, 0.8], [0.3, 0.0, 0.25])
    model = CameraModel.from_fov(640, 480, 60.0, T_true)
    rng = np.random.default_rng(5)
    points = np.array([0.3, 0.0, 0.25]) + rng.uniform(-0.2, 0.2, (12, 3))
    blue = ColorProfile("robot", 100, 125, 100, 255, 40)
    det = BlobDetector(blue)
    pixels = []
    for p in points:
        scene = PointerScene(p, ball_bgr=BLUE_MARKER_BGR, stick=None,
                             background=BackgroundSpec(kind="plain"),
                             sensor=SensorSpec(exposure_s=0.0))
        f = SyntheticCamera(model, scene, np.random.default_rng(int(p[0] * 1e6))).read(1.0)
        d = det.detect(f.image)[0]
        ray = sphere_ray(model, d.center_px, d.radius_px)  # centre, not ellipse centroid
        pixels.append(ray.normalized * model.focal_px + model.K[:2, 2])
    intrinsics = model.with_pose(np.eye(4))  # the pose is what we solve for
    res = calibrate_extrinsics(intrinsics, points, np.array(pixels))
    assert res.rms_px < 0.4 and res.rms_m < 1e-3
    dR = res.T_world_camera[:3, :3].T @ T_true[:3, :3]
    angle = np.degrees(np.arccos(np.clip((np.trace(dR) - 1) / 2, -1, 1)))
    assert angle < 0.1
    assert np.linalg.norm(res.T_world_camera[:3, 3] - T_true[:3, 3]) < 3e-3


def test_extrinsics_bad_input_is_refused():
    m = CameraModel.from_fov(640, 480, 60.0)
    line = np.column_stack([np.linspace(0, 0.5, 8), np.zeros(8), np.ones(8)])
    with pytest.raises(CalibrationError, match="one line"):
        calibrate_extrinsics(m, line, m.project(line))
    few = np.array([[0, 0, 1.0], [0.1, 0, 1], [0, 0.1, 1.2]])
    with pytest.raises(CalibrationError, match="too few"):
        calibrate_extrinsics(m, few, m.project(few))
    pts = np.random.default_rng(0).uniform(-0.2, 0.2, (8, 3)) + [0, 0, 1.0]
    px = m.project(pts)
    px[3] = np.nan
    with pytest.raises(CalibrationError, match="NaN"):
        calibrate_extrinsics(m, pts, px)
    with pytest.raises(CalibrationError, match="\\(N, 2\\)"):
        calibrate_extrinsics(m, pts, px[:5])
