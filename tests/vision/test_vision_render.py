"""The fast renderer (hit-only sphere shading, cached static canvas, per-region redraw) gives
the same frames as the straightforward reference path, across moving frames and scene changes."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from vision.calibration_targets import ChessboardSpec
from vision.camera_model import CameraModel
from vision.render import CanvasGeometry, render_scene
from vision.render_backdrop import make_background
from vision.render_primitives import Canvas, _draw_sphere_reference, draw_sphere
from vision.rigs import look_at
from vision.scene import (
    BLUE_MARKER_BGR,
    GREEN_MARKER_BGR,
    BackgroundSpec,
    Lighting,
    PointerScene,
    SensorSpec,
    SphereMarker,
)
from vision.scripted import board_poses
from vision.trajectories import lissajous

# The sphere's dot products are summed in a different order than the reference's einsum/matmul
# (whose order depends on the array shape and the CPU), so float64 colours may differ in the
# last bits; rounded to float32 and then to grey levels this almost never shows.
MAX_FRACTION_OFF = 1e-5  # of all pixel values in a frame, each off by at most one grey level


def _assert_same_frame(fast: np.ndarray, ref: np.ndarray) -> None:
    assert fast.shape == ref.shape and fast.dtype == ref.dtype == np.uint8
    diff = np.abs(fast.astype(np.int16) - ref.astype(np.int16))
    assert diff.max() <= 1
    assert np.count_nonzero(diff) <= MAX_FRACTION_OFF * diff.size


def _render_both(geometry: CanvasGeometry, scene: PointerScene, t: float,
                 background: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Fast frame (advancing `rng`), checked against the reference from a copy of `rng`."""
    ref = render_scene(geometry, scene, t, background, copy.deepcopy(rng), reference=True)
    fast = render_scene(geometry, scene, t, background, rng)
    _assert_same_frame(fast, ref)
    return fast


@pytest.mark.parametrize("centre_cam", [
    (0.0, 0.0, 1.0),       # on axis
    (0.52, 0.38, 0.9),     # far corner: the outline is an ellipse
    (0.575, -0.1, 1.0),    # cut by the right image edge
    (0.0, 0.0, 0.05),      # close: big, just behind the near plane limit
    (0.01, 0.02, 3.5),     # far: a few pixels
])
def test_sphere_matches_the_reference_drawing(centre_cam):
    model = CameraModel.from_fov(640, 480, 60.0)
    rng = np.random.default_rng(1)
    bg = rng.uniform(0, 255, (480, 640, 3)).astype(np.float32)
    light = Lighting(direction_world=np.array([-0.4, 0.3, -1.0]), shininess=25.0)
    fast, ref = bg.copy(), bg.copy()
    args = (np.eye(4), np.array(centre_cam), 0.0125, (0.13, 0.13, 0.82), light)
    draw_sphere(Canvas(fast, model.K, 0), *args)
    _draw_sphere_reference(Canvas(ref, model.K, 0), *args)
    assert not np.array_equal(ref, bg)  # something was drawn
    # float64 rounding of the dot products, seen through the float32 canvas
    assert np.abs(fast - ref).max() <= 1e-3


def test_moving_ball_markers_and_stick_over_frames(stereo_rig, centre):
    """A blurred ball on its stick moves between frames, one marker stands, one moves: every
    frame matches the reference while the (backdrop-only) static canvas is reused."""
    scene = PointerScene(
        lissajous(centre, [0.12, 0.1, 0.06], freq_hz=(0.9, 0.7, 0.5)),
        markers=[SphereMarker(centre + [0.05, 0.02, 0.0], bgr=BLUE_MARKER_BGR),
                 SphereMarker(lissajous(centre + [-0.05, 0.0, 0.05], [0.03, 0.03, 0.0]),
                              bgr=GREEN_MARKER_BGR)],
        hidden=[(0.25, 0.3)],
        background=BackgroundSpec(n_distractors=4),
        sensor=SensorSpec(noise_sigma=2.0, exposure_s=0.02, blur_samples=5))
    for model in stereo_rig:
        geometry = CanvasGeometry(model)
        rng = np.random.default_rng(5)
        bg = make_background(model.width, model.height, scene.background, rng)
        frames = [_render_both(geometry, scene, t, bg, rng)
                  for t in np.arange(0.0, 0.6, 1 / 30)]
        assert not np.array_equal(frames[0], frames[1])  # the ball moved


def test_board_change_and_camera_move_invalidate_the_static_canvas():
    """Boards are part of the cached static canvas: a new board pose, a new backdrop or a moved
    camera must give a new canvas, and frames must still match the reference."""
    model = CameraModel.from_fov(640, 480, 60.0)
    board = ChessboardSpec(7, 5, 0.03)
    poses = board_poses(model, *board.texture()[1:], 2, seed=3)
    targets = [board.target(T) for T in poses]
    path = lissajous(np.array([0.0, 0.0, 0.8]), [0.05, 0.05, 0.0], freq_hz=(2.0, 1.5, 1.0))
    scene = PointerScene(path, stick=None, boards=lambda t: [targets[0] if t < 0.5 else targets[1]],
                         sensor=SensorSpec(noise_sigma=1.5, exposure_s=0.01, blur_samples=3))
    geometry = CanvasGeometry(model)
    rng = np.random.default_rng(2)
    bg = make_background(640, 480, BackgroundSpec(kind="plain"), rng)
    _render_both(geometry, scene, 0.0, bg, rng)
    first = geometry.static_cache[1]
    _render_both(geometry, scene, 0.1, bg, rng)
    assert geometry.static_cache[1] is first  # same board, same camera: reused
    _render_both(geometry, scene, 0.6, bg, rng)
    second = geometry.static_cache[1]
    assert second is not first and not np.array_equal(second, first)
    bg2 = make_background(640, 480, BackgroundSpec(kind="cluttered"), rng)
    _render_both(geometry, scene, 0.7, bg2, rng)
    assert geometry.static_cache[1] is not second
    third = geometry.static_cache[1]
    T = model.T_world_camera.copy()
    T[:3, 3] += [0.01, 0.0, 0.0]
    model.T_world_camera = T
    _render_both(geometry, scene, 0.8, bg2, rng)
    assert geometry.static_cache[1] is not third


def test_distorting_lens_gain_and_sharp_exposure():
    """The lens remap, a gain ramp and blur-free exposure take the whole-canvas route."""
    T = look_at(np.array([0.0, -0.8, 0.4]), np.array([0.0, 0.0, 0.2]))
    model = CameraModel.from_fov(640, 480, 70.0, T_world_camera=T,
                                 dist=[-0.15, 0.04, 0.0005, -0.0003, 0.0])
    scene = PointerScene(lissajous(np.array([0.05, 0.0, 0.2]), [0.05, 0.04, 0.03]),
                         markers=[SphereMarker(np.array([-0.1, 0.05, 0.15]))],
                         sensor=SensorSpec(noise_sigma=0.0, exposure_s=0.0,
                                           gain=lambda t: 0.8 + t))
    geometry = CanvasGeometry(model)
    assert geometry.map_x is not None
    rng = np.random.default_rng(9)
    h, w = geometry.shape
    bg = make_background(w, h, scene.background, rng)
    for t in (0.0, 0.05, 0.3):
        _render_both(geometry, scene, t, bg, rng)
