"""Per-camera blob tracks: Hungarian association with a Mahalanobis gate, a 2-D
constant-velocity Kalman filter per track, and tracks held for a while after they vanish.

The thesis matched each blob to the nearest previous blob and held a lost blob for at most
1 s (003, §6.5.3); the Hungarian assignment is the same idea without its failure when two blobs
are close, and gating on the filter's own uncertainty replaces a fixed distance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from vision.detection import Detection
from vision.kalman import ConstantVelocityFilter

CHI2_2DOF_999 = 13.82


@dataclass(frozen=True)
class Tracking2DParams:
    hold_s: float = 1.0  # a track without detections is kept this long
    measurement_sigma_px: float = 0.5
    accel_std_px: float = 4000.0  # px/s^2: a hand swinging a pointer at 1 m
    initial_velocity_std_px: float = 400.0
    gate_chi2: float = CHI2_2DOF_999
    min_gate_px: float = 3.0  # never gate tighter than this (the ball's own wobble)
    confirm_hits: int = 3
    max_tracks: int = 16


@dataclass
class Track2D:
    track_id: int
    filter: ConstantVelocityFilter
    last_time: float
    radius_px: float
    hits: int = 1
    consecutive_hits: int = 1
    origin_px: np.ndarray | None = None  # where it was first seen
    travel_px: float = 0.0  # farthest it has been from there (still clutter: ~0)

    @property
    def position(self) -> np.ndarray:
        return self.filter.position


class Tracker2D:
    """All blob tracks of one camera."""

    def __init__(self, params: Tracking2DParams | None = None) -> None:
        self.params = params or Tracking2DParams()
        self.tracks: list[Track2D] = []
        self._next_id = 1
        self._time: float | None = None

    def reset(self) -> None:
        self.tracks.clear()
        self._time = None

    def track(self, track_id: int | None) -> Track2D | None:
        return next((t for t in self.tracks if t.track_id == track_id), None)

    def predicted(self, track_id: int | None, t: float) -> tuple[np.ndarray, np.ndarray] | None:
        """Predicted centre and covariance of a track at time t (None if gone)."""
        tr = self.track(track_id)
        if tr is None or self._time is None:
            return None
        return tr.filter.predicted(t - self._time)

    def update(self, t: float, detections: list[Detection]) -> list[int]:
        """Advance to time t with this frame's detections; returns the track id of each."""
        p = self.params
        dt = 0.0 if self._time is None else t - self._time
        if dt < 0:
            raise ValueError(f"time went backwards ({self._time} -> {t})")
        for tr in self.tracks:
            tr.filter.predict(dt)
        self._time = t
        R = np.eye(2) * p.measurement_sigma_px**2
        ids = [-1] * len(detections)
        matched_tracks: set[int] = set()
        if self.tracks and detections:
            cost = np.full((len(self.tracks), len(detections)), 1e9)
            for i, tr in enumerate(self.tracks):
                for j, d in enumerate(detections):
                    d2 = tr.filter.mahalanobis_sq(d.center_px, R)
                    near = np.linalg.norm(d.center_px - tr.position) <= p.min_gate_px
                    if d2 <= p.gate_chi2 or near:
                        cost[i, j] = d2
            rows, cols = linear_sum_assignment(cost)
            for i, j in zip(rows, cols, strict=True):
                if cost[i, j] >= 1e9:
                    continue
                tr = self.tracks[i]
                tr.filter.update(detections[j].center_px, R)
                tr.radius_px = 0.7 * tr.radius_px + 0.3 * detections[j].radius_px
                tr.last_time = t
                tr.hits += 1
                tr.consecutive_hits += 1
                if tr.origin_px is not None:
                    tr.travel_px = max(tr.travel_px, float(np.linalg.norm(
                        detections[j].center_px - tr.origin_px)))
                ids[j] = tr.track_id
                matched_tracks.add(tr.track_id)
        for tr in self.tracks:
            if tr.track_id not in matched_tracks:
                tr.consecutive_hits = 0
        self.tracks = [tr for tr in self.tracks if t - tr.last_time <= p.hold_s]
        for j, d in enumerate(detections):
            if ids[j] >= 0 or len(self.tracks) >= p.max_tracks:
                continue
            f = ConstantVelocityFilter(2, d.center_px, R, p.initial_velocity_std_px,
                                       p.accel_std_px)
            self.tracks.append(Track2D(self._next_id, f, t, d.radius_px,
                                       origin_px=np.asarray(d.center_px, float).copy()))
            ids[j] = self._next_id
            self._next_id += 1
        return ids

    def has_moved(self, track_id: int, radii: float = 2.0) -> bool:
        """True once the blob has travelled `radii` of its own radius: a hand-held ball does,
        a red thing of the background does not."""
        tr = self.track(track_id)
        return tr is not None and tr.travel_px >= radii * max(tr.radius_px, 1.0)

    def is_confirmed(self, track_id: int) -> bool:
        tr = self.track(track_id)
        return tr is not None and tr.consecutive_hits >= self.params.confirm_hits
