"""Intrinsic calibration (K and distortion) from chessboard or ChArUco images, with the
reprojection error reported and too few or too similar views refused with a clear reason."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from vision.calibration_targets import CharucoSpec, ChessboardSpec
from vision.camera_model import CameraModel
from vision.errors import CalibrationError


@dataclass(frozen=True)
class IntrinsicsResult:
    K: np.ndarray
    dist: np.ndarray
    image_size: tuple[int, int]  # width, height
    rms_px: float  # overall reprojection RMS
    per_view_rms_px: np.ndarray
    std_intrinsics: np.ndarray  # OpenCV's standard deviations (fx, fy, cx, cy, k1, ...)
    n_views: int
    used_views: tuple[int, ...]  # indices of the input images that showed the board

    def camera_model(self, T_world_camera: np.ndarray | None = None) -> CameraModel:
        w, h = self.image_size
        return CameraModel(w, h, self.K, self.dist,
                           np.eye(4) if T_world_camera is None else T_world_camera)


def _check_images(images: Sequence[np.ndarray]) -> tuple[int, int]:
    if len(images) == 0:
        raise CalibrationError("no calibration images")
    sizes = set()
    for k, img in enumerate(images):
        if not isinstance(img, np.ndarray) or img.dtype != np.uint8 or img.ndim != 3:
            raise CalibrationError(f"calibration image {k} is not a BGR uint8 image")
        sizes.add((img.shape[1], img.shape[0]))
    if len(sizes) != 1:
        raise CalibrationError(f"calibration images differ in size: {sorted(sizes)}")
    return sizes.pop()


def _solve(obj: list[np.ndarray], img: list[np.ndarray], size: tuple[int, int],
           used: list[int], n_images: int, min_views: int, max_rel_std: float,
           fix_k3: bool, min_tilt_spread_deg: float) -> IntrinsicsResult:
    if len(obj) < min_views:
        raise CalibrationError(
            f"only {len(obj)} of {n_images} images show the board; need at least {min_views} "
            "(hold the whole board in view, at different angles)")
    flags = cv2.CALIB_FIX_K3 if fix_k3 else 0
    rms, K, dist, rvecs, _, std_in, _, per_view = cv2.calibrateCameraExtended(
        [o.astype(np.float32) for o in obj], [i.astype(np.float32) for i in img], size, None,
        None, flags=flags,
        criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-10))
    normals = np.array([cv2.Rodrigues(r)[0][:, 2] for r in rvecs])
    cross = np.linalg.norm(np.cross(normals[:, None, :], normals[None, :, :]), axis=2)
    spread = np.degrees(np.arctan2(cross, normals @ normals.T)).max()  # atan2: well conditioned
    if spread < min_tilt_spread_deg:
        raise CalibrationError(
            f"the views are degenerate: the board faces the same way in all of them (within "
            f"{spread:.1f} degrees); tilt it by 20-40 degrees in different directions")
    std_in = np.asarray(std_in, float).ravel()
    f = 0.5 * (K[0, 0] + K[1, 1])
    rel = np.max(std_in[:4]) / f if np.all(np.isfinite(std_in[:4])) else np.inf
    if not np.isfinite(rms) or rel > max_rel_std:
        raise CalibrationError(
            "the views are degenerate (too similar, or all square-on): the focal length and "
            f"centre are uncertain to {100 * rel:.1f} % of f; tilt the board by 20-40 degrees in "
            "different directions and cover the corners of the image")
    return IntrinsicsResult(K, np.asarray(dist, float).ravel(), size, float(rms),
                            np.asarray(per_view, float).ravel(), std_in, len(obj), tuple(used))


def calibrate_chessboard(images: Sequence[np.ndarray], spec: ChessboardSpec, *,
                         min_views: int = 5, max_rel_std: float = 0.01, fix_k3: bool = True,
                         min_tilt_spread_deg: float = 10.0) -> IntrinsicsResult:
    """K and distortion from images of a chessboard (views without the full board are skipped).

    Raises `CalibrationError` for too few usable views or a degenerate set: board normals all
    within `min_tilt_spread_deg` of each other, or the standard deviation of fx, fy, cx or cy
    above `max_rel_std` of the focal length. `fix_k3` (default) keeps the sixth-order radial
    term at zero: with views that rarely reach the image corners it only adds wild
    extrapolation there, which is OpenCV's own advice for ordinary lenses.
    """
    size = _check_images(images)
    obj, img, used = [], [], []
    P = spec.object_points()
    for k, im in enumerate(images):
        c = spec.detect(im)
        if c is not None:
            obj.append(P)
            img.append(c)
            used.append(k)
    return _solve(obj, img, size, used, len(images), min_views, max_rel_std, fix_k3,
                  min_tilt_spread_deg)


def calibrate_charuco(images: Sequence[np.ndarray], spec: CharucoSpec, *, min_views: int = 5,
                      min_corners: int = 8, max_rel_std: float = 0.01, fix_k3: bool = True,
                      min_tilt_spread_deg: float = 10.0) -> IntrinsicsResult:
    """K and distortion from ChArUco images; partial views count if >= `min_corners` corners."""
    size = _check_images(images)
    P = spec.object_points()
    obj, img, used = [], [], []
    for k, im in enumerate(images):
        found = spec.detect(im, min_corners)
        if found is None:
            continue
        px, ids = found
        obj.append(P[ids])
        img.append(px)
        used.append(k)
    return _solve(obj, img, size, used, len(images), min_views, max_rel_std, fix_k3,
                  min_tilt_spread_deg)
