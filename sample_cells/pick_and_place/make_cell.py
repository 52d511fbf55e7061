"""Generate the pick-and-place sample cell: re-run after changing a number.

    python sample_cells/pick_and_place/make_cell.py [OUT_DIR]

The RV-2AJ with a 100 mm two-finger gripper takes three blocks off a conveyor and puts each
into its pocket of a fixture. Each pick/place pair is one application path: the gripper
closes at the block, lifts it (depart line), carries it over to its pocket (line) and lowers
it in (approach line), then opens; the mission planner orders the three pairs and plans the
transfers between them around the conveyor rails and the light-barrier post.

Writes, next to this script (or into OUT_DIR):

* ``cad/conveyor.stl`` - belt and two side rails (mm, origin: middle of the belt's footprint).
* ``cad/fixture.stl`` - a plate with four walls forming three pockets (mm, origin: middle
  of the plate's footprint).
* ``cell/`` - the cell saved with `save_cell`: the RV-2AJ with the gripper, its base at the
  world origin on the table (top z = 0), the conveyor, the fixture, the post and the three
  30 mm blocks (workpieces) on the belt.
* ``mission.json`` - START (right), GOAL (left), pairs PP1..PP3.

World = robot base frame, metres; tool pointing down (A, B, C = 0, 0, 180 deg).
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
    PathSegment,
    ResolvedMission,
    SegmentKind,
)
from assistant.mission.motion import ToolAction, ToolActionKind  # noqa: E402
from assistant.robots.catalog import RobotSpec, ToolSpec  # noqa: E402
from assistant.transforms import make_T  # noqa: E402

#: Tool pointing straight down.
R_DOWN = np.diag([1.0, -1.0, -1.0])
GRIPPER_LENGTH, GRIPPER_RADIUS = 0.100, 0.020

TABLE = ((0.0, 0.0, -0.01), (1.2, 1.2, 0.02))
#: Conveyor along y in front of the robot: footprint middle, belt size (x, y, z), rails.
CONVEYOR_AT = (0.33, -0.12, 0.0)
BELT = (0.12, 0.36, 0.04)
RAIL_WIDTH, RAIL_HEIGHT = 0.010, 0.025
#: Fixture on the table, nearer the robot and to its left; plate and pocket walls.
FIXTURE_AT = (0.20, 0.20, 0.0)
PLATE = (0.10, 0.20, 0.020)
WALL_WIDTH, WALL_HEIGHT = 0.010, 0.020
POCKET_PITCH = 0.063
#: Light-barrier post at the conveyor's near end (an obstacle for the transfers).
POST = ((0.22, -0.28, 0.13), 0.015, 0.26)  # centre, radius, height
#: The blocks: 30 mm cubes on the belt.
BLOCK = 0.030
BLOCK_Y = (-0.16, -0.09, -0.02)
#: Heights: carry above the rails, depart/approach lines 60-70 mm long.
CARRY_Z = 0.11
START = (0.10, -0.32, 0.20)
GOAL = (0.10, 0.32, 0.20)
SPEED = 0.10


def _box_mm(size: tuple, centre: tuple) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=[v * 1000 for v in size],
                                transform=trimesh.transformations.translation_matrix(
                                    [v * 1000 for v in centre]))


def conveyor_stl() -> bytes:
    bx, by, bz = BELT
    parts = [_box_mm(BELT, (0, 0, bz / 2))]
    for s in (-1, 1):
        parts.append(_box_mm((RAIL_WIDTH, by, RAIL_HEIGHT),
                             (s * (bx + RAIL_WIDTH) / 2, 0, bz + RAIL_HEIGHT / 2)))
    return trimesh.util.concatenate(parts).export(file_type="stl")


def fixture_stl() -> bytes:
    px, py, pz = PLATE
    parts = [_box_mm(PLATE, (0, 0, pz / 2))]
    for k in range(4):
        y = (k - 1.5) * POCKET_PITCH
        parts.append(_box_mm((px, WALL_WIDTH, WALL_HEIGHT), (0, y, pz + WALL_HEIGHT / 2)))
    return trimesh.util.concatenate(parts).export(file_type="stl")


def pick_points() -> list[np.ndarray]:
    """TCP at the middle of each block's top face."""
    x, y0, _ = CONVEYOR_AT
    return [np.array([x, y, BELT[2] + BLOCK]) for y in BLOCK_Y]


