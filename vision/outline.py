"""Finding the ball by its outline where its colour merged with the background and no clean look
of it is at hand.

A ball held in front of a red box or a red motorcycle tank is one region with it in the colour
mask, and `vision.appearance` needs a look learnt within 10 cm. Its outline is still there: a
lit sphere is darker or brighter than what is behind it almost all the way round. So, near
where the track predicts the ball and at the size it predicts:

1. OpenCV's gradient Hough transform (`cv2.HoughCircles`) proposes circles (whole pixels);
2. from each, 36 rays find the strongest brightness step between 0.55 and 1.5 radii
   (sub-pixel, by a parabola through the gradient's peak), and a least-squares circle is fitted
   to those edge points, dropping the rays that hit something else (the stick, a highlight,
   a background edge) - on the motorcycle and box of the photo sequences this puts the centre
   0.02-0.32 px from the truth, from starts up to 1.2 px off;
3. the circle is taken only if it is unmistakable: most rays agree (`min_support`), the fit is
   tight, its size is the predicted one, the disc is in the colour profile and shaded like a
   sphere, and no second circle near the prediction passes the same tests.

Such a detection is marked `method="outline"`; the pointer offers a fix using it only when its
views agree within `AppearanceParams.offer_max_reprojection_px`, as for a look match.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vision.color import ColorProfile
from vision.detection import Detection


@dataclass(frozen=True)
class OutlineParams:
    rays: int = 36
    min_support: float = 0.6  # share of rays whose edge lies on the fitted circle
    max_residual_px: float = 0.35  # median distance of those edges from the circle
    radius_range: tuple[float, float] = (0.85, 1.3)  # fitted / predicted (the edge is found
    # where the brightness step is steepest, ~0.35 px outside the drawn outline)
    min_in_colour: float = 0.85  # share of the inner disc (0.8 radius) in the colour profile
    min_shading: float = 0.1  # std/mean of brightness in that disc: a sphere, not a flat patch
    max_shift_px: float = 1.5  # the fit may move this far from the Hough proposal
    proposals: int = 4


def find_outline(image: np.ndarray, profile: ColorProfile, predicted_px: np.ndarray,
                 half: float, r_exp: float, params: OutlineParams | None = None
                 ) -> tuple[Detection | None, str]:
    """The ball's outline within `half` px of `predicted_px` at about radius `r_exp`, or None
    and why not."""
    p = params or OutlineParams()
    if not (np.isfinite(r_exp) and r_exp >= 3.0 and np.all(np.isfinite(predicted_px))):
        return None, "no usable prediction"
    h, w = image.shape[:2]
    m = int(np.ceil(half + 1.6 * r_exp + 3))
    cx, cy = (int(round(v)) for v in predicted_px)
    x0, y0, x1, y1 = max(cx - m, 0), max(cy - m, 0), min(cx + m + 1, w), min(cy + m + 1, h)
    if x1 - x0 < 4 * r_exp or y1 - y0 < 4 * r_exp:
        return None, "at the image edge"
    crop = image[y0:y1, x0:x1]
    gray = cv2.cvtColor(crop, cv2.COLOR_BGR2GRAY)
    circles = cv2.HoughCircles(gray, cv2.HOUGH_GRADIENT, dp=1, minDist=max(r_exp, 2.0),
                               param1=60, param2=8, minRadius=int(np.floor(0.8 * r_exp)),
                               maxRadius=int(np.ceil(1.25 * r_exp)))
    if circles is None:
        return None, "no circle of the ball's size there"
    smooth = cv2.GaussianBlur(gray.astype(np.float32), (0, 0), 0.8)
    hsv = cv2.cvtColor(crop, cv2.COLOR_BGR2HSV)
    pred = np.asarray(predicted_px, float) - (x0, y0)
    passed: list[tuple[np.ndarray, float, float]] = []
    why = "no circle near the prediction"
    for u, v, _ in circles[0][: p.proposals]:
        start = np.array([u, v], float)
        if np.linalg.norm(start - pred) > half:
            continue
        fit = _ray_fit(smooth, start, r_exp, p.rays)
        if fit is None:
            why = "the outline is not seen around the ball"
            continue
        centre, radius, support, residual = fit
        ok, why = _judge(p, hsv, centre, radius, support, residual, r_exp, start, profile)
        if ok and np.linalg.norm(centre - pred) <= half:
            passed.append((centre, radius, support))
    if not passed:
        return None, why
    distinct = [c for c in passed if np.linalg.norm(c[0] - passed[0][0]) > r_exp]
    if distinct:
        return None, "two ball-like outlines near the prediction"
    centre, radius, support = passed[0]
    return Detection(center_px=centre + (x0, y0), radius_px=float(radius),
                     area_px=float(np.pi * radius**2), axis_ratio=1.0, fill=1.0,
                     shading=0.0, hole_fraction=0.0, method="outline",
                     match=float(support)), ""


def _judge(p: OutlineParams, hsv: np.ndarray, centre: np.ndarray, radius: float,
           support: float, residual: float, r_exp: float, start: np.ndarray,
           profile: ColorProfile) -> tuple[bool, str]:
    if support < p.min_support or residual > p.max_residual_px:
        return False, f"outline seen on {support:.0%} of the rim (residual {residual:.2f} px)"
    if not p.radius_range[0] <= radius / r_exp <= p.radius_range[1]:
        return False, f"outline {radius / r_exp:.2f}x the predicted size"
    if np.linalg.norm(centre - start) > p.max_shift_px:
        return False, "the fitted outline left its proposal"
    hh, ww = hsv.shape[:2]
    yy, xx = np.mgrid[0:hh, 0:ww]
    disc = (xx - centre[0]) ** 2 + (yy - centre[1]) ** 2 <= (0.8 * radius) ** 2
    if disc.sum() < 12:
        return False, "too small"
    in_colour = float((profile.mask(hsv)[disc] > 0).mean())
    val = hsv[..., 2][disc].astype(np.float32)
    shading = float(val.std() / val.mean()) if val.mean() > 0 else 0.0
    if in_colour < p.min_in_colour or shading < p.min_shading:
        return False, f"inside: {in_colour:.0%} in colour, shading {shading:.2f}"
    return True, ""


def _ray_fit(gray: np.ndarray, c0: np.ndarray, r0: float, n: int,
             inner: float = 0.55, outer: float = 1.5, step: float = 0.25
             ) -> tuple[np.ndarray, float, float, float] | None:
    """Edge points along `n` rays from `c0` (strongest brightness step), a circle fitted to
    them (algebraic least squares, rays off the circle dropped and refitted): centre, radius,
    share of rays kept, median residual."""
    ang = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    d = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    s = np.arange(inner * r0, outer * r0, step)
    pts = c0[None, None, :] + d[:, None, :] * s[None, :, None]
    prof = cv2.remap(gray, pts[..., 0].astype(np.float32), pts[..., 1].astype(np.float32),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    grad = np.abs(np.diff(prof, axis=1))
    rows = np.arange(n)
    k = np.argmax(grad, axis=1)
    peak = grad[rows, k]
    left = grad[rows, np.clip(k - 1, 0, None)]
    right = grad[rows, np.clip(k + 1, None, grad.shape[1] - 1)]
    den = left - 2.0 * peak + right
    inside = (k > 0) & (k < grad.shape[1] - 1) & (den < 0)
    off = np.where(inside, 0.5 * (left - right) / np.where(den < 0, den, -1.0), 0.0)
    edge = c0[None, :] + d * (s[0] + (k + 0.5 + off) * step)[:, None]
    keep = peak > 0.3 * np.median(peak)
    for _ in range(5):
        if keep.sum() < max(8, n // 2):
            return None
        P = edge[keep]
        A = np.c_[2.0 * P, np.ones(len(P))]
        sol, *_ = np.linalg.lstsq(A, (P**2).sum(axis=1), rcond=None)
        centre = sol[:2]
        radius = float(np.sqrt(max(sol[2] + centre @ centre, 0.0)))
        res = np.abs(np.linalg.norm(edge - centre, axis=1) - radius)
        new = keep & (res < max(0.6, 2.5 * float(np.median(res[keep]))))
        if new.sum() == keep.sum():
            break
        keep = new
    if keep.sum() < max(8, n // 2):
        return None
    return centre, radius, float(keep.mean()), float(np.median(res[keep]))
