"""Software renderer behind the synthetic camera: exact ray-cast spheres with Phong shading and
anti-aliasing, a stick, planar calibration boards, a cluttered backdrop, motion blur, exposure
changes, lens distortion and sensor noise.

Everything is drawn into an ideal pinhole canvas (padded when the lens distorts, so the corners
of a barrel-distorted image still have content), then remapped through the camera's distortion,
so ground truth from `CameraModel.project` and the pixels agree to a small fraction of a pixel.

This module holds the per-camera canvas geometry, the cached static canvas and the frame
pipeline; the objects are drawn by `vision.render_primitives` and the backdrop comes from
`vision.render_backdrop`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import cv2
import numpy as np

from vision.camera_model import CameraModel
from vision.frame import GroundTruth
from vision.render_primitives import (
    NEAR_M,
    Canvas,
    _draw_sphere_reference,
    blend_stick,
    draw_board,
    draw_sphere,
    stick_footprint,
)
from vision.scene import PlanarTarget, PointerScene


class CanvasGeometry:
    """Per-camera constants: padded intrinsics and the distortion remap (computed once)."""

    def __init__(self, model: CameraModel) -> None:
        self.model = model
        if not model.has_distortion:
            self.pad = 0
            self.map_x = self.map_y = None
        else:
            u, v = np.meshgrid(np.arange(model.width, dtype=np.float64),
                               np.arange(model.height, dtype=np.float64))
            px = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
            crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-9)
            n = cv2.undistortPointsIter(px, model.K, model.dist, None, None, crit).reshape(-1, 2)
            ideal = n @ model.K[:2, :2].T + model.K[:2, 2]
            over = max(0.0, -ideal.min(), ideal[:, 0].max() - model.width,
                       ideal[:, 1].max() - model.height)
            self.pad = int(np.ceil(over)) + 4
            self.map_x = (ideal[:, 0] + self.pad).reshape(model.height, model.width)
            self.map_y = (ideal[:, 1] + self.pad).reshape(model.height, model.width)
            self.map_x, self.map_y = cv2.convertMaps(self.map_x.astype(np.float32),
                                                     self.map_y.astype(np.float32),
                                                     cv2.CV_16SC2)
        self.K = model.K.copy()
        self.K[0, 2] += self.pad
        self.K[1, 2] += self.pad
        self.shape = (model.height + 2 * self.pad, model.width + 2 * self.pad)
        #: (key, canvas, kept-alive inputs) of the last static canvas, see `_static_canvas`
        self.static_cache: tuple | None = None
        self._scratch = threading.local()

    def scratch(self) -> np.ndarray:
        """A float32 frame buffer for this thread, reused from frame to frame (a fresh
        allocation of this size costs more than filling it)."""
        buf = getattr(self._scratch, "frame", None)
        if buf is None:
            buf = np.empty((self.model.height, self.model.width, 3), np.float32)
            self._scratch.frame = buf
        return buf

    def finish(self, canvas: np.ndarray) -> np.ndarray:
        """Ideal canvas -> image as the distorting lens delivers it (float32)."""
        if self.map_x is None:
            return canvas
        return cv2.remap(canvas, self.map_x, self.map_y, cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REPLICATE)


# -- whole frame --------------------------------------------------------------------------------
def ball_truth(model: CameraModel, centre_world: np.ndarray | None, radius: float,
               hidden: bool) -> GroundTruth:
    """Where the ball centre projects and how big it looks (exact cone half-angle)."""
    if centre_world is None:
        return GroundTruth(None, None, 0.0, False)
    c_cam = model.to_camera(centre_world)[0]
    D = float(np.linalg.norm(c_cam))
    if c_cam[2] <= radius or D <= radius:
        return GroundTruth(np.asarray(centre_world, float), None, 0.0, False)
    px = model.project_camera(c_cam)[0]
    r_px = model.focal_px * np.tan(np.arcsin(radius / D))
    visible = (not hidden) and bool(model.in_image(px[None], margin=-r_px)[0])
    return GroundTruth(np.asarray(centre_world, float), px, float(r_px), visible)


def render_scene(geometry: CanvasGeometry, scene: PointerScene, t: float,
                 background: np.ndarray, rng: np.random.Generator, *,
                 reference: bool = False) -> np.ndarray:
    """One exposure centred on time t as uint8 BGR, with blur, gain, distortion and noise.

    Motion blur averages `blur_samples` renders across the exposure, but only inside the box
    the moving objects sweep, so a blurred frame costs little more than a sharp one. The static
    canvas (backdrop and boards) is cached per camera; a frame redraws only the region the stick
    and the moving objects cover. `reference=True` renders the straightforward way (the whole
    canvas, every sphere sample shaded) for tests to compare against.
    """
    if reference:
        return _render_scene_reference(geometry, scene, t, background, rng)
    model = geometry.model
    T_cw = model.T_camera_world
    sensor = scene.sensor
    n_sub = max(1, sensor.blur_samples) if sensor.exposure_s > 0 else 1
    times = [t] if n_sub == 1 else list(t + sensor.exposure_s * (np.linspace(0, 1, n_sub) - 0.5))
    static = _static_canvas(geometry, T_cw, scene.boards_at(t), background)
    ball = scene.ball_at(t)
    stick = None
    if scene.stick is not None and ball is not None and not scene.ball_hidden(t):
        # the stick is drawn sharp at mid-exposure: it is big, and its blur matters to no one
        s = scene.stick
        stick = stick_footprint(geometry.K, geometry.shape, T_cw, ball, s.direction_world,
                                 s.length, s.radius)
    box = _dynamic_box(geometry, scene, times)
    region = _union(stick[1] if stick is not None else None, box)
    patch = None
    if region is not None:
        rx0, ry0, rx1, ry1 = region
        patch = static[ry0:ry1, rx0:rx1].copy()
        if stick is not None:
            s = scene.stick
            blend_stick(patch, (rx0, ry0), stick, s.bgr, scene.lighting)
        if box is not None:
            x0, y0, x1, y1 = box
            K_roi = geometry.K.copy()
            K_roi[0, 2] -= x0
            K_roi[1, 2] -= y0
            sub = patch[y0 - ry0:y1 - ry0, x0 - rx0:x1 - rx0]
            acc = np.zeros((y1 - y0, x1 - x0, 3), np.float32)
            for ts in times:
                roi = Canvas(sub.copy(), K_roi, geometry.pad)
                _draw_objects(roi, T_cw, scene, ts)
                acc += roi.image
            sub[...] = acc / np.float32(len(times))
    gain = sensor.gain_at(t)
    noise = None
    if sensor.noise_sigma > 0:
        shape = (model.height, model.width, 3)
        noise = _noise(shape, rng, sensor.noise_sigma)
    if geometry.map_x is not None:  # the lens mixes neighbouring pixels: remap the whole canvas
        base = static.copy()
        if patch is not None:
            rx0, ry0, rx1, ry1 = region
            base[ry0:ry1, rx0:rx1] = patch
        img = geometry.finish(base)
        _expose(img, img, gain, noise)
    else:  # per-pixel from here on: expose the static canvas, then the redrawn region over it
        img = geometry.scratch()
        _expose(static, img, gain, noise)
        if patch is not None:
            rx0, ry0, rx1, ry1 = region
            _expose(patch, img[ry0:ry1, rx0:rx1], gain,
                    None if noise is None else noise[ry0:ry1, rx0:rx1])
    np.clip(img, 0, 255, out=img)
    return img.astype(np.uint8)


def _expose(src: np.ndarray, out: np.ndarray, gain: float, noise: np.ndarray | None) -> None:
    """Sensor gain, read noise and the +0.5 of rounding, in the order a frame gets them."""
    if gain != 1.0:
        np.multiply(src, np.float32(gain), out=out)
        src = out
    if noise is not None:
        np.add(src, noise, out=out)
        src = out
    np.add(src, np.float32(0.5), out=out)


def _union(a: tuple[int, int, int, int] | None,
           b: tuple[int, int, int, int] | None) -> tuple[int, int, int, int] | None:
    if a is None or b is None:
        return a if b is None else b
    return min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3])


def _static_canvas(geometry: CanvasGeometry, T_cw: np.ndarray, boards: list[PlanarTarget],
                   background: np.ndarray) -> np.ndarray:
    """Backdrop with the boards drawn in: the part of a frame that moves only when the camera,
    the backdrop or a board does, so it is drawn once and kept (read-only) on the geometry.

    Keyed by the camera pose, the backdrop array and each board's texture array, size and pose;
    the cache entry keeps those arrays alive, so their ids stay unique. Arrays are not compared
    by content: a backdrop or texture changed in place is not noticed (hand in a new array).
    """
    if not boards:
        return background
    key = (T_cw.tobytes(), geometry.K.tobytes(), id(background), background.shape,
           tuple((id(b.texture), b.texture.shape, float(b.width_m), float(b.height_m),
                  np.asarray(b.T_world_board, dtype=float).tobytes()) for b in boards))
    cached = geometry.static_cache
    if cached is not None and cached[0] == key:
        return cached[1]
    base = background.copy()
    for board in boards:
        draw_board(Canvas(base, geometry.K, geometry.pad), T_cw, board)
    base.flags.writeable = False
    geometry.static_cache = (key, base, (background, [b.texture for b in boards]))
    return base


def _render_scene_reference(geometry: CanvasGeometry, scene: PointerScene, t: float,
                            background: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """`render_scene` without caching or region tricks: the yardstick for tests."""
    model = geometry.model
    T_cw = model.T_camera_world
    sensor = scene.sensor
    n_sub = max(1, sensor.blur_samples) if sensor.exposure_s > 0 else 1
    times = [t] if n_sub == 1 else list(t + sensor.exposure_s * (np.linspace(0, 1, n_sub) - 0.5))
    base = background.copy()
    for board in scene.boards_at(t):
        draw_board(Canvas(base, geometry.K, geometry.pad), T_cw, board)
    ball = scene.ball_at(t)
    if scene.stick is not None and ball is not None and not scene.ball_hidden(t):
        s = scene.stick
        fp = stick_footprint(geometry.K, base.shape, T_cw, ball, s.direction_world, s.length,
                              s.radius)
        if fp is not None:
            blend_stick(base, (0, 0), fp, s.bgr, scene.lighting, sparse=False)
    box = _dynamic_box(geometry, scene, times)
    if box is not None:
        x0, y0, x1, y1 = box
        K_roi = geometry.K.copy()
        K_roi[0, 2] -= x0
        K_roi[1, 2] -= y0
        acc = np.zeros((y1 - y0, x1 - x0, 3), np.float32)
        for ts in times:
            roi = Canvas(base[y0:y1, x0:x1].copy(), K_roi, geometry.pad)
            _draw_objects(roi, T_cw, scene, ts, _draw_sphere_reference)
            acc += roi.image
        base[y0:y1, x0:x1] = acc / np.float32(len(times))
    img = geometry.finish(base)
    gain = sensor.gain_at(t)
    if gain != 1.0:
        img *= np.float32(gain)
    if sensor.noise_sigma > 0:
        img += _noise(img.shape, rng) * np.float32(sensor.noise_sigma)
    img += np.float32(0.5)
    np.clip(img, 0, 255, out=img)
    return img.astype(np.uint8)


_NOISE_BANK: dict[int, np.ndarray] = {}
_SCALED_NOISE: dict[tuple[int, float], np.ndarray] = {}


def _noise(shape: tuple[int, ...], rng: np.random.Generator,
           sigma: float | None = None) -> np.ndarray:
    """Unit Gaussian noise of `shape`: a random window into a bank 1.5x the frame size, drawn
    once per size (fresh draws for every frame cost more than the rest of the render).

    With `sigma` the window comes from the bank already scaled by float32(sigma), which is the
    same per element as scaling the window, and saves a pass over the frame.
    """
    n = int(np.prod(shape))
    bank = _NOISE_BANK.get(n)
    if bank is None:
        bank = np.random.default_rng(12345).standard_normal(n + n // 2, dtype=np.float32)
        _NOISE_BANK[n] = bank
    if sigma is not None:
        scaled = _SCALED_NOISE.get((n, sigma))
        if scaled is None:
            if len(_SCALED_NOISE) >= 8:  # many sigmas in one process: keep memory bounded
                _SCALED_NOISE.clear()
            scaled = bank * np.float32(sigma)
            _SCALED_NOISE[(n, sigma)] = scaled
        bank = scaled
    start = int(rng.integers(0, n // 2 + 1))
    return bank[start:start + n].reshape(shape)


def _dynamic_box(geometry: CanvasGeometry, scene: PointerScene,
                 times: list[float]) -> tuple[int, int, int, int] | None:
    """Canvas box (x0, y0, x1, y1) holding every ball and marker over the exposure."""
    T_cw = geometry.model.T_camera_world
    K = geometry.K
    f = float(max(K[0, 0], K[1, 1]))
    pts: list[np.ndarray] = []
    margins: list[float] = []
    near_plane = False

    def add(p_world: np.ndarray, extent: float) -> bool:
        nonlocal near_plane
        c = T_cw[:3, :3] @ p_world + T_cw[:3, 3]
        if c[2] < NEAR_M + extent:
            near_plane = True
            return False
        pts.append(c[:2] / c[2] * [K[0, 0], K[1, 1]] + K[:2, 2])
        margins.append(2.0 * f * extent / c[2] + 3.0)
        return True

    for ts in times:
        ball = scene.ball_at(ts)
        if ball is not None and not scene.ball_hidden(ts):
            add(ball, scene.ball_radius)
        for m in scene.markers:
            p = m.position(ts)
            if p is not None:
                add(p, m.radius)
    h, w = geometry.shape
    if near_plane:  # something crosses the near plane: let the draw functions clip it
        return 0, 0, w, h
    if not pts:
        return None
    P = np.array(pts)
    m = max(margins)
    x0 = int(max(0, np.floor(P[:, 0].min() - m)))
    y0 = int(max(0, np.floor(P[:, 1].min() - m)))
    x1 = int(min(w, np.ceil(P[:, 0].max() + m)))
    y1 = int(min(h, np.ceil(P[:, 1].max() + m)))
    if x0 >= x1 or y0 >= y1:
        return None
    return x0, y0, x1, y1


def _draw_objects(canvas: Canvas, T_cw: np.ndarray, scene: PointerScene, t: float,
                  draw: Callable[..., None] = draw_sphere) -> None:
    """Markers and the pointer ball, far to near so nearer balls cover farther ones."""
    items: list[tuple[float, str, object]] = []
    ball = scene.ball_at(t)
    if ball is not None and not scene.ball_hidden(t):
        depth = (T_cw[:3, :3] @ ball + T_cw[:3, 3])[2]
        items.append((depth, "ball", ball))
    for m in scene.markers:
        p = m.position(t)
        if p is not None:
            items.append(((T_cw[:3, :3] @ p + T_cw[:3, 3])[2], "marker", (m, p)))
    for _, kind, obj in sorted(items, key=lambda it: -it[0]):
        if kind == "ball":
            draw(canvas, T_cw, obj, scene.ball_radius, scene.ball_bgr, scene.lighting)
        else:
            m, p = obj
            draw(canvas, T_cw, p, m.radius, m.bgr, scene.lighting)
