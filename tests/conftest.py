"""Shared fixtures. Browser tests live in tests/web and have their own conftest."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.robot_model import Tool
from assistant.rv2aj import RV2AJ, RV2AJConfig


@pytest.fixture(scope="session")
def rv2aj() -> RV2AJ:
    """The RV-2AJ with a 100 mm straight gripper, as in the sample cells."""
    return RV2AJ(RV2AJConfig(tool=Tool.straight(0.1)))


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)
