"""Fixtures for the link tests: a fast arm and a closer for emulators and links."""

from __future__ import annotations

import pytest
from link_fixtures import FAST_SPEEDS

from assistant.robots.model import Tool
from assistant.robots.rv2aj import RV2AJ, RV2AJConfig


@pytest.fixture(scope="session")
def fast_robot() -> RV2AJ:
    return RV2AJ(RV2AJConfig(speeds_deg_s=FAST_SPEEDS, tool=Tool.straight(0.1)))


