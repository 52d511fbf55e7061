"""Fixtures of the robot tests: the UR5 and Panda from example-robot-data."""

from __future__ import annotations

import pytest
from urdf_builders import PANDA_URDF, SHARE, UR5_URDF

from assistant.robots.urdf_robot import URDFRobot


@pytest.fixture(scope="module")
def ur5() -> URDFRobot:
    return URDFRobot.from_file(UR5_URDF, package_dirs=[SHARE])


@pytest.fixture(scope="module")
def panda() -> URDFRobot:
    # No package_dirs: package://example-robot-data/... is found among the URDF's ancestors.
    return URDFRobot.from_file(PANDA_URDF, tool_link="panda_hand")
