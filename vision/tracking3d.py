"""The pointer's 3-D track: one constant-velocity Kalman filter in the world frame, Mahalanobis
gating of each frame's candidate positions, held (coasting) for up to `hold_s` without a
measurement, re-initialised when the measurements persistently disagree with it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision.geometry import PointEstimate
from vision.kalman import ConstantVelocityFilter

CHI2_3DOF_999 = 16.27


@dataclass(frozen=True)
class Tracking3DParams:
    hold_s: float = 1.0
    accel_std: float = 8.0  # m/s^2: brisk hand motion
    initial_velocity_std: float = 1.0  # m/s
    gate_chi2: float = CHI2_3DOF_999
    min_gate: float = 0.003  # metres: never gate tighter than the ball wobble
    reinit_after_s: float = 0.25  # persistent disagreement this long: start a new track
    reinit_step: float = 0.05  # metres a disagreeing candidate may move per frame and persist
    reseed_after_s: float = 0.1  # a measurement after a longer gap re-seeds the velocity
    max_speed: float = 2.5  # m/s: no hand moves the pointer faster; bounds the gate in metres
    reach_margin: float = 0.02  # metres added to max_speed * gap (measurement noise, wobble)
    same_place: float = 0.03  # metres: picked up again this close to where it was lost


class Track3D:
    """At most one pointer track. `step` predicts; `offer` gates and updates."""

    def __init__(self, params: Tracking3DParams | None = None) -> None:
        self.params = params or Tracking3DParams()
        self.filter: ConstantVelocityFilter | None = None
        self.track_id = 0
        self.time: float | None = None
        self.last_measurement_time: float | None = None
        self.last_mode = "lost"
        self._disagree_since: float | None = None
        self._disagree_at: np.ndarray | None = None
        self.last_measured_position: np.ndarray | None = None
        self.hits = 0  # measurements in a row since the track (re)started
        self.confirmed = False  # set by the owner once the track has been offered
        self.was_confirmed = False  # offered before it was picked up again elsewhere
        self.start_position: np.ndarray | None = None
        self.travel = 0.0  # farthest a measurement has been from where the track started

    @property
    def active(self) -> bool:
        return self.filter is not None

    def reset(self) -> None:
        self.filter = None
        self.last_measured_position = None
        self.hits = 0
        self.confirmed = False
        self.was_confirmed = False
        self.time = None
        self.last_measurement_time = None
        self.last_mode = "lost"
        self._disagree_since = None
        self._disagree_at = None

    def predict_to(self, t: float) -> None:
        """Advance to time t; drop the track when it has gone unmeasured for over `hold_s`."""
        if self.filter is None:
            self.time = t
            return
        if self.time is not None and t > self.time:
            self.filter.predict(t - self.time)
        self.time = t if self.time is None else max(self.time, t)
        if self.last_measurement_time is not None and \
                t - self.last_measurement_time > self.params.hold_s:
            self.reset()
            self.time = t

    def gate_distance(self, est: PointEstimate) -> float:
        """Squared Mahalanobis distance of a candidate (inf with no track)."""
        if self.filter is None:
            return float("inf")
        if self.last_measured_position is not None and self.time is not None and \
                self.last_measurement_time is not None:
            gap = max(self.time - self.last_measurement_time, 0.0)
            sd = float(np.sqrt(max(np.linalg.eigvalsh(est.covariance).max(), 0.0)))
            reach = self.params.reach_margin + self.params.max_speed * gap + 3.0 * sd
            if np.linalg.norm(est.position_world - self.last_measured_position) > reach:
                return float("inf")  # farther than a hand could have taken it
        if np.linalg.norm(est.position_world - self.filter.position) <= self.params.min_gate:
            return 0.0
        return self.filter.mahalanobis_sq(est.position_world, est.covariance)

    def in_gate(self, est: PointEstimate) -> bool:
        return self.gate_distance(est) <= self.params.gate_chi2

    def start(self, t: float, est: PointEstimate) -> None:
        p = self.params
        self.filter = ConstantVelocityFilter(3, est.position_world, est.covariance,
                                             p.initial_velocity_std, p.accel_std)
        self.track_id += 1
        self.time = t
        self.last_measurement_time = t
        self.last_mode = est.mode
        self._disagree_since = None
        self._disagree_at = None
        self.last_measured_position = np.asarray(est.position_world, float).copy()
        self.hits = 1
        self.confirmed = False
        self.was_confirmed = False
        self.start_position = self.last_measured_position.copy()
        self.travel = 0.0

    def update(self, t: float, est: PointEstimate, keep_disagreement: bool = False) -> None:
        """Kalman update; after a gap of over `reseed_after_s` (occlusion, dropout) the filter
        is re-seeded at the measurement instead, keeping the track id: a velocity inferred
        from a jump across a long gap is mostly the gap's error and would fling the track.
        `keep_disagreement`: a weaker (single-view) fix updates the track without clearing the
        count of stereo fixes persistently elsewhere, so those can still take over."""
        assert self.filter is not None
        p = self.params
        gap = t - (self.last_measurement_time if self.last_measurement_time is not None else t)
        jump = np.inf if self.last_measured_position is None else float(
            np.linalg.norm(est.position_world - self.last_measured_position))
        # picked up again and not yet confirmed there: what it was picked up at may have been
        # something else (a look-alike while the ball was hidden); a jump from there is a new
        # start, not a velocity
        unsure = self.was_confirmed and not self.confirmed and jump > p.same_place
        if gap > p.reseed_after_s or unsure:
            self.filter = ConstantVelocityFilter(3, est.position_world, est.covariance,
                                                 p.initial_velocity_std, p.accel_std)
            self.hits = 1  # picked up again after a gap: to be confirmed like a new track
            if jump > p.same_place:  # somewhere else: it must show it moves, like a new track
                # (or the owner recognises it: `was_confirmed` says it had been offered)
                self.was_confirmed |= self.confirmed
                self.confirmed = False
                self.start_position = np.asarray(est.position_world, float).copy()
                self.travel = 0.0
        else:
            self.filter.update(est.position_world, est.covariance)
            self.hits += 1
        self.last_measured_position = np.asarray(est.position_world, float).copy()
        if self.start_position is not None:
            self.travel = max(self.travel, float(np.linalg.norm(
                self.last_measured_position - self.start_position)))
        self.last_measurement_time = t
        self.last_mode = est.mode
        if not keep_disagreement:
            self._disagree_since = None
            self._disagree_at = None

    def disagreement(self, t: float, position: np.ndarray) -> bool:
        """Note a candidate outside the gate at `position`; True once candidates have stayed
        outside for `reinit_after_s`, each within `reinit_step` of the last (the pointer
        really is elsewhere: restart there). A candidate that jumps around restarts the
        count, so a one-off look-alike never captures the track."""
        p = np.asarray(position, float)
        if self._disagree_at is None or np.linalg.norm(p - self._disagree_at) > \
                self.params.reinit_step:
            self._disagree_since = t
        self._disagree_at = p
        return t - self._disagree_since >= self.params.reinit_after_s
