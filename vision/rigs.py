"""Ready camera arrangements for sample cells, tests and benchmarks.

The robot cell is roughly a 1 m cube around the robot base at the world origin, z up; cameras
stand off to one side and look at a workspace centre.
"""

from __future__ import annotations

import numpy as np

from vision.camera_model import CameraModel


def look_at(eye_world: np.ndarray, target_world: np.ndarray,
            up_world: np.ndarray = (0.0, 0.0, 1.0)) -> np.ndarray:
    """T_world_camera of an OpenCV camera at `eye_world` whose optical axis hits `target_world`.

    Image "up" (−y) is as close to `up_world` as the viewing direction allows.
    """
    eye = np.asarray(eye_world, dtype=float)
    z = np.asarray(target_world, dtype=float) - eye
    if np.linalg.norm(z) < 1e-9:
        raise ValueError("camera position and target coincide")
    z /= np.linalg.norm(z)
    up = np.asarray(up_world, dtype=float)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-6:  # looking straight along up: pick any sideways axis
        x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, y, z])
    T[:3, 3] = eye
    return T


def default_stereo_rig(
    center_world: np.ndarray = (0.3, 0.0, 0.3),
    distance: float = 1.0,
    baseline: float = 0.5,
    fov_deg: float = 60.0,
    size: tuple[int, int] = (640, 480),
    *,
    azimuth_deg: float = 0.0,
    elevation_deg: float = 20.0,
) -> list[CameraModel]:
    """Two converging cameras `distance` from `center_world`, `baseline` apart, no distortion.

    The pair's midpoint sits at `distance` from the centre along the direction given by
    `azimuth_deg` (about z, 0 = +x: in front of a robot facing +x) and `elevation_deg` (above
    the horizontal); the cameras are offset ±baseline/2 sideways and both look at the centre.
    """
    if distance <= 0 or baseline <= 0:
        raise ValueError("distance and baseline must be positive")
    c = np.asarray(center_world, dtype=float)
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    back = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    side = np.array([-np.sin(az), np.cos(az), 0.0])
    mid = c + distance * back
    w, h = size
    return [
        CameraModel.from_fov(w, h, fov_deg, look_at(mid + s * 0.5 * baseline * side, c))
        for s in (-1.0, 1.0)
    ]


def ring_rig(
    center_world: np.ndarray,
    n_cameras: int,
    distance: float = 1.0,
    fov_deg: float = 60.0,
    size: tuple[int, int] = (640, 480),
    elevation_deg: float = 25.0,
    spread_deg: float = 90.0,
) -> list[CameraModel]:
    """`n_cameras` on an arc of `spread_deg` around the centre, all looking at it."""
    if n_cameras < 1:
        raise ValueError("a rig needs at least one camera")
    c = np.asarray(center_world, dtype=float)
    el = np.radians(elevation_deg)
    azs = np.radians(np.linspace(-spread_deg / 2, spread_deg / 2, n_cameras)) \
        if n_cameras > 1 else np.zeros(1)
    w, h = size
    cams = []
    for az in azs:
        eye = c + distance * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                                       np.sin(el)])
        cams.append(CameraModel.from_fov(w, h, fov_deg, look_at(eye, c)))
    return cams
