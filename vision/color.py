"""Colour profiles (HSV ranges) and their calibration from an ellipse drawn over a marker.

OpenCV's 8-bit HSV: H in 0..179 (degrees / 2), S and V in 0..255. A profile is the thesis'
"min/max of hue and saturation plus a minimum brightness" (003, §6.5.1). Red straddles H = 0, so
a profile whose `h_min` > `h_max` wraps around: it accepts H >= h_min *or* H <= h_max.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import cv2
import numpy as np

from vision.errors import ColorCalibrationError

H_RANGE = 180  # OpenCV 8-bit hue period


@dataclass(frozen=True)
class ColorProfile:
    """A named HSV acceptance region: hue interval (may wrap), saturation interval, V >= v_min."""

    name: str
    h_min: int
    h_max: int
    s_min: int
    s_max: int = 255
    v_min: int = 0

    def __post_init__(self) -> None:
        if not self.name:
            raise ValueError("a colour profile needs a name")
        for field_name, hi in (("h_min", 179), ("h_max", 179), ("s_min", 255), ("s_max", 255),
                               ("v_min", 255)):
            v = getattr(self, field_name)
            if not isinstance(v, (int, np.integer)) or not 0 <= v <= hi:
                raise ValueError(f"{field_name} must be an integer in 0..{hi}, got {v!r}")
            object.__setattr__(self, field_name, int(v))
        if self.s_min > self.s_max:
            raise ValueError(f"s_min {self.s_min} > s_max {self.s_max}")

    @property
    def wraps(self) -> bool:
        """True for hue ranges that cross H = 0 (reds)."""
        return self.h_min > self.h_max

    @property
    def hue_width(self) -> int:
        return (self.h_max - self.h_min) % H_RANGE + 1

    def mask(self, hsv: np.ndarray) -> np.ndarray:
        """uint8 mask (255 = in profile) of an OpenCV HSV image."""
        if not self.wraps:
            return cv2.inRange(hsv, (self.h_min, self.s_min, self.v_min),
                               (self.h_max, self.s_max, 255))
        low = cv2.inRange(hsv, (0, self.s_min, self.v_min), (self.h_max, self.s_max, 255))
        high = cv2.inRange(hsv, (self.h_min, self.s_min, self.v_min), (179, self.s_max, 255))
        return cv2.bitwise_or(low, high)

    def mask_bgr(self, image_bgr: np.ndarray) -> np.ndarray:
        return self.mask(cv2.cvtColor(image_bgr, cv2.COLOR_BGR2HSV))

    def contains_hsv(self, h: int, s: int, v: int) -> bool:
        hue_ok = (h >= self.h_min or h <= self.h_max) if self.wraps \
            else self.h_min <= h <= self.h_max
        return bool(hue_ok and self.s_min <= s <= self.s_max and v >= self.v_min)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> ColorProfile:
        try:
            return cls(**{k: data[k] for k in ("name", "h_min", "h_max", "s_min", "s_max",
                                               "v_min")})
        except KeyError as exc:
            raise ValueError(f"colour profile is missing {exc.args[0]!r}") from None


#: A starting point for the red pointer ball before the operator calibrates on the real light.
DEFAULT_POINTER_RED = ColorProfile("pointer", h_min=170, h_max=8, s_min=120, s_max=255, v_min=50)


@dataclass
class ColorProfileSet:
    """Several named profiles (pointer, robot markers, ...); JSON-serialisable for the session."""

    profiles: dict[str, ColorProfile]

    def __init__(self, profiles: list[ColorProfile] | None = None) -> None:
        self.profiles = {}
        for p in profiles or []:
            self.add(p)

    def add(self, profile: ColorProfile) -> None:
        """Add or replace (recalibration replaces the profile of the same name)."""
        self.profiles[profile.name] = profile

    def __getitem__(self, name: str) -> ColorProfile:
        try:
            return self.profiles[name]
        except KeyError:
            have = sorted(self.profiles)
            raise KeyError(f"no colour profile named {name!r}; have {have}") from None

    def __contains__(self, name: object) -> bool:
        return name in self.profiles

    def names(self) -> list[str]:
        return sorted(self.profiles)

    def to_dict(self) -> dict:
        return {"profiles": [p.to_dict() for p in self.profiles.values()]}

    @classmethod
    def from_dict(cls, data: dict) -> ColorProfileSet:
        return cls([ColorProfile.from_dict(p) for p in data.get("profiles", [])])


def calibrate_from_ellipse(
    image_bgr: np.ndarray,
    center: tuple[float, float],
    axes: tuple[float, float],
    angle: float = 0.0,
    *,
    name: str = "pointer",
    percentile: float = 1.0,
    hue_margin: int = 4,
    sat_margin: int = 20,
    val_margin: int = 20,
    min_saturation: int = 40,
    min_pixels: int = 12,
) -> ColorProfile:
    """Profile from the pixels inside an ellipse the operator drew over the marker.

    `center` (x, y) pixels, `axes` the half-axes in pixels, `angle` degrees (cv2.ellipse
    convention). As in the thesis the result is min/max of H and S and a minimum V; unlike it we
    take the `percentile` / 100-`percentile` quantiles, not the extremes, and widen them by the
    margins, so a few background or highlight pixels caught by a sloppy ellipse do not blow the
    range open. Hue statistics are circular, so a red ball straddling H = 0 yields a wrapping
    profile. Unsaturated pixels (highlights, grey background) carry no hue and are ignored, and
    only the dominant hue peak is kept, so a patch of coloured background in the ellipse does
    not widen the range either.
    """
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
    h, w = image_bgr.shape[:2]
    mask = np.zeros((h, w), np.uint8)
    cv2.ellipse(mask, (int(round(center[0])), int(round(center[1]))),
                (int(round(ax[0])), int(round(ax[1]))), float(angle), 0, 360, 255, -1)
    inside = mask > 0
    if not inside.any():
        raise ColorCalibrationError("the ellipse lies outside the image; draw it over the ball")
    hsv = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2HSV)[inside].astype(float)
    coloured = hsv[hsv[:, 1] >= min_saturation]
    if len(coloured) < min_pixels:
        raise ColorCalibrationError(
            f"the ellipse holds {len(coloured)} coloured pixels (need {min_pixels}); it covers "
            "grey or white only: draw it over the coloured ball"
        )
    coloured = _dominant_hue(coloured)
    hue, sat, val = coloured[:, 0], coloured[:, 1], coloured[:, 2]
    ang = hue * (2 * np.pi / H_RANGE)
    mean_h = (np.arctan2(np.sin(ang).mean(), np.cos(ang).mean()) * H_RANGE / (2 * np.pi)) % H_RANGE
    offsets = (hue - mean_h + H_RANGE / 2) % H_RANGE - H_RANGE / 2
    lo, hi = np.percentile(offsets, [percentile, 100 - percentile])
    if hi - lo + 2 * hue_margin >= H_RANGE - 1:
        h_min, h_max = 0, 179
    else:
        h_min = int(np.floor(mean_h + lo - hue_margin)) % H_RANGE
        h_max = int(np.ceil(mean_h + hi + hue_margin)) % H_RANGE
    s_lo, s_hi = np.percentile(sat, [percentile, 100 - percentile])
    v_lo = np.percentile(val, percentile)
    return ColorProfile(
        name=name,
        h_min=h_min,
        h_max=h_max,
        s_min=int(max(min_saturation, np.floor(s_lo - sat_margin))),
        s_max=int(min(255, np.ceil(s_hi + sat_margin))),
        v_min=int(max(0, np.floor(v_lo - val_margin))),
    )


def _dominant_hue(hsv: np.ndarray, max_half_width: int = 30) -> np.ndarray:
    """Keep the pixels of the strongest hue peak (circular histogram weighted by saturation,
    grown out to where it falls to 3 % of the peak): an ellipse that also caught a piece of
    coloured background then still calibrates on the ball alone."""
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
    return hsv[(off >= -lo - 2) & (off <= hi + 2)]
