"""Fixtures for the export tests: the thesis scenario and a Bezier drawing on the RV-2AJ."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.export import NeutralProgram, program_from_trajectory
from assistant.export.samples import drawing_trajectory, thesis_trajectory
from assistant.trajectory.bezier_drawings import drawing

UR5_URDF = "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"


@pytest.fixture(scope="session")
def thesis_program(rv2aj) -> NeutralProgram:
    return program_from_trajectory(thesis_trajectory(rv2aj), rv2aj, name="thesis")


@pytest.fixture(scope="session")
def drawing_program(rv2aj) -> NeutralProgram:
    """Screen 9 (straight sides, a curved top), sampled to 0.1 mm, drawn as one spline."""
    traj = drawing_trajectory(rv2aj, drawing(9), tolerance=1e-4, name="screen")
    return program_from_trajectory(traj, rv2aj, name="screen")


@pytest.fixture(scope="session")
def frame_program(rv2aj) -> NeutralProgram:
    """Frame 1 (the source timed a frame): straight strokes and quarter arcs -> LIN and CIRC."""
    traj = drawing_trajectory(rv2aj, drawing(1), tolerance=1e-4, name="frame")
    return program_from_trajectory(traj, rv2aj, name="frame")


@pytest.fixture(scope="session")
def ur5():
    """A UR5 from example-robot-data (the `test` extra) through URDFRobot; never skipped."""
    from assistant.robots.catalog import installed_robot_urdf
    from assistant.robots.model import Tool
    from assistant.robots.urdf_robot import URDFRobot

    urdf, share = installed_robot_urdf(UR5_URDF)
    T = np.eye(4)
    T[2, 3] = 0.1
    return URDFRobot.from_file(urdf, package_dirs=[share], load_visual=False,
                               tool=Tool("gripper", T))