def place_points() -> list[np.ndarray]:
    """TCP where a block's top face is when it sits in its pocket (pocket k for block k)."""
    x, y0, _ = FIXTURE_AT
    return [np.array([x, y0 + (k - 1) * POCKET_PITCH, PLATE[2] + BLOCK]) for k in range(3)]


def pair_path(k: int) -> ApplicationPath:
    """Block k: close, lift, carry, lower, open."""
    pick, place = pick_points()[k], place_points()[k]
    pts = [pick, np.r_[pick[:2], CARRY_Z], np.r_[place[:2], CARRY_Z], place]
    segs = [PathSegment(SegmentKind.LINE, (a, b)) for a, b in zip(pts[:-1], pts[1:],
                                                                   strict=True)]
    grip = [ToolAction(ToolActionKind.GRIPPER_CLOSE, 1), ToolAction(ToolActionKind.WAIT,
                                                                     seconds=0.3)]
    release = [ToolAction(ToolActionKind.GRIPPER_OPEN, 1), ToolAction(ToolActionKind.WAIT,
                                                                       seconds=0.3)]
    return ApplicationPath(f"PP{k + 1}", segs, R_DOWN, grip, release, SPEED)


def make_cell(out: Path = HERE) -> Cell:
    spec = RobotSpec(kind="rv2aj", tool=ToolSpec.straight(GRIPPER_LENGTH, GRIPPER_RADIUS))
    cell = Cell(robot_spec=spec, T_world_base=np.eye(4))
    (c, s) = TABLE
    cell.add_object(CellObject.box("table", s, make_T(p=c), role=ObjectRole.FIXTURE))
    cad = out / "cad"
    cad.mkdir(parents=True, exist_ok=True)
    for name, data, at in (("conveyor", conveyor_stl(), CONVEYOR_AT),
                           ("fixture", fixture_stl(), FIXTURE_AT)):
        (cad / f"{name}.stl").write_bytes(data)
        cell.add_object(CellObject.from_cad(name, load_cad(data, f"{name}.stl", units="mm"),
                                            make_T(p=at), role=ObjectRole.FIXTURE))
    (c, r, h) = POST
    cell.add_object(CellObject.cylinder("post", r, h, make_T(p=c)))
    for k, p in enumerate(pick_points()):
        cell.add_object(CellObject.box(f"block{k + 1}", (BLOCK,) * 3,
                                       make_T(p=(p[0], p[1], p[2] - BLOCK / 2)),
                                       role=ObjectRole.WORKPIECE))
    return cell


def make_mission() -> ResolvedMission:
    return ResolvedMission(Location("START", make_T(R_DOWN, START)),
                           Location("GOAL", make_T(R_DOWN, GOAL)),
                           [pair_path(k) for k in range(3)])


def main(out: Path = HERE) -> None:
    out.mkdir(parents=True, exist_ok=True)
    save_cell(make_cell(out), out / "cell")
    (out / "mission.json").write_text(json.dumps(make_mission().to_json(), indent=1) + "\n")
    mm = lambda p: "(" + ", ".join(f"{v * 1000:.0f}" for v in p) + ")"  # noqa: E731
    print(f"wrote {out / 'cell'}, cad/, mission.json; picks "
          + " ".join(mm(p) for p in pick_points()) + "; places "
          + " ".join(mm(p) for p in place_points()))


if __name__ == "__main__":
    main(Path(sys.argv[1]).resolve() if len(sys.argv) > 1 else HERE)
