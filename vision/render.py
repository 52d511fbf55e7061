"""Software renderer behind the synthetic camera: exact ray-cast spheres with Phong shading and
anti-aliasing, a stick, planar calibration boards, a cluttered backdrop, motion blur, exposure
changes, lens distortion and sensor noise.

Everything is drawn into an ideal pinhole canvas (padded when the lens distorts, so the corners
of a barrel-distorted image still have content), then remapped through the camera's distortion,
so ground truth from `CameraModel.project` and the pixels agree to a small fraction of a pixel.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
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
_SAMPLE_OFFSETS = (np.arange(_SUPERSAMPLE) + 0.5) / _SUPERSAMPLE - 0.5


_CUBE = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)


def _sphere_box(K: np.ndarray, shape: tuple[int, ...], c: np.ndarray,
                radius: float) -> tuple[int, int, int, int] | None:
    """Canvas box (x0, y0, x1, y1) around the projected bounding cube of a camera-frame sphere."""
    corners = c + radius * _CUBE
    uv = corners[:, :2] / corners[:, 2:3] * [K[0, 0], K[1, 1]] + K[:2, 2]
    h, w = shape[:2]
    x0, y0 = np.floor(uv.min(axis=0)).astype(int) - 1
    x1, y1 = np.ceil(uv.max(axis=0)).astype(int) + 2
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x0 >= x1 or y0 >= y1:
        return None
    return int(x0), int(y0), int(x1), int(y1)


def _silhouette_span(f: float, centre_px: float, lateral: float, depth: float,
                     radius: float) -> tuple[int, int]:
    """Pixel span [lo, hi) that holds a sphere's outline along one image axis, one pixel to
    spare: the sphere's shadow on the (lateral, depth) plane is a disc, and its two tangent rays
    from the optical centre bound the outline (the sphere lies in front, depth > radius)."""
    mid = math.atan2(lateral, depth)
    half = math.asin(min(1.0, radius / math.hypot(lateral, depth)))
    lo = f * math.tan(mid - half) + centre_px
    hi = f * math.tan(mid + half) + centre_px
    return math.floor(lo) - 1, math.ceil(hi) + 2


def draw_sphere(canvas: Canvas, T_camera_world: np.ndarray, centre_world: np.ndarray,
                radius: float, albedo_bgr: tuple[float, float, float],
                lighting: Lighting) -> None:
    """Ray-cast a Phong-shaded sphere with 4x4 supersampling into the canvas (in place).

    Every sample gets the ray-sphere test, but only the samples that hit are shaded, and the
    per-pixel average is a scatter-add in the same order as a mean over the sample grid, so the
    result matches `_draw_sphere_reference` up to float64 rounding of the dot products.
    """
    R_cw, t_cw = T_camera_world[:3, :3], T_camera_world[:3, 3]
    c = R_cw @ np.asarray(centre_world, dtype=float) + t_cw
    if c[2] - radius < _NEAR:
        return
    K = canvas.K
    # no sample outside the outline's box hits, so the pixels there stay as they are
    cx, cy, cz = c.tolist()
    h, w = canvas.image.shape[:2]
    x0, x1 = _silhouette_span(K[0, 0], K[0, 2], cx, cz, radius)
    y0, y1 = _silhouette_span(K[1, 1], K[1, 2], cy, cz, radius)
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x0 >= x1 or y0 >= y1:
        return
    ss = _SUPERSAMPLE
    # rays d = (dx, dy, 1): dx depends on the sample column only, dy on the sample row only
    dx = ((np.arange(x0, x1)[:, None] + _SAMPLE_OFFSETS[None, :]).ravel() - K[0, 2]) / K[0, 0]
    dy = ((np.arange(y0, y1)[:, None] + _SAMPLE_OFFSETS[None, :]).ravel() - K[1, 2]) / K[1, 1]
    a = (dy[:, None] * dy[:, None] + dx[None, :] * dx[None, :]) + 1.0
    b = (dy[:, None] * cy + dx[None, :] * cx) + cz
    disc = b * b - a * (c @ c - radius * radius)
    hit = disc > 0
    iy, ix = np.nonzero(hit)  # row-major: per pixel, sample rows then sample columns
    if iy.size == 0:
        return
    a, b, disc = a[hit], b[hit], disc[hit]
    sx, sy = dx[ix], dy[iy]
    tt = (b - np.sqrt(disc)) / a
    px, py, pz = sx * tt, sy * tt, tt
    nx, ny, nz = (px - cx) / radius, (py - cy) / radius, (pz - cz) / radius
    L = R_cw @ lighting.direction_world
    p_len = np.sqrt((px * px + py * py) + pz * pz)
    hx, hy, hz = L[0] + -px / p_len, L[1] + -py / p_len, L[2] + -pz / p_len
    h_len = np.sqrt((hx * hx + hy * hy) + hz * hz)
    hx /= h_len
    hy /= h_len
    hz /= h_len
    diff = np.maximum((nx * L[0] + ny * L[1]) + nz * L[2], 0.0)
    spec = np.maximum((nx * hx + ny * hy) + nz * hz, 0.0) ** lighting.shininess
    lit = lighting.ambient + lighting.diffuse * diff
    highlight = lighting.specular * spec
    pw = x1 - x0
    pix = (iy // ss) * pw + ix // ss
    npix = (y1 - y0) * pw
    inv_n = 1.0 / (ss * ss)  # a power of two: dividing by the count is exact either way
    cov = np.bincount(pix, minlength=npix).reshape(y1 - y0, pw) * inv_n
    col = np.empty((y1 - y0, pw, 3))
    for k, albedo in enumerate(np.asarray(albedo_bgr, dtype=float)):
        colour = (albedo * lit + highlight) * 255.0
        col[..., k] = np.bincount(pix, weights=colour, minlength=npix).reshape(y1 - y0, pw)
    col *= inv_n
    roi = canvas.image[y0:y1, x0:x1]
    roi *= (1.0 - cov)[..., None].astype(np.float32)
    roi += np.minimum(col, 255.0).astype(np.float32)


def _draw_sphere_reference(canvas: Canvas, T_camera_world: np.ndarray,
                           centre_world: np.ndarray, radius: float,
                           albedo_bgr: tuple[float, float, float], lighting: Lighting) -> None:
    """`draw_sphere` the straightforward way (shade every sample): the yardstick in tests."""
    R_cw, t_cw = T_camera_world[:3, :3], T_camera_world[:3, 3]
    c = R_cw @ np.asarray(centre_world, dtype=float) + t_cw
    if c[2] - radius < _NEAR:
        return
    K = canvas.K
    box = _sphere_box(K, canvas.image.shape, c, radius)
    if box is None:
        return
    x0, y0, x1, y1 = box
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


StickFootprint = tuple[np.ndarray, tuple[int, int, int, int]]


def _stick_footprint(K: np.ndarray, shape: tuple[int, ...], T_camera_world: np.ndarray,
                     start_world: np.ndarray, direction_world: np.ndarray, length: float,
                     radius: float) -> StickFootprint | None:
    """The stick's tapered quad in canvas pixels and its clipped box (None: nothing shows)."""
    R_cw, t_cw = T_camera_world[:3, :3], T_camera_world[:3, 3]
    a = R_cw @ np.asarray(start_world, dtype=float) + t_cw
    b = R_cw @ (np.asarray(start_world) + length * np.asarray(direction_world)) + t_cw
    if a[2] < _NEAR and b[2] < _NEAR:
        return None
    if a[2] < _NEAR or b[2] < _NEAR:  # clip at the near plane
        s = (_NEAR - a[2]) / (b[2] - a[2])
        if a[2] < _NEAR:
            a = a + s * (b - a)
        else:
            b = a + s * (b - a)
    f = 0.5 * (K[0, 0] + K[1, 1])
    pa = a[:2] / a[2] * [K[0, 0], K[1, 1]] + K[:2, 2]
    pb = b[:2] / b[2] * [K[0, 0], K[1, 1]] + K[:2, 2]
    axis = pb - pa
    if np.linalg.norm(axis) < 1e-6:
        return None
    nrm = np.array([-axis[1], axis[0]]) / np.linalg.norm(axis)
    wa, wb = f * radius / a[2], f * radius / b[2]
    quad = np.array([pa + nrm * wa, pb + nrm * wb, pb - nrm * wb, pa - nrm * wa])
    h, w = shape[:2]
    x0, y0 = np.maximum(np.floor(quad.min(axis=0)).astype(int) - 2, 0)
    x1, y1 = np.minimum(np.ceil(quad.max(axis=0)).astype(int) + 3, [w, h])
    if x0 >= x1 or y0 >= y1:
        return None
    return quad, (int(x0), int(y0), int(x1), int(y1))


