"""Camera sources: real cameras and files through OpenCV, image folders, replayed frames and the
synthetic camera that renders a `PointerScene` with exact ground truth.

Every source has `camera_id`, `read(timeout) -> Frame` and `close()`. A source that may block
(a device or stream that stalls, a cable pulled) reads on its own thread, so `read` returns or
raises `CameraTimeout` within `timeout` instead of hanging the pipeline.
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Protocol, runtime_checkable

import cv2
import numpy as np

from vision.camera_model import CameraModel
from vision.errors import CameraClosed, CameraError, CameraTimeout, FrameError
from vision.frame import Frame
from vision.render import CanvasGeometry, ball_truth, render_scene
from vision.render_backdrop import make_background
from vision.scene import PointerScene


@runtime_checkable
class FrameSource(Protocol):
    """What the pointer pipeline needs from a camera."""

    camera_id: str

    def read(self, timeout: float) -> Frame: ...

    def close(self) -> None: ...


# -- synthetic ----------------------------------------------------------------------------------
class SyntheticCamera:
    """Renders `scene` as seen by `model` at a fixed frame rate in simulated time.

    Frame i is exposed around t = start_time + i / fps (its timestamp); `Frame.truth` holds the
    ball's true world position and projection at that time. Deterministic for a given `rng`.
    `stop_after_s` simulates a camera that stops delivering: later reads wait out the timeout
    and raise `CameraTimeout`, as a stalled real camera would.
    """

    def __init__(self, model: CameraModel, scene: PointerScene,
                 rng: np.random.Generator | None = None, *, camera_id: str = "cam0",
                 fps: float = 60.0, start_time: float = 0.0,
                 stop_after_s: float | None = None) -> None:
        if fps <= 0:
            raise ValueError("fps must be positive")
        self.model = model
        self.scene = scene
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.camera_id = camera_id
        self.fps = float(fps)
        self.start_time = float(start_time)
        self.stop_after_s = stop_after_s
        self.geometry = CanvasGeometry(model)
        h, w = self.geometry.shape
        self.background = make_background(w, h, scene.background, self.rng)
        self.index = 0
        self._closed = False

    @property
    def time(self) -> float:
        """Timestamp of the next frame."""
        return self.start_time + self.index / self.fps

    def render(self, t: float) -> Frame:
        """The frame at time t (does not advance the camera's clock)."""
        img = render_scene(self.geometry, self.scene, t, self.background, self.rng)
        truth = ball_truth(self.model, self.scene.ball_at(t), self.scene.ball_radius,
                           self.scene.ball_hidden(t))
        return Frame(img, t, self.camera_id, truth)

    def read(self, timeout: float = 1.0) -> Frame:
        if self._closed:
            raise CameraClosed(f"camera {self.camera_id!r} is closed")
        t = self.time
        if self.stop_after_s is not None and t >= self.start_time + self.stop_after_s:
            time.sleep(max(0.0, timeout))
            raise CameraTimeout(f"camera {self.camera_id!r}: no frame within {timeout:.2f} s")
        self.index += 1
        return self.render(t)

    def close(self) -> None:
        self._closed = True


def synthetic_cameras(models: Sequence[CameraModel], scene: PointerScene, seed: int = 0,
                      fps: float = 60.0) -> list[SyntheticCamera]:
    """One synthetic camera per model, ids cam0, cam1, ..., independent seeded noise."""
    seeds = np.random.SeedSequence(seed).spawn(len(models))
    return [SyntheticCamera(m, scene, np.random.default_rng(s), camera_id=f"cam{i}", fps=fps)
            for i, (m, s) in enumerate(zip(models, seeds, strict=True))]


# -- replay and folders -------------------------------------------------------------------------
class ReplaySource:
    """Hands out given frames (or raw images at `fps`) in order; for tests and benchmarks."""

    def __init__(self, frames: Sequence[Frame | np.ndarray], camera_id: str = "replay",
                 fps: float = 60.0, loop: bool = False) -> None:
        self.camera_id = camera_id
        self._frames = list(frames)
        self._fps = fps
        self._loop = loop
        self.index = 0

    def read(self, timeout: float = 1.0) -> Frame:
        if self.index >= len(self._frames) and (not self._loop or not self._frames):
            raise CameraClosed(f"camera {self.camera_id!r}: replay ended")
        i = self.index % len(self._frames)
        lap = self.index // len(self._frames)
        self.index += 1
        f = self._frames[i]
        period = len(self._frames) / self._fps
        if isinstance(f, Frame):
            return Frame(f.image, f.timestamp + lap * period, self.camera_id, f.truth)
        return Frame(f, (self.index - 1) / self._fps, self.camera_id)

    def close(self) -> None:
        self.index = len(self._frames)
        self._loop = False


_IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}


