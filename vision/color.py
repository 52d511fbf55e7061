"""Colour profiles (HSV ranges); their calibration from an ellipse drawn over a marker is in
`vision.color_calibration` (re-exported here).

OpenCV's 8-bit HSV: H in 0..179 (degrees / 2), S and V in 0..255. A profile is the thesis'
"min/max of hue and saturation plus a minimum brightness" (003, §6.5.1). Red straddles H = 0, so
a profile whose `h_min` > `h_max` wraps around: it accepts H >= h_min *or* H <= h_max.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import cv2
import numpy as np

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