def _blend_stick(image: np.ndarray, origin: tuple[int, int], footprint: StickFootprint,
                 albedo_bgr: tuple[float, float, float], lighting: Lighting, *,
                 sparse: bool = True) -> None:
    """Composite the stick's anti-aliased quad into `image`, whose pixel (0, 0) is canvas pixel
    `origin`. `sparse` touches only the covered pixels (a thin diagonal stick fills little of
    its box); the result is the same as blending the whole box, where alpha 0 changes nothing."""
    quad, (x0, y0, x1, y1) = footprint
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    pts = np.round((quad - [x0, y0]) * 16).astype(np.int32)
    cv2.fillConvexPoly(mask, pts, 255, cv2.LINE_AA, shift=4)
    shade = lighting.ambient + 0.5 * lighting.diffuse
    colour = (np.asarray(albedo_bgr, dtype=np.float32) * shade * 255.0)[None, None, :]
    ox, oy = origin
    roi = image[y0 - oy:y1 - oy, x0 - ox:x1 - ox]
    if not sparse:
        alpha = (mask.astype(np.float32) / 255.0)[..., None]
        roi *= 1.0 - alpha
        roi += alpha * colour
        return
    iy, ix = np.nonzero(mask)
    alpha = (mask[iy, ix].astype(np.float32) / 255.0)[:, None]
    px = roi[iy, ix]
    px *= 1.0 - alpha
    px += alpha * colour[0]
    roi[iy, ix] = px


