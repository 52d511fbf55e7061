"""Dwell-to-teach: when the pointer stays within a small radius for a set time, emit one taught
point with the averaged position and its uncertainty; fire again only after the pointer left.

Only measured frames count: a frame without a measurement adds nothing (and cannot complete
a dwell), and a gap of over `max_gap_s` between measured frames ends the dwell under way.
Stillness is judged on the Kalman-filtered position (smooth, so hand tremor decides, not pixel
noise); the average is taken over the raw per-frame measurements, which are independent, so
their scatter says honestly how well the mean is known.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DwellParams:
    dwell_s: float = 1.0  # how long the pointer must stay still
    radius: float = 0.005  # metres, stereo
    radius_mono: float = 0.03  # metres: single-camera depth jitters much more
    min_samples: int = 10
    rearm_factor: float = 3.0  # re-arm once the pointer is this many radii from the last point
    max_gap_s: float = 0.25  # longer without a measurement ends the dwell under way

    def __post_init__(self) -> None:
        if self.dwell_s <= 0 or self.radius <= 0 or self.radius_mono <= 0:
            raise ValueError("dwell time and radii must be positive")


@dataclass(frozen=True)
class TaughtPoint:
    """A location the operator taught with the pointer (world frame, metres)."""

    position_world: np.ndarray
    covariance: np.ndarray  # of the mean (random part; calibration error not included)
    n_samples: int
    duration_s: float
    timestamp: float
    mode: str  # "stereo" or "mono" (mono: less accurate)
    spread: float  # RMS distance of the samples from the mean (hand tremor + noise)

    @property
    def std(self) -> np.ndarray:
        """Per-axis standard deviation of the taught position."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    @property
    def uncertainty(self) -> float:
        """One number for the UI: standard deviation along the worst direction (metres)."""
        return float(np.sqrt(max(np.linalg.eigvalsh(self.covariance).max(), 0.0)))

    def to_dict(self) -> dict:
        return {
            "position_world": self.position_world.tolist(),
            "covariance": self.covariance.tolist(),
            "n_samples": self.n_samples,
            "duration_s": self.duration_s,
            "timestamp": self.timestamp,
            "mode": self.mode,
            "spread": self.spread,
        }

    @classmethod
    def from_dict(cls, d: dict) -> TaughtPoint:
        return cls(np.asarray(d["position_world"], float), np.asarray(d["covariance"], float),
                   int(d["n_samples"]), float(d["duration_s"]), float(d["timestamp"]),
                   str(d["mode"]), float(d["spread"]))


@dataclass
class _Sample:
    t: float
    filtered: np.ndarray
    measured: np.ndarray | None
    covariance: np.ndarray | None
    mode: str


class DwellDetector:
    """Feed it every frame's filtered position (None when lost) and measurement (None when the
    frame was not measured: such frames are skipped)."""

    def __init__(self, params: DwellParams | None = None) -> None:
        self.params = params or DwellParams()
        self._window: deque[_Sample] = deque()
        self._armed = True
        self._last_taught: np.ndarray | None = None

    def reset(self) -> None:
        self._window.clear()
        self._armed = True
        self._last_taught = None

    @property
    def armed(self) -> bool:
        return self._armed

    def progress(self) -> float:
        """0..1: how far into the dwell the pointer is (for a UI progress ring)."""
        if not self._armed or len(self._window) < 2:
            return 0.0
        return float(min(1.0, (self._window[-1].t - self._window[0].t) / self.params.dwell_s))

    def update(self, t: float, filtered: np.ndarray | None, measured: np.ndarray | None = None,
               covariance: np.ndarray | None = None, mode: str = "stereo") -> TaughtPoint | None:
        p = self.params
        if filtered is None:  # lost: whatever dwell was under way is over, and re-arm
            self._window.clear()
            self._armed = True
            return None
        if measured is None:  # nothing measured: no sample, and never an event
            if self._window and t - self._window[-1].t > p.max_gap_s:
                self._window.clear()
            return None
        if self._window and t - self._window[-1].t > p.max_gap_s:
            self._window.clear()  # too long unmeasured: start the dwell afresh
        filtered = np.asarray(filtered, float)
        radius = p.radius if mode == "stereo" else p.radius_mono
        if not self._armed:
            if np.linalg.norm(filtered - self._last_taught) > p.rearm_factor * radius:
                self._armed = True
                self._window.clear()
            else:
                return None
        self._window.append(_Sample(t, filtered, measured, covariance, mode))
        # keep the longest recent stretch whose filtered positions all lie within the radius
        while len(self._window) > 1:
            pts = np.array([s.filtered for s in self._window])
            r = radius if all(s.mode == "stereo" for s in self._window) else p.radius_mono
            if np.max(np.linalg.norm(pts - pts.mean(axis=0), axis=1)) <= r:
                break
            self._window.popleft()
        span = self._window[-1].t - self._window[0].t
        meas = [s for s in self._window if s.measured is not None]
        if span + 1e-9 < p.dwell_s or len(meas) < p.min_samples:
            return None
        taught = self._summarise(meas, span)
        self._armed = False
        self._last_taught = taught.position_world
        self._window.clear()
        return taught

    @staticmethod
    def _summarise(samples: list[_Sample], span: float) -> TaughtPoint:
        Z = np.array([s.measured for s in samples])
        n = len(Z)
        mean = Z.mean(axis=0)
        scatter = np.cov(Z.T, ddof=1) if n > 1 else np.zeros((3, 3))
        covs = [s.covariance for s in samples if s.covariance is not None]
        model = np.mean(covs, axis=0) if covs else np.zeros((3, 3))
        mode = "stereo" if all(s.mode == "stereo" for s in samples) else "mono"
        spread = float(np.sqrt(np.mean(np.sum((Z - mean) ** 2, axis=1))))
        return TaughtPoint(mean, (scatter + model) / n, n, float(span), samples[-1].t, mode,
                           spread)
