"""Generate the Panda sample cell: re-run after changing a number.

    python sample_cells/panda_cell/make_cell.py [OUT_DIR]

A Franka Emika Panda (7 axes; the URDF and meshes of example-robot-data, installed with the
``test`` extra) at its own joint limits, with a 100 mm gripper on ``panda_hand``. The session
script adds the table, two fixtures and the wall between them, and teaches the pick and place.

Writes ``cell/`` next to this script (or into OUT_DIR): the robot (``panda_link0`` at the world
origin, the table top at z = 0). The URDF path is stored relative; a session resolves it in
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

URDF = "example-robot-data/robots/panda_description/urdf/panda.urdf"
GRIPPER_LENGTH, GRIPPER_RADIUS = 0.100, 0.03


def robot_spec() -> RobotSpec:
    return RobotSpec(kind="urdf", urdf_path=URDF, base_link="panda_link0",
                     tool_link="panda_hand",
                     tool=ToolSpec.straight(GRIPPER_LENGTH, GRIPPER_RADIUS, name="gripper",
                                            has_gripper=True))


def main(out: Path = HERE) -> None:
    out.mkdir(parents=True, exist_ok=True)
    save_cell(Cell(robot_spec=robot_spec(), T_world_base=np.eye(4)), out / "cell")
    print(f"wrote {out / 'cell'}")


if __name__ == "__main__":
    main(Path(sys.argv[1]).resolve() if len(sys.argv) > 1 else HERE)
