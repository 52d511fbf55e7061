"""The arm's reach sizes the world cube; it is remembered per robot and limits (every CAD
import and placement asks), and a robot with other limits gets its own answer."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from assistant.robots.rv2aj import RV2AJ, RV2AJConfig
from assistant.world.model_types import _REACH, tcp_reach


def test_reach_is_remembered_per_robot_and_limits():
    robot = RV2AJ(RV2AJConfig())
    first = tcp_reach(robot)
    assert 0.3 < first < 1.0  # the RV-2AJ reaches ~0.5 m from its base origin
    assert robot in _REACH and tcp_reach(robot) == first
    # narrower limits on the same object: computed again, not the remembered value
    full = robot.limits
    robot.limits = replace(full, lower=full.lower * 0.1, upper=full.upper * 0.1)
    try:
        narrow = tcp_reach(robot)
    finally:
        robot.limits = full
    assert not np.isclose(narrow, first)
    assert tcp_reach(RV2AJ(RV2AJConfig())) == first  # another object, same arm
