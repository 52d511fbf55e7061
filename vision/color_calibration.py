"""Colour calibration from an ellipse the operator drew over the marker, tolerant of background.

An ellipse drawn over a 15-pixel ball catches background: grey wall, but also an orange suit or
a red flag right behind the ball. Taking min/max over the ellipse (the thesis' way) then widens
the range to the background's colour and the detector merges ball and suit. So:

1. the ball's hue is read from the ellipse's core (half its size: the ball even when the
   ellipse is sloppy), and the ball's pixels are the ellipse's pixels of that hue;
2. candidate profiles are built from those pixels, from generous (wide quantiles, margins) to
   tight, and each is tried on a ring of background just outside the ellipse: the most
   generous one that accepts almost none of it (<= `max_background`) wins;
3. if even the tightest candidate that still covers the ball accepts much of the ring
   (> `not_separable`), the colour is not separable from this background: `calibrate_ellipse`
   says so (`separable=False`, a message, the mask of what the profile would pick up) and
   `calibrate_from_ellipse` raises `ColorNotSeparable` carrying that result.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vision.color import H_RANGE, ColorProfile
from vision.errors import ColorCalibrationError, ColorNotSeparable


@dataclass
class ColorCalibration:
    """Outcome of an ellipse calibration, for the UI: the profile, its mask over the image
    (uint8, 255 = accepted), how much of the ball and of the background around it it accepts,
    whether ball and background are separable, and a sentence for the operator."""

    profile: ColorProfile
    mask: np.ndarray
    ball_coverage: float
    background_fraction: float
    separable: bool
    message: str


def _ellipse_mask(shape: tuple[int, int], center: tuple[float, float],
                  axes: tuple[float, float], angle: float, scale: float) -> np.ndarray:
    m = np.zeros(shape, np.uint8)
    ax = (max(1, int(round(axes[0] * scale))), max(1, int(round(axes[1] * scale))))
    cv2.ellipse(m, (int(round(center[0])), int(round(center[1]))), ax, float(angle), 0, 360,
                255, -1)
    return m > 0


def _circular_mean(hue: np.ndarray, weight: np.ndarray) -> float:
    ang = hue * (2 * np.pi / H_RANGE)
    return float((np.arctan2((weight * np.sin(ang)).sum(), (weight * np.cos(ang)).sum())
                  * H_RANGE / (2 * np.pi)) % H_RANGE)


def _offsets(hue: np.ndarray, h0: float) -> np.ndarray:
    return (hue - h0 + H_RANGE / 2) % H_RANGE - H_RANGE / 2


def _profile(name: str, h0: float, off: np.ndarray, sat: np.ndarray, val: np.ndarray,
             pct: float, hue_margin: float, sat_margin: float, sat_margin_hi: float,
             val_margin: float, min_saturation: int) -> ColorProfile:
    lo, hi = np.percentile(off, [pct, 100 - pct])
    if hi - lo + 2 * hue_margin >= H_RANGE - 1:
        h_min, h_max = 0, 179
    else:
        h_min = int(np.floor(h0 + lo - hue_margin)) % H_RANGE
        h_max = int(np.ceil(h0 + hi + hue_margin)) % H_RANGE
    s_lo, s_hi = np.percentile(sat, [1.0, 99.0])
    v_lo = np.percentile(val, 1.0)
    return ColorProfile(name=name, h_min=h_min, h_max=h_max,
                        s_min=int(max(min_saturation, np.floor(s_lo - sat_margin))),
                        s_max=int(min(255, np.ceil(s_hi + sat_margin_hi))),
                        v_min=int(max(0, np.floor(v_lo - val_margin))))


#: candidate (quantile %, hue, saturation below, saturation above, value margins), most
#: generous first. First the saturation's upper bound narrows: a lit ball's saturation hardly
#: changes with exposure (a gain scales every channel) and its shading lowers it (highlights)
#: rather than raising it, so the ball loses almost nothing, while a deeper-coloured background
#: of its hue (a red cup's shadow behind a red ball) is cut off its outline (on the coffee
#: photo: 43 % -> 92 % of frames measured). Then the hue range narrows, which costs the ball
#: some of its rim. The lower saturation and brightness bounds never narrow: the shaded rim
#: and the exposure drift live there, and raising them loses the ball when it moves.
#: how far above the core's saturation (98th percentile) a pixel of the ellipse may still be
#: the ball's (sensor noise on its dark rim)
CORE_SATURATION_MARGIN = 10

_CANDIDATES = [(1.0, 4, 20, 20, 20), (1.0, 4, 20, 6, 20), (1.0, 2, 20, 6, 20),
               (2.0, 1, 20, 6, 20), (3.0, 0, 20, 6, 20), (5.0, 0, 20, 6, 20),
               (5.0, 0, 20, 3, 20)]


def calibrate_ellipse(
    image_bgr: np.ndarray,
    center: tuple[float, float],
    axes: tuple[float, float],
    angle: float = 0.0,
    *,
    name: str = "pointer",
    min_saturation: int = 40,
    min_pixels: int = 12,
    max_background: float = 0.01,
    not_separable: float = 0.25,
    min_coverage: float = 0.6,
) -> ColorCalibration:
    """Profile from the ellipse (`center` x, y and half-`axes` in pixels, `angle` degrees as
    cv2.ellipse), tried against the background around it; see the module docstring."""
    if not isinstance(image_bgr, np.ndarray) or image_bgr.dtype != np.uint8 \
            or image_bgr.ndim != 3 or image_bgr.shape[2] != 3:
        raise ColorCalibrationError("colour calibration needs a BGR uint8 image")
    ax = (float(axes[0]), float(axes[1]))
    if not np.all(np.isfinite([float(center[0]), float(center[1]), float(angle)])):
        raise ColorCalibrationError("the ellipse centre or angle is not a finite number")
    if not np.all(np.isfinite(ax)) or min(ax) < 1.0:
        raise ColorCalibrationError(
            f"the ellipse is empty (half-axes {ax[0]:.1f} x {ax[1]:.1f} px); drag it over the ball"
        )
    shape = image_bgr.shape[:2]
    inside = _ellipse_mask(shape, center, ax, angle, 1.0)
    if not inside.any():
        raise ColorCalibrationError("the ellipse lies outside the image; draw it over the ball")
    hsv_img = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2HSV)
    hsv = hsv_img[inside].astype(float)
    coloured = hsv[:, 1] >= min_saturation
    if coloured.sum() < min_pixels:
        raise ColorCalibrationError(
            f"the ellipse holds {int(coloured.sum())} coloured pixels (need {min_pixels}); it "
            "covers grey or white only: draw it over the coloured ball"
        )
    # 1. the ball's hue from the core; its pixels: the ellipse's pixels near that hue
    core = _ellipse_mask(shape, center, ax, angle, 0.5)[inside] & coloured
    if core.sum() >= 4:
        h0 = _circular_mean(hsv[core, 0], hsv[core, 1])
        c_off = _offsets(hsv[core, 0], h0)
        lo, hi = np.percentile(c_off, [2, 98])
        off = _offsets(hsv[:, 0], h0)
        ball = coloured & (off >= lo - 2) & (off <= hi + 2)
        # nor more saturated than the core: shading darkens a lit ball without deepening its
        # colour, so what is more saturated is a deeper-coloured background of that hue
        ball &= hsv[:, 1] <= np.percentile(hsv[core, 1], 98) + CORE_SATURATION_MARGIN
    else:  # a ring-shaped ball image (huge highlight) or a tiny ellipse: strongest hue peak
        ball = coloured & _dominant_hue_mask(hsv)
        h0 = _circular_mean(hsv[ball, 0], hsv[ball, 1])
    if ball.sum() < min_pixels:
        ball = coloured
        h0 = _circular_mean(hsv[ball, 0], hsv[ball, 1])
    px = hsv[ball]
    off = _offsets(px[:, 0], h0)
    # 2. candidates against the background ring just outside the ellipse
    # the ring starts beyond the ball, which may be larger than a tight ellipse
    first = _profile(name, h0, off, px[:, 1], px[:, 2], *_CANDIDATES[0], min_saturation)
    n, labels = cv2.connectedComponents(cv2.medianBlur(first.mask(hsv_img), 3))
    cx, cy = int(round(center[0])), int(round(center[1]))
    inner = 1.2
    if n > 1 and 0 <= cy < shape[0] and 0 <= cx < shape[1] and labels[cy, cx] > 0:
        r_ball = np.sqrt((labels == labels[cy, cx]).sum() / np.pi)
        inner = float(np.clip(1.25 * r_ball / min(ax), 1.2, 2.0))
    ring = _ellipse_mask(shape, center, ax, angle, inner + 1.3) & \
        ~_ellipse_mask(shape, center, ax, angle, inner)
    ball_img = np.zeros(shape, bool)
    ball_img[inside] = ball
    tried: list[tuple[ColorProfile, np.ndarray, float, float]] = []
    chosen = None
    for pct, hm, sm, sm_hi, vm in _CANDIDATES:
        prof = _profile(name, h0, off, px[:, 1], px[:, 2], pct, hm, sm, sm_hi, vm,
                        min_saturation)
        mask = prof.mask(hsv_img)  # raw: speckle is what the detector's closing bridges
        cover = float((mask[ball_img] > 0).mean())
        bg = float((mask[ring] > 0).mean()) if ring.any() else 0.0
        tried.append((prof, mask, cover, bg))
        if cover >= min_coverage and bg <= max_background:
            chosen = tried[-1]
            break
    if chosen is not None:
        prof, mask, cover, bg = chosen
        return ColorCalibration(prof, mask, cover, bg, True,
                                f"colour calibrated: {cover:.0%} of the ball, {bg:.1%} of the "
                                "background around it")
    usable = [c for c in tried if c[2] >= min_coverage] or tried[:1]
    prof, mask, cover, bg = min(usable, key=lambda c: c[3])
    if bg > not_separable:
        return ColorCalibration(
            prof, mask, cover, bg, False,
            f"the ball's colour is not separable from the background here: any range that "
            f"covers the ball also takes {bg:.0%} of the pixels around it (shown in the mask); "
            "hold the ball in front of something of another colour, or use a ball of a colour "
            "the background does not have")
    return ColorCalibration(prof, mask, cover, bg, True,
                            f"colour calibrated, but {bg:.0%} of the background around the ball "
                            "has its colour: the shape tests must tell them apart")


def calibrate_from_ellipse(image_bgr: np.ndarray, center: tuple[float, float],
                           axes: tuple[float, float], angle: float = 0.0, *,
                           name: str = "pointer", **kw: float) -> ColorProfile:
    """The profile of `calibrate_ellipse`; raises `ColorNotSeparable` (carrying the
    calibration and its mask) when the colour cannot be told from the background."""
    cal = calibrate_ellipse(image_bgr, center, axes, angle, name=name, **kw)
    if not cal.separable:
        raise ColorNotSeparable(cal.message, cal)
    return cal.profile


def _dominant_hue_mask(hsv: np.ndarray, max_half_width: int = 30) -> np.ndarray:
    """Pixels of the strongest hue peak (circular histogram weighted by saturation, grown out
    to where it falls to 3 % of the peak)."""
    h = hsv[:, 0].astype(int) % H_RANGE
    hist = np.bincount(h, weights=hsv[:, 1], minlength=H_RANGE)
    smooth = sum(np.roll(hist, k) for k in (-2, -1, 0, 1, 2))
    peak = int(np.argmax(smooth))
    floor = 0.03 * smooth[peak]
    lo = hi = 0
    while lo < max_half_width and smooth[(peak - lo - 1) % H_RANGE] > floor:
        lo += 1
    while hi < max_half_width and smooth[(peak + hi + 1) % H_RANGE] > floor:
        hi += 1
    off = (h - peak + H_RANGE // 2) % H_RANGE - H_RANGE // 2
    return (off >= -lo - 2) & (off <= hi + 2)
