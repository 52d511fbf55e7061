"""Extrinsic calibration: where a calibrated camera sits relative to the robot base, from
points the robot's TCP (or the pointer touching the TCP) visits and where the camera saw them.

Perspective-n-point in least squares (SQPnP start, Levenberg-Marquardt refinement), with the
residual reported both in pixels and as the 3-D distance of each point from its viewing ray.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vision.camera_model import CameraModel
from vision.errors import CalibrationError


@dataclass(frozen=True)
class ExtrinsicsResult:
    T_world_camera: np.ndarray
    rms_px: float
    max_px: float
    residuals_px: np.ndarray  # per point
    rms_m: float  # RMS distance of the points from their rays (metres)
    n_points: int

    def camera_model(self, intrinsics: CameraModel) -> CameraModel:
        return intrinsics.with_pose(self.T_world_camera)


def calibrate_extrinsics(intrinsics: CameraModel, points_world: np.ndarray,
                         pixels: np.ndarray, *, min_points: int = 6) -> ExtrinsicsResult:
    """T_world_camera from world points (N, 3) and their pixels (N, 2); intrinsics' pose unused.

    Raises `CalibrationError` for fewer than `min_points` points, non-finite input, or points
    that are (nearly) collinear, since their pose is not determined.
    """
    P = np.asarray(points_world, dtype=np.float64)
    uv = np.asarray(pixels, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3 or uv.shape != (len(P), 2):
        raise CalibrationError(f"need (N, 3) points and (N, 2) pixels, got {P.shape} and "
                               f"{uv.shape}")
    if len(P) < min_points:
        raise CalibrationError(f"{len(P)} points are too few; visit at least {min_points} "
                               "robot positions spread over the workspace")
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(uv))):
        raise CalibrationError("calibration points contain NaN or infinity")
    sv = np.linalg.svd(P - P.mean(axis=0), compute_uv=False)
    if sv[1] < 1e-3 * max(sv[0], 1e-12) or sv[0] < 1e-6:
        raise CalibrationError("the points are (nearly) on one line; the camera's rotation "
                               "about that line is undetermined: visit points off the line")
    ok, rvec, tvec = cv2.solvePnP(P, uv, intrinsics.K, intrinsics.dist,
                                  flags=cv2.SOLVEPNP_SQPNP)
    if not ok:
        raise CalibrationError("no camera pose fits these points")
    rvec, tvec = cv2.solvePnPRefineLM(P, uv, intrinsics.K, intrinsics.dist, rvec, tvec)
    R, _ = cv2.Rodrigues(rvec)
    T_camera_world = np.eye(4)
    T_camera_world[:3, :3] = R
    T_camera_world[:3, 3] = tvec.ravel()
    T_world_camera = np.eye(4)
    T_world_camera[:3, :3] = R.T
    T_world_camera[:3, 3] = -R.T @ tvec.ravel()
    model = intrinsics.with_pose(T_world_camera)
    proj = model.project(P)
    res = np.linalg.norm(proj - uv, axis=1)
    rays = model.rays_world(uv)
    rel = P - model.position_world
    along = np.sum(rel * rays, axis=1, keepdims=True)
    dist3 = np.linalg.norm(rel - along * rays, axis=1)
    if np.any(along <= 0):
        raise CalibrationError("the solved pose puts some points behind the camera; check "
                               "that points and pixels are listed in the same order")
    return ExtrinsicsResult(T_world_camera, float(np.sqrt(np.mean(res**2))), float(res.max()),
                            res, float(np.sqrt(np.mean(dist3**2))), len(P))
