"""Fixtures for the export tests: the thesis scenario and two Bezier drawings on the RV-2AJ,
the same three on a UR5 (URScript runs on 6-axis UR arms only), a 7-axis Panda.

`robot_for(dialect)` is the arm a dialect's tests run on: the thesis RV-2AJ (5 axes) where
the dialect's controller runs a 5-axis arm, else the UR5; `program_for(scenario, robot)` the
scenario planned for that arm."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.export import NeutralProgram, get_dialect, program_from_trajectory
from assistant.export.samples import drawing_trajectory, thesis_trajectory
from assistant.trajectory.bezier_drawings import drawing

UR5_URDF = "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"
PANDA_URDF = "example-robot-data/robots/panda_description/urdf/panda.urdf"


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


@pytest.fixture(scope="session")
def panda():
    """A 7-axis arm: the Franka Panda from example-robot-data, flange at panda_hand."""
    from assistant.robots.catalog import installed_robot_urdf
    from assistant.robots.urdf_robot import URDFRobot

    urdf, share = installed_robot_urdf(PANDA_URDF)
    return URDFRobot.from_file(urdf, package_dirs=[share], load_visual=False,
                               tool_link="panda_hand")


@pytest.fixture(scope="session")
def robot_for(rv2aj, ur5):
    """dialect name -> the arm its tests run on (the RV-2AJ unless its controller does not
    run a 5-axis arm: then the UR5)."""
    def pick(dialect: str):
        return rv2aj if rv2aj.dof in get_dialect(dialect).axis_counts else ur5

    return pick


@pytest.fixture(scope="session")
def program_for(rv2aj, thesis_program, drawing_program, frame_program):
    """(scenario, robot) -> the thesis, drawing (screen 9) or frame (frame 1) program planned
    for that robot; the RV-2AJ's are the fixtures above, others are made once and kept."""
    made = {("thesis", rv2aj.name): thesis_program, ("drawing", rv2aj.name): drawing_program,
            ("frame", rv2aj.name): frame_program}

    def get(scenario: str, robot) -> NeutralProgram:
        key = (scenario, robot.name)
        if key not in made:
            if scenario == "thesis":
                traj, name = thesis_trajectory(robot), "thesis"
            else:
                number, name = {"drawing": (9, "screen"), "frame": (1, "frame")}[scenario]
                traj = drawing_trajectory(robot, drawing(number), tolerance=1e-4, name=name)
            made[key] = program_from_trajectory(traj, robot, name=name)
        return made[key]

    return get
