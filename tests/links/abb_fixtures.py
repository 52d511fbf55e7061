"""Shared values for the ABB tests: the UR5 of example-robot-data stands in for an IRB arm
(6 axes, the jointtarget's rax_1..rax_6), postures and an exploration sweep."""

from __future__ import annotations

import numpy as np

from assistant.robots.catalog import installed_robot_urdf
from assistant.robots.urdf_robot import URDFRobot

UR5 = "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"

HOME = np.radians([0.0, -90.0, 90.0, -90.0, -90.0, 0.0])
#: The sweep: the arm turns about axis 1 from -40 to +40 degrees, reaching forward.
Q_A = np.radians([-40.0, -80.0, 80.0, -90.0, -90.0, 0.0])
Q_B = np.radians([40.0, -80.0, 80.0, -90.0, -90.0, 0.0])
#: Robot seconds per wall second in the emulator: moves take tenths of a second.
TIME_SCALE = 4.0


def ur5() -> URDFRobot:
    path, share = installed_robot_urdf(UR5)
    return URDFRobot.from_file(path, package_dirs=[share], tool_link="tool0")
