"""Software renderer behind the synthetic camera: exact ray-cast spheres with Phong shading and
anti-aliasing, a stick, planar calibration boards, a cluttered backdrop, motion blur, exposure
changes, lens distortion and sensor noise.

Everything is drawn into an ideal pinhole canvas (padded when the lens distorts, so the corners
of a barrel-distorted image still have content), then remapped through the camera's distortion,
so ground truth from `CameraModel.project` and the pixels agree to a small fraction of a pixel.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vision.camera_model import CameraModel
from vision.frame import GroundTruth
from vision.scene import BackgroundSpec, Lighting, PlanarTarget, PointerScene

_SUPERSAMPLE = 4  # sphere sub-pixel samples per axis
_BOARD_SUPERSAMPLE = 3
_NEAR = 0.02  # metres: nothing closer to the optical centre is drawn


@dataclass
class Canvas:
    """The ideal (undistorted) image an object is drawn into, with its own intrinsics."""

    image: np.ndarray  # float32 HxWx3, 0..255
    K: np.ndarray
    pad: int


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

    def finish(self, canvas: np.ndarray) -> np.ndarray:
        """Ideal canvas -> image as the distorting lens delivers it (float32)."""
        if self.map_x is None:
            return canvas
        return cv2.remap(canvas, self.map_x, self.map_y, cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REPLICATE)


# -- background ---------------------------------------------------------------------------------
def _hsv_to_bgr(h: float, s: float, v: float) -> tuple[float, float, float]:
    px = np.uint8([[[int(h) % 180, int(s), int(v)]]])
    b, g, r = cv2.cvtColor(px, cv2.COLOR_HSV2BGR)[0, 0]
    return float(b), float(g), float(r)


def _safe_colour(rng: np.random.Generator) -> tuple[float, float, float]:
    """A clutter colour that is not red or orange (hue 25..160) or is nearly grey."""
    if rng.random() < 0.4:
        g = rng.uniform(30, 230)
        return _hsv_to_bgr(0, rng.uniform(0, 30), g)
    return _hsv_to_bgr(rng.uniform(25, 160), rng.uniform(40, 255), rng.uniform(60, 240))


def _distractor_colour(rng: np.random.Generator) -> tuple[float, float, float]:
    h = rng.choice([rng.uniform(0, 6), rng.uniform(172, 180), rng.uniform(8, 22)])
    return _hsv_to_bgr(h, rng.uniform(150, 255), rng.uniform(120, 240))


def make_background(width: int, height: int, spec: BackgroundSpec,
                    rng: np.random.Generator) -> np.ndarray:
    """Static backdrop (float32 0..255): a lit grey wall, optionally cluttered and with
    red/orange distractors that a naive colour threshold would take for the ball."""
    y = np.linspace(0.0, 1.0, height, dtype=np.float32)[:, None]
    x = np.linspace(0.0, 1.0, width, dtype=np.float32)[None, :]
    shade = 0.85 + 0.25 * (1.0 - y) * (0.7 + 0.3 * x)
    img = (np.asarray(spec.base_bgr, dtype=np.float32) * 255.0)[None, None, :] * shade[..., None]
    img = np.ascontiguousarray(img, dtype=np.float32)
    if spec.kind == "plain":
        return img
    diag = float(np.hypot(width, height))
    for _ in range(spec.n_shapes):
        colour = _safe_colour(rng)
        kind = rng.integers(0, 4)
        cx, cy = int(rng.uniform(0, width)), int(rng.uniform(0, height))
        if kind == 0:
            w, h = rng.uniform(0.02, 0.25, 2) * diag
            box = ((cx, cy), (float(w), float(h)), float(rng.uniform(0, 180)))
            cv2.fillConvexPoly(img, cv2.boxPoints(box).astype(np.int32), colour, cv2.LINE_AA)
        elif kind == 1:
            cv2.circle(img, (cx, cy), int(rng.uniform(0.01, 0.08) * diag), colour, -1,
                       cv2.LINE_AA)
        elif kind == 2:
            p2 = (int(rng.uniform(0, width)), int(rng.uniform(0, height)))
            cv2.line(img, (cx, cy), p2, colour, int(rng.integers(1, 8)), cv2.LINE_AA)
        else:
            cv2.ellipse(img, (cx, cy), tuple(int(a) for a in rng.uniform(5, 0.1 * diag, 2)),
                        float(rng.uniform(0, 180)), 0, 360, colour, -1, cv2.LINE_AA)
    for _ in range(spec.n_distractors):
        _draw_distractor(img, rng, width, height)
    # a little surface texture so the wall is not perfectly flat
    img += rng.normal(0.0, 3.0, img.shape).astype(np.float32)
    return np.clip(img, 0, 255, out=img)


def _draw_distractor(img: np.ndarray, rng: np.random.Generator, width: int, height: int) -> None:
    """One red/orange thing that is not a 2.5 cm ball: the shapes a shop floor offers."""
    colour = _distractor_colour(rng)
    cx, cy = int(rng.uniform(0, width)), int(rng.uniform(0, height))
    kind = int(rng.integers(0, 7))
    if kind == 0:  # bar / label / cable
        w, h = rng.uniform(30, 160), rng.uniform(3, 12)
        box = ((cx, cy), (float(w), float(h)), float(rng.uniform(0, 180)))
        cv2.fillConvexPoly(img, cv2.boxPoints(box).astype(np.int32), colour, cv2.LINE_AA)
    elif kind == 1:  # text on a warning sign
        cv2.putText(img, "STOP", (cx, cy), cv2.FONT_HERSHEY_SIMPLEX, rng.uniform(0.6, 1.5),
                    colour, int(rng.integers(2, 4)), cv2.LINE_AA)
    elif kind == 2:  # dust of red specks (sensor or paint): the median filter's job
        for _ in range(12):
            p = (int(cx + rng.normal(0, 25)), int(cy + rng.normal(0, 25)))
            cv2.circle(img, p, 1, colour, -1)
    elif kind == 3:  # a big red disc (emergency stop button up close, a lamp)
        cv2.circle(img, (cx, cy), int(rng.uniform(28, 60)), colour, -1, cv2.LINE_AA)
    elif kind == 4:  # elongated blob (hose, hand in a red glove seen edge-on)
        a = rng.uniform(15, 40)
        cv2.ellipse(img, (cx, cy), (int(a), int(a * rng.uniform(0.2, 0.45))),
                    float(rng.uniform(0, 180)), 0, 360, colour, -1, cv2.LINE_AA)
    elif kind == 5:  # an orange ball of pointer size: hue must reject it
        cv2.circle(img, (cx, cy), int(rng.uniform(4, 10)),
                   _hsv_to_bgr(rng.uniform(12, 22), 230, 230), -1, cv2.LINE_AA)
    else:  # a red square sticker: round by moments, not by shape
        s = rng.uniform(10, 18)
        box = ((cx, cy), (float(s), float(s)), float(rng.uniform(0, 90)))
        cv2.fillConvexPoly(img, cv2.boxPoints(box).astype(np.int32), colour, cv2.LINE_AA)


# -- objects ------------------------------------------------------------------------------------
def draw_sphere(canvas: Canvas, T_camera_world: np.ndarray, centre_world: np.ndarray,
                radius: float, albedo_bgr: tuple[float, float, float],
                lighting: Lighting) -> None:
    """Ray-cast a Phong-shaded sphere with 4x4 supersampling into the canvas (in place)."""
    R_cw, t_cw = T_camera_world[:3, :3], T_camera_world[:3, 3]
    c = R_cw @ np.asarray(centre_world, dtype=float) + t_cw
    if c[2] - radius < _NEAR:
        return
    K = canvas.K
    corners = c + radius * np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                                     for sz in (-1, 1)])
    uv = corners[:, :2] / corners[:, 2:3] * [K[0, 0], K[1, 1]] + K[:2, 2]
    h, w = canvas.image.shape[:2]
    x0, y0 = np.floor(uv.min(axis=0)).astype(int) - 1
    x1, y1 = np.ceil(uv.max(axis=0)).astype(int) + 2
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x0 >= x1 or y0 >= y1:
        return
    ss = _SUPERSAMPLE
    off = (np.arange(ss) + 0.5) / ss - 0.5
    us = (np.arange(x0, x1)[:, None] + off[None, :]).ravel()
    vs = (np.arange(y0, y1)[:, None] + off[None, :]).ravel()
    U, V = np.meshgrid(us, vs)
    d = np.stack([(U - K[0, 2]) / K[0, 0], (V - K[1, 2]) / K[1, 1], np.ones_like(U)], axis=-1)
    a = np.einsum("...i,...i->...", d, d)
    b = d @ c
    disc = b * b - a * (c @ c - radius * radius)
    hit = disc > 0
    tt = (b - np.sqrt(np.where(hit, disc, 0.0))) / a
    p = d * tt[..., None]
    n = (p - c) / radius
    L = R_cw @ lighting.direction_world
    view = -p / np.linalg.norm(p, axis=-1, keepdims=True)
    half = L + view
    half /= np.linalg.norm(half, axis=-1, keepdims=True)
    diff = np.clip(n @ L, 0.0, None)
    spec = np.clip(np.einsum("...i,...i->...", n, half), 0.0, None) ** lighting.shininess
    colour = (np.asarray(albedo_bgr) * (lighting.ambient + lighting.diffuse * diff)[..., None]
              + lighting.specular * spec[..., None]) * 255.0
    colour *= hit[..., None]
    ny, nx = y1 - y0, x1 - x0
    cov = hit.reshape(ny, ss, nx, ss).mean(axis=(1, 3))
    col = colour.reshape(ny, ss, nx, ss, 3).mean(axis=(1, 3))
    roi = canvas.image[y0:y1, x0:x1]
    roi *= (1.0 - cov)[..., None].astype(np.float32)
    roi += np.minimum(col, 255.0).astype(np.float32)


def draw_stick(canvas: Canvas, T_camera_world: np.ndarray, start_world: np.ndarray,
               direction_world: np.ndarray, length: float, radius: float,
               albedo_bgr: tuple[float, float, float], lighting: Lighting) -> None:
    """The pointer's stick as a tapered anti-aliased quad (perspective width at both ends)."""
    R_cw, t_cw = T_camera_world[:3, :3], T_camera_world[:3, 3]
    a = R_cw @ np.asarray(start_world, dtype=float) + t_cw
    b = R_cw @ (np.asarray(start_world) + length * np.asarray(direction_world)) + t_cw
    if a[2] < _NEAR and b[2] < _NEAR:
        return
    if a[2] < _NEAR or b[2] < _NEAR:  # clip at the near plane
        s = (_NEAR - a[2]) / (b[2] - a[2])
        if a[2] < _NEAR:
            a = a + s * (b - a)
        else:
            b = a + s * (b - a)
    K = canvas.K
    f = 0.5 * (K[0, 0] + K[1, 1])
    pa = a[:2] / a[2] * [K[0, 0], K[1, 1]] + K[:2, 2]
    pb = b[:2] / b[2] * [K[0, 0], K[1, 1]] + K[:2, 2]
    axis = pb - pa
    if np.linalg.norm(axis) < 1e-6:
        return
    nrm = np.array([-axis[1], axis[0]]) / np.linalg.norm(axis)
    wa, wb = f * radius / a[2], f * radius / b[2]
    quad = np.array([pa + nrm * wa, pb + nrm * wb, pb - nrm * wb, pa - nrm * wa])
    h, w = canvas.image.shape[:2]
    x0, y0 = np.maximum(np.floor(quad.min(axis=0)).astype(int) - 2, 0)
    x1, y1 = np.minimum(np.ceil(quad.max(axis=0)).astype(int) + 3, [w, h])
    if x0 >= x1 or y0 >= y1:
        return
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    pts = np.round((quad - [x0, y0]) * 16).astype(np.int32)
    cv2.fillConvexPoly(mask, pts, 255, cv2.LINE_AA, shift=4)
    alpha = (mask.astype(np.float32) / 255.0)[..., None]
    shade = lighting.ambient + 0.5 * lighting.diffuse
    colour = (np.asarray(albedo_bgr, dtype=np.float32) * shade * 255.0)[None, None, :]
    roi = canvas.image[y0:y1, x0:x1]
    roi *= 1.0 - alpha
    roi += alpha * colour


