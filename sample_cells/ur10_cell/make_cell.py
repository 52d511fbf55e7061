"""Generate the UR10 sample cell: re-run after changing a number.

    python sample_cells/ur10_cell/make_cell.py [OUT_DIR]

A Universal Robots UR10 (the URDF and meshes of example-robot-data, installed with the
``test`` extra) at its own joint limits (+-360 deg, the elbow +-180 deg), with a 100 mm glue
nozzle on ``tool0``. The session script adds the table, the workpiece, a clamp block and a
post, and teaches the seam.

Writes ``cell/`` next to this script (or into OUT_DIR): the robot (``base_link`` at the world
origin on the table, top z = 0). The URDF path is stored relative; a session resolves it in
the installed robot data at run time.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))

from assistant.cell.model import Cell  # noqa: E402
from assistant.cell.storage import save_cell  # noqa: E402
from assistant.robots.catalog import RobotSpec, ToolSpec  # noqa: E402

URDF = "example-robot-data/robots/ur_description/urdf/ur10_robot.urdf"
NOZZLE_LENGTH, NOZZLE_RADIUS = 0.100, 0.025


def robot_spec() -> RobotSpec:
    return RobotSpec(kind="urdf", urdf_path=URDF, base_link="base_link", tool_link="tool0",
                     tool=ToolSpec.straight(NOZZLE_LENGTH, NOZZLE_RADIUS, name="nozzle",
                                            has_gripper=False))


def main(out: Path = HERE) -> None:
    out.mkdir(parents=True, exist_ok=True)
    save_cell(Cell(robot_spec=robot_spec(), T_world_base=np.eye(4)), out / "cell")
    print(f"wrote {out / 'cell'}")


if __name__ == "__main__":
    main(Path(sys.argv[1]).resolve() if len(sys.argv) > 1 else HERE)
