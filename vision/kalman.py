"""Constant-velocity Kalman filters (filterpy) for image points and 3-D points.

Frames do not arrive at a perfectly fixed rate, so F and Q are rebuilt from each step's dt;
Q is filterpy's discrete white-noise acceleration model. Gating uses the squared Mahalanobis
distance of a measurement from the prediction, computed before the update.
"""

from __future__ import annotations

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter


class ConstantVelocityFilter:
    """State [p (dim), v (dim)]; measurements are positions with a given covariance."""

    def __init__(self, dim: int, position: np.ndarray, position_cov: np.ndarray,
                 velocity_std: float, accel_std: float) -> None:
        if dim not in (2, 3):
            raise ValueError("dim must be 2 or 3")
        self.dim = dim
        self.accel_std = float(accel_std)
        kf = KalmanFilter(dim_x=2 * dim, dim_z=dim)
        kf.x = np.concatenate([np.asarray(position, float), np.zeros(dim)])
        kf.P = np.zeros((2 * dim, 2 * dim))
        kf.P[:dim, :dim] = position_cov
        kf.P[dim:, dim:] = np.eye(dim) * velocity_std**2
        kf.H = np.hstack([np.eye(dim), np.zeros((dim, dim))])
        self.kf = kf

    def _FQ(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        d = self.dim
        F = np.eye(2 * d)
        F[:d, d:] = np.eye(d) * dt
        Q = Q_discrete_white_noise(dim=2, dt=dt, var=self.accel_std**2, block_size=d,
                                   order_by_dim=False)
        return F, Q

    def predict(self, dt: float) -> None:
        if dt <= 0:
            return
        F, Q = self._FQ(dt)
        self.kf.predict(F=F, Q=Q)

    def predicted(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Position and its covariance dt from now, without changing the filter."""
        if dt <= 0:
            return self.position, self.position_cov
        F, Q = self._FQ(dt)
        x = F @ self.kf.x
        P = F @ self.kf.P @ F.T + Q
        return x[: self.dim].copy(), P[: self.dim, : self.dim].copy()

    def mahalanobis_sq(self, z: np.ndarray, R: np.ndarray) -> float:
        S = self.position_cov + R
        y = np.asarray(z, float) - self.position
        try:
            return float(y @ np.linalg.solve(S, y))
        except np.linalg.LinAlgError:
            return float("inf")

    def update(self, z: np.ndarray, R: np.ndarray) -> None:
        self.kf.update(np.asarray(z, float), R=np.asarray(R, float))

    @property
    def position(self) -> np.ndarray:
        return self.kf.x[: self.dim].copy()

    @property
    def velocity(self) -> np.ndarray:
        return self.kf.x[self.dim:].copy()

    @property
    def position_cov(self) -> np.ndarray:
        return self.kf.P[: self.dim, : self.dim].copy()