class ImageFolderSource:
    """Images of a folder in name order, time-stamped at `fps`."""

    def __init__(self, folder: str | os.PathLike, camera_id: str | None = None,
                 fps: float = 30.0, loop: bool = False) -> None:
        path = Path(folder)
        if not path.is_dir():
            raise CameraError(f"image folder {str(path)!r} does not exist")
        self.files = sorted(p for p in path.iterdir() if p.suffix.lower() in _IMAGE_SUFFIXES)
        if not self.files:
            raise CameraError(f"image folder {str(path)!r} holds no images "
                              f"({', '.join(sorted(_IMAGE_SUFFIXES))})")
        self.camera_id = camera_id or path.name
        self.fps = fps
        self.loop = loop
        self.index = 0

    def read(self, timeout: float = 1.0) -> Frame:
        if self.index >= len(self.files) and not self.loop:
            raise CameraClosed(f"camera {self.camera_id!r}: no more images in the folder")
        f = self.files[self.index % len(self.files)]
        t = self.index / self.fps
        self.index += 1
        img = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if img is None:
            raise FrameError(f"camera {self.camera_id!r}: cannot read image {f.name!r}")
        return Frame(img, t, self.camera_id)

    def close(self) -> None:
        self.index = len(self.files)
        self.loop = False


# -- threaded reading ---------------------------------------------------------------------------
class _End:
    def __init__(self, error: Exception) -> None:
        self.error = error


class ThreadedSource:
    """Runs a blocking `grab()` on a daemon thread so `read(timeout)` can never hang.

    `keep_all=True` queues every frame (files: nothing may be skipped); otherwise only the
    newest frame is kept (live cameras: never process stale frames). When `grab` raises, the
    error is handed to the next `read` (after frames already queued) and the thread ends.
    """

    def __init__(self, grab: Callable[[], Frame], camera_id: str, *, keep_all: bool = False,
                 queue_size: int = 4, on_close: Callable[[], None] | None = None) -> None:
        self.camera_id = camera_id
        self._grab = grab
        self._keep_all = keep_all
        self._queue: queue.Queue = queue.Queue(maxsize=queue_size if keep_all else 1)
        self._stop = threading.Event()
        self._on_close = on_close
        self._ended: Exception | None = None
        self._thread = threading.Thread(target=self._run, name=f"camera-{camera_id}",
                                        daemon=True)
        self._thread.start()

    def _put(self, item: object) -> None:
        if self._keep_all:
            while not self._stop.is_set():
                try:
                    self._queue.put(item, timeout=0.05)
                    return
                except queue.Full:
                    continue
        else:
            while True:
                try:
                    self._queue.put_nowait(item)
                    return
                except queue.Full:
                    with contextlib.suppress(queue.Empty):
                        self._queue.get_nowait()  # drop the stale frame

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                frame = self._grab()
            except CameraError as exc:
                self._put(_End(exc))
                return
            except Exception as exc:  # a driver error must reach the caller, not kill silently
                self._put(_End(CameraError(f"camera {self.camera_id!r} failed: {exc}")))
                return
            self._put(frame)

    def read(self, timeout: float = 1.0) -> Frame:
        if self._ended is not None:
            raise self._ended
        try:
            item = self._queue.get(timeout=max(0.0, timeout))
        except queue.Empty:
            raise CameraTimeout(
                f"camera {self.camera_id!r}: no frame within {timeout:.2f} s "
                "(slow, stalled or unplugged)"
            ) from None
        if isinstance(item, _End):
            self._ended = item.error
            raise item.error
        return item

    def close(self) -> None:
        self._stop.set()
        if self._ended is None:
            self._ended = CameraClosed(f"camera {self.camera_id!r} is closed")
        if self._on_close is not None:
            self._on_close()
        self._thread.join(timeout=0.5)