def draw_board(canvas: Canvas, T_camera_world: np.ndarray, board: PlanarTarget) -> None:
    """Warp a printed pattern into the canvas with 3x3 supersampling (sharp, sub-pixel exact)."""
    T_cb = T_camera_world @ board.T_world_board
    th, tw = board.texture.shape[:2]
    sx, sy = board.width_m / tw, board.height_m / th
    S = np.array([[sx, 0, 0.5 * sx], [0, sy, 0.5 * sy], [0, 0, 1.0]])
    H = canvas.K @ np.column_stack([T_cb[:3, 0], T_cb[:3, 1], T_cb[:3, 3]]) @ S
    # texture pixel -> canvas pixel
    h, w = canvas.image.shape[:2]
    corners = np.array([[-0.5, -0.5, 1], [tw - 0.5, -0.5, 1], [tw - 0.5, th - 0.5, 1],
                        [-0.5, th - 0.5, 1]]).T
    proj = H @ corners
    if np.any(proj[2] <= 0):
        return  # the board plane crosses behind the camera: not a view anyone calibrates with
    uv = (proj[:2] / proj[2]).T
    x0, y0 = np.maximum(np.floor(uv.min(axis=0)).astype(int) - 1, 0)
    x1, y1 = np.minimum(np.ceil(uv.max(axis=0)).astype(int) + 2, [w, h])
    if x0 >= x1 or y0 >= y1:
        return
    ss = _BOARD_SUPERSAMPLE
    # canvas pixel u <-> supersampled pixel ss*(u - x0) + (ss - 1)/2
    A = np.array([[ss, 0, (ss - 1) / 2 - ss * x0], [0, ss, (ss - 1) / 2 - ss * y0], [0, 0, 1.0]])
    bw, bh = x1 - x0, y1 - y0
    tex = board.texture.astype(np.float32)
    warped = cv2.warpPerspective(tex, A @ H, (bw * ss, bh * ss), flags=cv2.INTER_LINEAR)
    alpha = cv2.warpPerspective(np.ones((th, tw), np.float32), A @ H, (bw * ss, bh * ss),
                                flags=cv2.INTER_LINEAR)
    warped = cv2.resize(warped, (bw, bh), interpolation=cv2.INTER_AREA)
    alpha = cv2.resize(alpha, (bw, bh), interpolation=cv2.INTER_AREA)[..., None]
    roi = canvas.image[y0:y1, x0:x1]
    roi *= 1.0 - alpha
    roi += warped


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
                 background: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One exposure centred on time t as uint8 BGR, with blur, gain, distortion and noise.

    Motion blur averages `blur_samples` renders across the exposure, but only inside the box
    the moving objects sweep, so a blurred frame costs little more than a sharp one.
    """
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
        # the stick is drawn sharp at mid-exposure: it is big, and its blur matters to no one
        s = scene.stick
        draw_stick(Canvas(base, geometry.K, geometry.pad), T_cw, ball, s.direction_world,
                   s.length, s.radius, s.bgr, scene.lighting)
    box = _dynamic_box(geometry, scene, times)
    if box is not None:
        x0, y0, x1, y1 = box
        K_roi = geometry.K.copy()
        K_roi[0, 2] -= x0
        K_roi[1, 2] -= y0
        acc = np.zeros((y1 - y0, x1 - x0, 3), np.float32)
        for ts in times:
            roi = Canvas(base[y0:y1, x0:x1].copy(), K_roi, geometry.pad)
            _draw_objects(roi, T_cw, scene, ts)
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


def _noise(shape: tuple[int, ...], rng: np.random.Generator) -> np.ndarray:
    """Unit Gaussian noise of `shape`: a random window into a bank 1.5x the frame size, drawn
    once per size (fresh draws for every frame cost more than the rest of the render)."""
    n = int(np.prod(shape))
    bank = _NOISE_BANK.get(n)
    if bank is None:
        bank = np.random.default_rng(12345).standard_normal(n + n // 2, dtype=np.float32)
        _NOISE_BANK[n] = bank
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
        if c[2] < _NEAR + extent:
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


def _draw_objects(canvas: Canvas, T_cw: np.ndarray, scene: PointerScene, t: float) -> None:
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
            draw_sphere(canvas, T_cw, obj, scene.ball_radius, scene.ball_bgr, scene.lighting)
        else:
            m, p = obj
            draw_sphere(canvas, T_cw, p, m.radius, m.bgr, scene.lighting)