def draw_stick(canvas: Canvas, T_camera_world: np.ndarray, start_world: np.ndarray,
               direction_world: np.ndarray, length: float, radius: float,
               albedo_bgr: tuple[float, float, float], lighting: Lighting) -> None:
    """The pointer's stick as a tapered anti-aliased quad (perspective width at both ends)."""
    fp = _stick_footprint(canvas.K, canvas.image.shape, T_camera_world, start_world,
                          direction_world, length, radius)
    if fp is not None:
        _blend_stick(canvas.image, (0, 0), fp, albedo_bgr, lighting)


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
        stick = _stick_footprint(geometry.K, geometry.shape, T_cw, ball, s.direction_world,
                                 s.length, s.radius)
    box = _dynamic_box(geometry, scene, times)
    region = _union(stick[1] if stick is not None else None, box)
    patch = None
    if region is not None:
        rx0, ry0, rx1, ry1 = region
        patch = static[ry0:ry1, rx0:rx1].copy()
        if stick is not None:
            s = scene.stick
            _blend_stick(patch, (rx0, ry0), stick, s.bgr, scene.lighting)
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
        fp = _stick_footprint(geometry.K, base.shape, T_cw, ball, s.direction_world, s.length,
                              s.radius)
        if fp is not None:
            _blend_stick(base, (0, 0), fp, s.bgr, scene.lighting, sparse=False)
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
