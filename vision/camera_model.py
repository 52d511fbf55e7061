"""A calibrated camera: intrinsics (K, distortion), image size and its pose in the world.

The camera frame is OpenCV's (x right, y down, z forward, metres). `T_world_camera` maps points
in the camera frame into the world frame, which is whatever frame the extrinsic calibration was
solved in: the robot base frame in our cells.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

_DIST_LENGTHS = (4, 5, 8, 12, 14)


def _rigid(T: np.ndarray, what: str) -> np.ndarray:
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4):
        raise ValueError(f"{what} must be 4x4, got {T.shape}")
    R = T[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise ValueError(f"{what} is not a rigid transform (rotation not orthonormal)")
    if not np.allclose(T[3], [0, 0, 0, 1]):
        raise ValueError(f"{what} has a last row other than [0, 0, 0, 1]")
    return T


@dataclass
class CameraModel:
    """Pinhole camera with OpenCV distortion, placed in the world by `T_world_camera`."""

    width: int
    height: int
    K: np.ndarray
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))
    T_world_camera: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        if int(self.width) <= 0 or int(self.height) <= 0:
            raise ValueError(f"image size must be positive, got {self.width}x{self.height}")
        self.width, self.height = int(self.width), int(self.height)
        self.K = np.asarray(self.K, dtype=float)
        if self.K.shape != (3, 3) or self.K[0, 0] <= 0 or self.K[1, 1] <= 0:
            raise ValueError(f"K must be 3x3 with positive focal lengths, got {self.K.tolist()}")
        self.dist = np.asarray(self.dist, dtype=float).ravel()
        if self.dist.size not in _DIST_LENGTHS:
            raise ValueError(f"dist must have one of {_DIST_LENGTHS} coefficients")
        self.T_world_camera = _rigid(self.T_world_camera, "T_world_camera")

    @classmethod
    def from_fov(
        cls,
        width: int,
        height: int,
        fov_deg: float,
        T_world_camera: np.ndarray | None = None,
        dist: np.ndarray | None = None,
    ) -> CameraModel:
        """Square pixels, principal point at the image centre, `fov_deg` the horizontal FOV."""
        if not 0.0 < fov_deg < 179.0:
            raise ValueError(f"field of view must be in (0, 179) degrees, got {fov_deg}")
        f = 0.5 * width / np.tan(np.radians(fov_deg) / 2.0)
        K = np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0, 0, 1.0]])
        return cls(
            width,
            height,
            K,
            np.zeros(5) if dist is None else dist,
            np.eye(4) if T_world_camera is None else T_world_camera,
        )

    # -- derived ------------------------------------------------------------------------------
    @property
    def T_camera_world(self) -> np.ndarray:
        T = np.eye(4)
        R = self.T_world_camera[:3, :3]
        T[:3, :3] = R.T
        T[:3, 3] = -R.T @ self.T_world_camera[:3, 3]
        return T

    @property
    def position_world(self) -> np.ndarray:
        """Optical centre in the world frame."""
        return self.T_world_camera[:3, 3].copy()

    @property
    def focal_px(self) -> float:
        return float(0.5 * (self.K[0, 0] + self.K[1, 1]))

    @property
    def has_distortion(self) -> bool:
        return bool(np.any(self.dist != 0.0))

    @property
    def size(self) -> tuple[int, int]:
        return self.width, self.height

    # -- projection ---------------------------------------------------------------------------
    def to_camera(self, points_world: np.ndarray) -> np.ndarray:
        """World points (N,3) or (3,) into the camera frame."""
        P = np.atleast_2d(np.asarray(points_world, dtype=float))
        T = self.T_camera_world
        return P @ T[:3, :3].T + T[:3, 3]

    def project(self, points_world: np.ndarray) -> np.ndarray:
        """Pixels (N,2) of world points (N,3) (or (2,) for one point); NaN behind the camera."""
        single = np.asarray(points_world).ndim == 1
        Pc = self.to_camera(points_world)
        uv = self.project_camera(Pc)
        return uv[0] if single else uv

    def project_camera(self, points_camera: np.ndarray) -> np.ndarray:
        """Pixels (N,2) of points already in the camera frame; NaN for z <= 0."""
        Pc = np.atleast_2d(np.asarray(points_camera, dtype=float))
        out = np.full((Pc.shape[0], 2), np.nan)
        front = Pc[:, 2] > 1e-9
        if not np.any(front):
            return out
        if self.has_distortion:
            uv, _ = cv2.projectPoints(Pc[front].reshape(-1, 1, 3), np.zeros(3), np.zeros(3),
                                      self.K, self.dist)
            out[front] = uv.reshape(-1, 2)
        else:
            xy = Pc[front, :2] / Pc[front, 2:3]
            out[front] = xy @ self.K[:2, :2].T + self.K[:2, 2]
        return out

    def normalized(self, pixels: np.ndarray) -> np.ndarray:
        """Undistorted normalised image coordinates (N,2) of distorted pixels (N,2)."""
        px = np.asarray(pixels, dtype=float).reshape(-1, 1, 2)
        if self.has_distortion:
            return cv2.undistortPoints(px, self.K, self.dist).reshape(-1, 2)
        p = px.reshape(-1, 2)
        return np.column_stack(
            [(p[:, 0] - self.K[0, 2]) / self.K[0, 0], (p[:, 1] - self.K[1, 2]) / self.K[1, 1]]
        )

    def rays_world(self, pixels: np.ndarray) -> np.ndarray:
        """Unit direction vectors (N,3) in the world frame of the rays through `pixels`."""
        n = self.normalized(pixels)
        d = np.column_stack([n, np.ones(len(n))])
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return d @ self.T_world_camera[:3, :3].T

    def in_image(self, pixels: np.ndarray, margin: float = 0.0) -> np.ndarray:
        p = np.atleast_2d(pixels)
        return (
            np.isfinite(p).all(axis=1)
            & (p[:, 0] >= -0.5 + margin)
            & (p[:, 0] <= self.width - 0.5 - margin)
            & (p[:, 1] >= -0.5 + margin)
            & (p[:, 1] <= self.height - 0.5 - margin)
        )

    # -- persistence --------------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {
            "width": self.width,
            "height": self.height,
            "K": self.K.tolist(),
            "dist": self.dist.tolist(),
            "T_world_camera": self.T_world_camera.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict) -> CameraModel:
        missing = {"width", "height", "K"} - set(data)
        if missing:
            raise ValueError(f"camera model is missing {sorted(missing)}")
        return cls(
            width=data["width"],
            height=data["height"],
            K=np.asarray(data["K"], dtype=float),
            dist=np.asarray(data.get("dist", [0.0] * 5), dtype=float),
            T_world_camera=np.asarray(data.get("T_world_camera", np.eye(4)), dtype=float),
        )

    def with_pose(self, T_world_camera: np.ndarray) -> CameraModel:
        return CameraModel(self.width, self.height, self.K.copy(), self.dist.copy(),
                           T_world_camera)
