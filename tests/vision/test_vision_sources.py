"""Camera sources: synthetic determinism and ground truth, files, folders, threaded reading
that never hangs on a stalled camera, and clear errors for missing cameras."""

from __future__ import annotations

import threading

import cv2
import numpy as np
import pytest

from vision.errors import CameraClosed, CameraError, CameraTimeout, FrameError
from vision.frame import Frame, validate_image
from vision.scene import BackgroundSpec, PointerScene, SensorSpec
from vision.sources import (
    FrameSource,
    ImageFolderSource,
    ReplaySource,
    SyntheticCamera,
    ThreadedSource,
    VideoCaptureSource,
    synthetic_cameras,
)
from vision.trajectories import lissajous


def _scene(centre):
    return PointerScene(lissajous(centre, [0.1, 0.1, 0.05]),
                        background=BackgroundSpec(n_distractors=5))


def test_synthetic_camera_is_deterministic_and_time_stamped(stereo_rig, centre):
    a = SyntheticCamera(stereo_rig[0], _scene(centre), np.random.default_rng(7), fps=50)
    b = SyntheticCamera(stereo_rig[0], _scene(centre), np.random.default_rng(7), fps=50)
    fa = [a.read(1.0) for _ in range(3)]
    fb = [b.read(1.0) for _ in range(3)]
    assert all(np.array_equal(x.image, y.image) for x, y in zip(fa, fb, strict=True))
    assert [f.timestamp for f in fa] == pytest.approx([0.0, 0.02, 0.04])
    assert isinstance(a, FrameSource)
    f = fa[1]
    assert f.image.shape == (480, 640, 3) and f.image.dtype == np.uint8
    assert np.allclose(f.truth.ball_world, _scene(centre).ball_at(0.02))
    assert np.allclose(f.truth.ball_px, stereo_rig[0].project(f.truth.ball_world))


def test_rendered_ball_is_red_where_the_truth_says(stereo_rig, centre):
    scene = PointerScene(centre, sensor=SensorSpec(exposure_s=0.0))
    f = SyntheticCamera(stereo_rig[1], scene, np.random.default_rng(0)).read(1.0)
    x, y = np.round(f.truth.ball_px).astype(int)
    b, g, r = f.image[y, x].astype(int)
    assert r > 120 and r > 2 * g and r > 2 * b
    assert 5.0 < f.truth.ball_radius_px < 9.0  # 25 mm at ~1 m with f = 554 px


def test_hidden_ball_is_not_drawn_and_truth_says_so(stereo_rig, centre):
    scene = PointerScene(centre, hidden=[(0.0, 1.0)], stick=None,
                         sensor=SensorSpec(exposure_s=0.0, noise_sigma=0.0),
                         background=BackgroundSpec(kind="plain"))
    f = SyntheticCamera(stereo_rig[0], scene, np.random.default_rng(0)).read(1.0)
    assert not f.truth.visible
    x, y = np.round(f.truth.ball_px).astype(int)
    b, g, r = f.image[y, x].astype(int)
    assert abs(r - g) < 10  # grey wall, no ball


def test_synthetic_camera_that_stops_times_out(stereo_rig, centre):
    cam = SyntheticCamera(stereo_rig[0], _scene(centre), fps=10, stop_after_s=0.15)
    cam.read(1.0)
    cam.read(1.0)
    with pytest.raises(CameraTimeout, match="no frame within"):
        cam.read(0.01)
    cam.close()
    with pytest.raises(CameraClosed):
        cam.read(0.01)


def test_synthetic_cameras_have_distinct_ids_and_noise(stereo_rig, centre):
    cams = synthetic_cameras([stereo_rig[0], stereo_rig[0]], _scene(centre), seed=1)
    assert [c.camera_id for c in cams] == ["cam0", "cam1"]
    assert not np.array_equal(cams[0].read(1.0).image, cams[1].read(1.0).image)


