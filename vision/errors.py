"""Errors the vision package raises: each names what went wrong and what to do about it.

Callers (the Session, the web UI) show the message to the operator as is, so every message says
which camera / which input and, where there is one, the remedy.
"""

from __future__ import annotations


class VisionError(Exception):
    """Base of every error raised on purpose by `vision`."""


class CameraError(VisionError):
    """A camera could not be opened or failed while reading."""


class CameraTimeout(CameraError):
    """No frame arrived within the timeout: the camera is slow, stalled or unplugged."""


class CameraClosed(CameraError):
    """The source has ended (video file at its end, folder exhausted, closed by the caller)."""


class FrameError(VisionError):
    """A frame has the wrong size, type or channel count for its camera."""


class CalibrationError(VisionError):
    """Calibration input is too small, degenerate, or does not contain the expected pattern."""


class ColorCalibrationError(CalibrationError):
    """The colour-calibration ellipse is empty, outside the image, or holds no coloured pixels."""


class ColorNotSeparable(ColorCalibrationError):
    """The marker's colour is also the colour of much of the background around it.

    `calibration` (a `vision.color_calibration.ColorCalibration`) holds the best profile found
    and its mask over the image, for the UI to show what the profile would pick up."""

    def __init__(self, message: str, calibration: object = None) -> None:
        super().__init__(message)
        self.calibration = calibration
