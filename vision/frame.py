"""The unit of data between camera sources and the pointer pipeline: one time-stamped image.

`GroundTruth` rides along on synthetic frames only, so tests and benchmarks can compare the
pipeline's answer with where the ball really was when the frame was exposed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision.errors import FrameError


@dataclass(frozen=True)
class GroundTruth:
    """Where the pointer ball really was at the frame's timestamp (mid-exposure)."""

    ball_world: np.ndarray | None  # (3,) metres, None if the scene has no ball at that time
    ball_px: np.ndarray | None  # (2,) projection of the ball centre (distorted pixels)
    ball_radius_px: float  # apparent radius in pixels (0 when not in view)
    visible: bool  # drawn and inside the image (not hidden, not behind the camera)


@dataclass(frozen=True)
class Frame:
    """One image from one camera. `image` is BGR uint8 HxWx3; `timestamp` in seconds."""

    image: np.ndarray
    timestamp: float
    camera_id: str
    truth: GroundTruth | None = None


def validate_image(image: object, width: int, height: int, camera_id: str) -> np.ndarray:
    """Check that `image` is a BGR uint8 array of the camera's size; return it or raise.

    Raised rather than coerced: a silently resized or re-typed frame would put every pixel
    coordinate in the wrong place for the calibrated camera model.
    """
    if not isinstance(image, np.ndarray):
        raise FrameError(f"camera {camera_id!r}: frame is {type(image).__name__}, not an image")
    if image.dtype != np.uint8:
        raise FrameError(f"camera {camera_id!r}: frame has dtype {image.dtype}, expected uint8 BGR")
    if image.ndim != 3 or image.shape[2] != 3:
        raise FrameError(
            f"camera {camera_id!r}: frame has shape {image.shape}, expected (H, W, 3) BGR"
        )
    if image.shape[:2] != (height, width):
        raise FrameError(
            f"camera {camera_id!r}: frame is {image.shape[1]}x{image.shape[0]}, but the camera "
            f"is calibrated for {width}x{height}; recalibrate or set the capture size"
        )
    return image