def test_threaded_source_does_not_hang_on_a_stalled_camera():
    never = threading.Event()

    def grab() -> Frame:
        never.wait()  # a driver call that never returns
        raise AssertionError("unreachable")

    src = ThreadedSource(grab, "stuck")
    with pytest.raises(CameraTimeout, match="'stuck'"):
        src.read(0.05)
    src.close()
    never.set()


def test_threaded_source_hands_on_driver_errors():
    calls = iter(range(3))

    def grab() -> Frame:
        k = next(calls)
        if k == 2:
            raise OSError("USB disconnect")
        return Frame(np.zeros((4, 4, 3), np.uint8), float(k), "usb")

    src = ThreadedSource(grab, "usb", keep_all=True)
    assert [src.read(1.0).timestamp for _ in range(2)] == [0.0, 1.0]
    with pytest.raises(CameraError, match="USB disconnect"):
        src.read(1.0)
    with pytest.raises(CameraError):  # and keeps saying so
        src.read(0.01)
    src.close()


def test_video_file_round_trip_through_videocapture(tmp_path, stereo_rig, centre):
    path = str(tmp_path / "pointer.avi")
    cam = SyntheticCamera(stereo_rig[0], _scene(centre), np.random.default_rng(0), fps=30)
    frames = [cam.read(1.0) for _ in range(4)]
    writer = cv2.VideoWriter(path, cv2.VideoWriter_fourcc(*"FFV1"), 30, (640, 480))
    assert writer.isOpened()
    for f in frames:
        writer.write(f.image)
    writer.release()
    src = VideoCaptureSource(path)
    got = [src.read(2.0) for _ in range(4)]
    assert all(np.array_equal(g.image, f.image) for g, f in zip(got, frames, strict=True))
    assert [g.timestamp for g in got] == pytest.approx([0, 1 / 30, 2 / 30, 3 / 30], abs=1e-3)
    with pytest.raises(CameraClosed, match="end of video"):
        src.read(2.0)
    src.close()


def test_missing_video_file_is_a_clear_error(tmp_path):
    with pytest.raises(CameraError, match="does not exist"):
        VideoCaptureSource(str(tmp_path / "nope.avi"))


def test_missing_camera_device_is_a_clear_error():
    with pytest.raises(CameraError, match="could not open camera 97"):
        VideoCaptureSource(97, open_timeout=5.0)


def test_image_folder_source(tmp_path):
    for k in range(3):
        cv2.imwrite(str(tmp_path / f"img{k:02d}.png"), np.full((20, 30, 3), 40 * k, np.uint8))
    (tmp_path / "notes.txt").write_text("not an image")
    src = ImageFolderSource(tmp_path, fps=10)
    got = [src.read() for _ in range(3)]
    assert [int(g.image[0, 0, 0]) for g in got] == [0, 40, 80]
    assert [g.timestamp for g in got] == pytest.approx([0.0, 0.1, 0.2])
    with pytest.raises(CameraClosed):
        src.read()


def test_image_folder_errors(tmp_path):
    with pytest.raises(CameraError, match="does not exist"):
        ImageFolderSource(tmp_path / "missing")
    with pytest.raises(CameraError, match="no images"):
        ImageFolderSource(tmp_path)
    (tmp_path / "broken.png").write_bytes(b"not a png")
    with pytest.raises(FrameError, match="broken.png"):
        ImageFolderSource(tmp_path).read()


def test_replay_source_ends_cleanly():
    src = ReplaySource([np.zeros((2, 2, 3), np.uint8)] * 2, "r", fps=10)
    assert src.read().timestamp == 0.0 and src.read().timestamp == pytest.approx(0.1)
    with pytest.raises(CameraClosed):
        src.read()


@pytest.mark.parametrize("image, match", [
    (np.zeros((480, 640), np.uint8), "expected \\(H, W, 3\\)"),
    (np.zeros((480, 640, 3), np.float32), "dtype float32"),
    (np.zeros((240, 320, 3), np.uint8), "320x240.*640x480"),
    (None, "not an image"),
])
def test_frame_validation_names_the_problem(image, match):
    with pytest.raises(FrameError, match=match):
        validate_image(image, 640, 480, "cam0")
