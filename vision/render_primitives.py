"""What the synthetic camera draws, one object at a time, into an ideal pinhole `Canvas`:
exact ray-cast spheres with Phong shading and 4x4 supersampling (a hit-only fast path and the
straightforward reference tests compare it with), the pointer's stick as a tapered
anti-aliased quad, and planar calibration boards warped in with 3x3 supersampling.

`vision.render` composes these into frames (blur, exposure, distortion, noise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from vision.scene import Lighting, PlanarTarget

_SUPERSAMPLE = 4  # sphere sub-pixel samples per axis
_BOARD_SUPERSAMPLE = 3
NEAR_M = 0.02  # metres: nothing closer to the optical centre is drawn


@dataclass
class Canvas:
    """The ideal (undistorted) image an object is drawn into, with its own intrinsics."""

    image: np.ndarray  # float32 HxWx3, 0..255
    K: np.ndarray
    pad: int


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
    if c[2] - radius < NEAR_M:
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
    if c[2] - radius < NEAR_M:
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


def stick_footprint(K: np.ndarray, shape: tuple[int, ...], T_camera_world: np.ndarray,
                     start_world: np.ndarray, direction_world: np.ndarray, length: float,
                     radius: float) -> StickFootprint | None:
    """The stick's tapered quad in canvas pixels and its clipped box (None: nothing shows)."""
    R_cw, t_cw = T_camera_world[:3, :3], T_camera_world[:3, 3]
    a = R_cw @ np.asarray(start_world, dtype=float) + t_cw
    b = R_cw @ (np.asarray(start_world) + length * np.asarray(direction_world)) + t_cw
    if a[2] < NEAR_M and b[2] < NEAR_M:
        return None
    if a[2] < NEAR_M or b[2] < NEAR_M:  # clip at the near plane
        s = (NEAR_M - a[2]) / (b[2] - a[2])
        if a[2] < NEAR_M:
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


def blend_stick(image: np.ndarray, origin: tuple[int, int], footprint: StickFootprint,
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
    fp = stick_footprint(canvas.K, canvas.image.shape, T_camera_world, start_world,
                          direction_world, length, radius)
    if fp is not None:
        blend_stick(canvas.image, (0, 0), fp, albedo_bgr, lighting)


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
