"""Generate the UR5 sample cell: re-run after changing a number.

    python sample_cells/ur5_cell/make_cell.py [OUT_DIR]

A Universal Robots UR5 (the URDF and meshes of example-robot-data, installed with the
``test`` extra) glues one seam on a plate: from START it moves to the seam, runs it as a
line with the dispenser on (output 1), and goes to GOAL, past a clamp block and a post.

Writes, next to this script (or into OUT_DIR):

* ``cad/plate.stl`` - the workpiece plate (mm, origin: middle of its footprint).
* ``cell/`` - the cell saved with `save_cell`: the UR5 (`base_link` at the world origin on the
  table, top z = 0) with a 100 mm nozzle on `tool0`, the table, the plate, the clamp block
  and the post. The URDF path is stored relative (``example-robot-data/robots/...``); a
  session resolves it in the installed robot data at run time, so the cell names no
  machine's site-packages.
* ``mission.json`` - START, GOAL and the seam.

Joint ranges: the UR5's own (+-360 deg, the elbow +-180 deg), as the URDF states them; the
world model samples them (`world.joint_samples`) and gathers its positions around the taught
postures.

World = the UR5's ``base_link`` frame (x forward, z up), metres.
Note: the UR controller's own base frame is the URDF's ``base`` link, turned 180 deg about z
from ``base_link``; the program's poses are in ``base_link``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))

from assistant.cell.cad import load_cad  # noqa: E402
from assistant.cell.model import Cell, CellObject, ObjectRole  # noqa: E402
from assistant.cell.storage import save_cell  # noqa: E402
from assistant.mission.model import (  # noqa: E402
    ApplicationPath,
    Location,
    LocationSource,
    PathSegment,
    ResolvedMission,
    SegmentKind,
)
from assistant.mission.motion import ToolAction, ToolActionKind  # noqa: E402
from assistant.robots.catalog import RobotSpec, ToolSpec  # noqa: E402
from assistant.transforms import make_T, stored_pose  # noqa: E402

URDF = "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"
NOZZLE_LENGTH, NOZZLE_RADIUS = 0.100, 0.025

TABLE = ((0.2, 0.0, -0.01), (1.2, 1.2, 0.02))
PLATE_AT, PLATE = (0.50, 0.0, 0.0), (0.25, 0.35, 0.020)
#: Clamp block between START and the seam, post between the seam and GOAL.
CLAMP = ((0.30, -0.30, 0.075), (0.12, 0.10, 0.15))
POST = ((0.42, 0.26, 0.225), 0.03, 0.45)
#: START, GOAL and the seam's start as the operator jogs to them (joints, deg); nozzle down,
#: wrist 3 at 0 (the nozzle lies on the wrist 3 axis: the world model holds it at 0). The
#: TCPs: START (300, -400, 350), GOAL (300, 400, 350), SEAM_A (500, -120, 45) mm, within the
#: jog's rounding.
START_Q_DEG = (-65.7, -89.8, 87.2, -87.3, -90.0, 0.0)
GOAL_Q_DEG = (40.5, -89.8, 87.2, -87.3, -90.0, 0.0)
SEAM_A_Q_DEG = (-25.8, -73.3, 116.6, -133.3, -90.0, 0.0)
#: The seam ends 25 mm above the plate (the nozzle body ends a radius short of its tip).
SEAM_B = (0.50, 0.12, 0.045)
SEAM_SPEED = 0.05


def robot_spec() -> RobotSpec:
    return RobotSpec(kind="urdf", urdf_path=URDF, base_link="base_link", tool_link="tool0",
                     tool=ToolSpec.straight(NOZZLE_LENGTH, NOZZLE_RADIUS, name="nozzle",
                                            has_gripper=False))


def plate_stl() -> bytes:
    size = [v * 1000 for v in PLATE]
    box = trimesh.creation.box(extents=size, transform=trimesh.transformations
                               .translation_matrix((0, 0, size[2] / 2)))
    return box.export(file_type="stl")


def make_cell(out: Path = HERE) -> Cell:
    cell = Cell(robot_spec=robot_spec(), T_world_base=np.eye(4))
    (c, s) = TABLE
    cell.add_object(CellObject.box("table", s, make_T(p=c), role=ObjectRole.FIXTURE))
    cad = out / "cad"
    cad.mkdir(parents=True, exist_ok=True)
    data = plate_stl()
    (cad / "plate.stl").write_bytes(data)
    cell.add_object(CellObject.from_cad("plate", load_cad(data, "plate.stl", units="mm"),
                                        make_T(p=PLATE_AT), role=ObjectRole.WORKPIECE))
    (c, s) = CLAMP
    cell.add_object(CellObject.box("clamp", s, make_T(p=c)))
    (c, r, h) = POST
    cell.add_object(CellObject.cylinder("post", r, h, make_T(p=c)))
    return cell


def _taught(name: str, q_deg: tuple[float, ...]) -> Location:
    """A location taught from the robot pose."""
    from assistant.session.types import sample_robot_spec

    robot = sample_robot_spec(robot_spec(), HERE).build()
    q = np.radians(np.array(q_deg))
    return Location(name, stored_pose(robot.fk(q)), LocationSource.ROBOT_POSE, q)


def make_mission() -> ResolvedMission:
    a = _taught("SEAM_A", SEAM_A_Q_DEG)
    seam = ApplicationPath(
        "SEAM", [PathSegment(SegmentKind.LINE, (a.position.copy(), np.array(SEAM_B)))],
        a.T_world_tool[:3, :3].copy(), [ToolAction(ToolActionKind.OUTPUT, 1, True)],
        [ToolAction(ToolActionKind.OUTPUT, 1, False)], SEAM_SPEED)
    return ResolvedMission(_taught("START", START_Q_DEG), _taught("GOAL", GOAL_Q_DEG), [seam])


def main(out: Path = HERE) -> None:
    out.mkdir(parents=True, exist_ok=True)
    save_cell(make_cell(out), out / "cell")
    (out / "mission.json").write_text(json.dumps(make_mission().to_json(), indent=1) + "\n")
    print(f"wrote {out / 'cell'}, cad/, mission.json")


if __name__ == "__main__":
    main(Path(sys.argv[1]).resolve() if len(sys.argv) > 1 else HERE)