class VideoCaptureSource:
    """A camera device (index), video file or stream URL through `cv2.VideoCapture`.

    Opening and grabbing happen on a reader thread: a device that never answers makes the
    constructor raise `CameraTimeout` after `open_timeout` and `read` raise after `timeout`.
    Files deliver every frame with their own timestamps; devices and streams deliver the newest
    frame stamped with the time it was grabbed (`time.monotonic()`).
    """

    def __init__(self, spec: int | str, camera_id: str | None = None, *,
                 size: tuple[int, int] | None = None, open_timeout: float = 5.0) -> None:
        if isinstance(spec, str) and spec.isdigit():
            spec = int(spec)
        self.spec = spec
        self.is_file = isinstance(spec, str) and Path(spec).is_file()
        if isinstance(spec, str) and "://" not in spec and not self.is_file:
            raise CameraError(f"video file {spec!r} does not exist")
        self.camera_id = camera_id or (f"camera{spec}" if isinstance(spec, int)
                                       else Path(str(spec)).stem)
        self._cap: cv2.VideoCapture | None = None
        self._size = size
        self._opened = threading.Event()
        self._open_error: Exception | None = None
        self._lock = threading.Lock()
        self._threaded = ThreadedSource(self._grab, self.camera_id, keep_all=self.is_file,
                                        on_close=self._release)
        if not self._opened.wait(open_timeout):
            self._threaded.close()
            raise CameraTimeout(f"camera {self.camera_id!r} did not open within "
                                f"{open_timeout:.1f} s")
        if self._open_error is not None:
            self._threaded.close()
            raise self._open_error

    def _open(self) -> None:
        cap = cv2.VideoCapture(self.spec)
        if not cap.isOpened():
            cap.release()
            raise CameraError(f"could not open camera {self.spec!r}: no such device, file or "
                              "stream (check the index, path or URL and the cable)")
        if self._size is not None:
            cap.set(cv2.CAP_PROP_FRAME_WIDTH, self._size[0])
            cap.set(cv2.CAP_PROP_FRAME_HEIGHT, self._size[1])
        self._cap = cap

    def _grab(self) -> Frame:
        if self._cap is None:
            try:
                self._open()
            except CameraError as exc:
                self._open_error = exc
                self._opened.set()
                raise
            self._opened.set()
        with self._lock:
            if self._cap is None:
                raise CameraClosed(f"camera {self.camera_id!r} is closed")
            ok, img = self._cap.read()
            stamp = (self._cap.get(cv2.CAP_PROP_POS_MSEC) / 1000.0 if self.is_file
                     else time.monotonic())
        if not ok or img is None:
            if self.is_file:
                raise CameraClosed(f"camera {self.camera_id!r}: end of video file")
            raise CameraError(f"camera {self.camera_id!r} stopped delivering frames")
        if img.ndim == 2:
            img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
        return Frame(img, stamp, self.camera_id)

    def _release(self) -> None:
        with self._lock:
            if self._cap is not None:
                self._cap.release()
                self._cap = None

    def read(self, timeout: float = 1.0) -> Frame:
        return self._threaded.read(timeout)

    def close(self) -> None:
        self._threaded.close()
