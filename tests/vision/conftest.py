"""Fixtures for the marker-pointer tests: the default stereo rig of the sample cells."""

from __future__ import annotations

import numpy as np
import pytest

from vision.camera_model import CameraModel
from vision.rigs import default_stereo_rig

CENTRE = np.array([0.3, 0.0, 0.3])


@pytest.fixture(scope="session")
def stereo_rig() -> list[CameraModel]:
    """Two 640x480, 60 degree cameras 1 m from the workspace centre, 0.5 m apart."""
    return default_stereo_rig(CENTRE, distance=1.0, baseline=0.5, fov_deg=60, size=(640, 480))


@pytest.fixture(scope="session")
def centre() -> np.ndarray:
    return CENTRE.copy()
