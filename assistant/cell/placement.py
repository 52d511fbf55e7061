"""Placing objects: a pose typed in mm/degrees, or fitted to points measured in the cell.

The thesis' four-point method measures four known locations of a part with the robot or the
pointer; here any N >= 3 point pairs give the rigid least-squares pose (Kabsch, no scale), and
the residuals tell the operator how well the model matches what was measured — a wrong point
order or a mis-measured corner shows up as one large per-point error.
Depends on the cell model only; must not import the UI, vision or planning.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.cell.model import Cell, CellObject
from assistant.transforms import pose_from_mm_deg, pose_to_mm_deg

Array = np.ndarray

#: Points closer than this are the same point measured twice.
MIN_SEPARATION_M = 0.002
#: If no point is this far from the line through the others, the rotation about that line is
#: not determined by the points (a pointer measures to ~1 mm).
MIN_OFF_LINE_M = 0.005
#: A per-point error above this earns a warning naming the point.
WARN_POINT_ERROR_M = 0.005


class PlacementError(ValueError):
    """Points that cannot define a pose; the message says which and what to measure instead."""


@dataclass(frozen=True, eq=False)
class PoseFit:
    """The fitted pose and how well the measured points agree with the model points."""

    T_world_object: Array
    rms_m: float
    per_point_error_m: Array  # (N,) distance of each transformed model point from its measurement
    max_error_m: float
    warnings: tuple[str, ...] = ()

    @property
    def worst_point(self) -> int:
        return int(np.argmax(self.per_point_error_m))

    def summary(self) -> str:
        errs = ", ".join(f"{e * 1000:.2f}" for e in self.per_point_error_m)
        text = (f"RMS {self.rms_m * 1000:.2f} mm, max {self.max_error_m * 1000:.2f} mm "
                f"(point {self.worst_point + 1}); per point [mm]: {errs}")
        return "\n".join([text, *self.warnings])


def _as_points(P: Array, what: str) -> Array:
    try:
        A = np.array(P, dtype=float)
    except (TypeError, ValueError) as exc:
        raise PlacementError(f"{what}: not a list of 3-D points ({exc})") from exc
    if A.ndim != 2 or A.shape[1] != 3:
        raise PlacementError(f"{what}: expected N points with x, y, z each, got shape {A.shape}")
    if not np.isfinite(A).all():
        raise PlacementError(f"{what}: contains NaN or infinite coordinates")
    return A


def _check_spread(P: Array, what: str, min_separation_m: float, min_off_line_m: float) -> None:
    n = len(P)
    d = np.linalg.norm(P[:, None, :] - P[None, :, :], axis=-1)
    i, j = np.triu_indices(n, k=1)
    close = d[i, j] < min_separation_m
    if close.any():
        a, b = int(i[close][0]), int(j[close][0])
        raise PlacementError(
            f"{what}: points {a + 1} and {b + 1} are the same point "
            f"({d[a, b] * 1000:.2f} mm apart); measure {n} distinct points")
    C = P - P.mean(axis=0)
    _, _, Vt = np.linalg.svd(C, full_matrices=False)
    along = C @ Vt[0]
    off = np.linalg.norm(C - np.outer(along, Vt[0]), axis=1)
    if off.max() < min_off_line_m:
        raise PlacementError(
            f"{what}: the points are nearly on a line (farthest {off.max() * 1000:.2f} mm off "
            f"it, need {min_off_line_m * 1000:.0f} mm), measure a point off the line")


def fit_pose(
    model_points: Array,
    measured_points: Array,
    *,
    min_separation_m: float = MIN_SEPARATION_M,
    min_off_line_m: float = MIN_OFF_LINE_M,
) -> PoseFit:
    """Rigid least-squares pose mapping model points (object frame) onto measured points (world).

    Args:
        model_points: (N, 3) points in the object frame (metres), N >= 3.
        measured_points: (N, 3) the same points measured in the world frame, same order.
        min_separation_m: closer points count as duplicates.
        min_off_line_m: at least one point must be this far from the line through the others.

    Returns:
        The pose, RMS and per-point residuals (metres).

    Raises:
        PlacementError: too few points, mismatched lists, duplicates or (near-)collinear points.
    """
    X = _as_points(model_points, "model points")
    Y = _as_points(measured_points, "measured points")
    if len(X) != len(Y):
        raise PlacementError(f"{len(X)} model points but {len(Y)} measured points; "
                             "give one measurement per model point, in the same order")
    if len(X) < 3:
        raise PlacementError(f"a pose needs at least 3 point pairs, got {len(X)}")
    _check_spread(X, "model points", min_separation_m, min_off_line_m)
    _check_spread(Y, "measured points", min_separation_m, min_off_line_m)

    cx, cy = X.mean(axis=0), Y.mean(axis=0)
    H = (X - cx).T @ (Y - cy)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])  # no reflections
    R = Vt.T @ D @ U.T
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = cy - R @ cx

    err = np.linalg.norm(X @ R.T + T[:3, 3] - Y, axis=1)
    warnings = []
    k = int(np.argmax(err))
    if err[k] > WARN_POINT_ERROR_M:
        warnings.append(f"point {k + 1} is {err[k] * 1000:.1f} mm off the fitted model: check "
                        "that the points were measured in the same order as the model points")
    return PoseFit(T, float(np.sqrt(np.mean(err**2))), err, float(err.max()), tuple(warnings))


def place_by_points(cell: Cell, name: str, model_points: Array,
                    measured_points: Array, **kwargs) -> PoseFit:
    """Fit the pose of object `name` and apply it (nothing changes if the fit is refused)."""
    cell.get_object(name)
    fit = fit_pose(model_points, measured_points, **kwargs)
    cell.set_object_pose(name, fit.T_world_object)
    return fit


def set_pose_mm_deg(cell: Cell, name: str, xyzabc: Array) -> CellObject:
    """Place object `name` at (x, y, z [mm], a, b, c [deg]) in the world frame (Z-Y'-X'')."""
    try:
        T = pose_from_mm_deg(xyzabc)
    except (ValueError, TypeError) as exc:
        raise PlacementError(f"pose of {name!r}: {exc}") from exc
    if not np.isfinite(T).all():
        raise PlacementError(f"pose of {name!r}: contains NaN or infinite values")
    return cell.set_object_pose(name, T)


def pose_mm_deg(cell: Cell, name: str) -> Array:
    """The object's world pose as (x, y, z [mm], a, b, c [deg]) for the UI."""
    return pose_to_mm_deg(cell.get_object(name).T_world_object)
