"""Generate the Bezier drawing sample cell (source 000): re-run after changing a number.

    python sample_cells/bezier_drawing/make_cell.py [OUT_DIR]

The source's cell (FASTory workstation 3): a KUKA KR3 R540 draws the parts of a mobile phone
(frame, screen, keyboard) with a pen on paper lying on a pallet that the conveyor brings in.
The pallet is never exactly level, so its base frame is calibrated with the 3-point method
(origin, a point on +x, a point in the XY plane), the pen touching the paper each time.

Writes, next to this script (or into OUT_DIR):

* ``kr3r540.urdf`` - a KR3 R540-like arm: KUKA's axis conventions (A1 about -z, A2/A3/A5
  about +y, A4/A6 about -x; all zero = arm stretched forward, the KRC's HOME is
  (0, -90, 90, 0, 0, 0)), public dimensions (A2 345 mm above the floor and 20 mm forward, 260 mm
  upper arm, A4 20 mm above A3, 260 mm forearm, 75 mm A5 to flange), datasheet joint limits
  and speeds, cylinders and boxes as geometry. The flange frame has z out of the flange.
* ``cad/pallet.stl``, ``cad/pen_holder.stl`` - the pallet (plate with a rim) and the pen
  holder (block with three pens), millimetres, origin at the middle of their footprint.
* ``cell/`` - the cell saved with `save_cell`: the KR3 with a 140 mm pen, its base at the world
  origin on the robot stand (top z = 0), the conveyor, the pallet where it really lies
  (slightly tilted), the pen holder, and the frame ``PALLET`` as the calibration finds it.
* ``mission.json`` - HOME as start and goal, the phone's frame (drawing 1), screen (8) and
  keyboard (4) as pen paths on ``PALLET``.

The session script (`session.yaml`) does it as the operator would: imports the parts, touches
three paper corners with the pen (jog + teach from the robot pose), calibrates ``PALLET``,
places the pallet on it, adds the drawings, plans and writes KRL with SPLINE blocks.
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
from assistant.mission.model import Location, LocationSource, ResolvedMission  # noqa: E402
from assistant.robots.catalog import RobotSpec, ToolSpec  # noqa: E402
from assistant.session.frames import _drawing_control, drawing_path  # noqa: E402
from assistant.transforms import make_T, pose_from_mm_deg, stored_pose  # noqa: E402

URDF_NAME = "kr3r540.urdf"

# ------------------------------------------------------------------ the robot (metres, degrees)
#: A2 above the floor, A2 in front of A1, upper arm, A4 above A3, forearm, A5 to flange.
BASE_HEIGHT, SHOULDER_OFFSET, UPPER_ARM = 0.345, 0.020, 0.260
ELBOW_OFFSET, FOREARM, FLANGE = 0.020, 0.260, 0.075
#: KR3 R540 datasheet: axis ranges (deg) and speeds (deg/s).
DATASHEET_LIMITS_DEG = ((-170.0, 170.0), (-170.0, 50.0), (-110.0, 155.0), (-175.0, 175.0),
                        (-120.0, 120.0), (-350.0, 350.0))
SPEEDS_DEG_S = (430.0, 430.0, 430.0, 500.0, 500.0, 850.0)
#: The ranges the cell uses (software limits): the arm works in front of itself over the
#: pallet, elbow up, pen down. They keep the reachability table small (about 4.6 M joint
#: positions); the datasheet ranges would give ~570 M.
CELL_LIMITS_DEG = ((-60.0, 60.0), (-120.0, 0.0), (30.0, 150.0), (-30.0, 30.0),
                   (0.0, 110.0), (-350.0, 350.0))
#: The pen in the gripper: TCP 140 mm out of the flange, body radius 12 mm.
PEN_LENGTH, PEN_RADIUS = 0.140, 0.012

# ------------------------------------------------------------------ the cell (metres, degrees)
#: Robot stand (its top is z = 0, the robot's base plate on it) and the conveyor in front.
STAND = ((-0.05, 0.0, -0.30), (0.40, 0.40, 0.60))
CONVEYOR = ((0.40, 0.0, -0.08), (0.34, 1.20, 0.10))
#: Pallet: 300 x 300 x 20 mm plate with an 8 mm rim, 10 mm wide; the paper is its top.
PALLET_SIZE, PALLET_THICK, RIM_HEIGHT, RIM_WIDTH = 0.30, 0.020, 0.008, 0.010
#: Where the pallet really lies: x, y, z of its footprint middle (mm) and A, B, C (deg) -
#: not level (source 000: "the surface of the pallet is not entirely aligned with the XY
#: plane of the robot").
PALLET_TRUE_MM_DEG = (382.0, 4.0, -30.0, 1.5, 0.8, -1.2)
#: Nominal place the operator imports it at before calibrating (on the conveyor, level).
PALLET_NOMINAL_MM_DEG = (380.0, 0.0, -30.0, 0.0, 0.0, 0.0)
#: Pen holder: block and three pens; it stands on the stand, right of the robot.
PEN_HOLDER_MM_DEG = (60.0, -150.0, 0.0, 0.0, 0.0, 0.0)
#: The calibration points on the paper, in the pallet frame (mm): origin at the paper's
#: lower-left corner, a point 200 mm along x, a point 200 mm along y.
PAPER_ORIGIN_MM = (-120.0, -120.0)
CALIBRATION_POINTS_MM = ((0.0, 0.0), (200.0, 0.0), (0.0, 200.0))
#: HOME: pen down over the pallet at (300, 0, 250) mm, A6 near 0 (joints, deg), taught from
#: the robot pose. The drawings turn the pen half a turn about itself so that A6 stays near
#: 0 too (the pen draws alike).
HOME_Q_DEG = (0.0, -77.5154, 112.7979, 0.0, 54.7175, 0.0)
PEN_TURN = np.pi
#: The drawings (source 000's numbering) and where their origin goes on the paper (mm).
DRAWINGS = (("FRAME1", 1, (120.0, 120.0)), ("SCREEN8", 8, (120.0, 120.0)),
            ("KEYS4", 4, (120.0, 120.0)))
PEN_LIFT, DRAW_SPEED = 0.040, 0.10


# ------------------------------------------------------------------ URDF
def _cyl(r: float, length: float, xyz: tuple, rpy: tuple = (0.0, 0.0, 0.0)) -> str:
    return _geom(f'<cylinder radius="{r:g}" length="{length:g}"/>', xyz, rpy)


def _box(size: tuple, xyz: tuple, rpy: tuple = (0.0, 0.0, 0.0)) -> str:
    return _geom(f'<box size="{" ".join(f"{v:g}" for v in size)}"/>', xyz, rpy)


def _geom(shape: str, xyz: tuple, rpy: tuple) -> str:
    o = (f'<origin xyz="{" ".join(f"{v:g}" for v in xyz)}" '
         f'rpy="{" ".join(f"{v:.10g}" for v in rpy)}"/>')
    return (f"    <visual>{o}<geometry>{shape}</geometry><material name=\"kuka\"/></visual>\n"
            f"    <collision>{o}<geometry>{shape}</geometry></collision>\n")


def kr3_urdf() -> str:
    """The KR3 R540-like arm as URDF text (see the module docstring)."""
    h = np.pi / 2
    links = {
        "base_link": _box((0.18, 0.18, 0.16), (0.0, 0.0, 0.08)),
        "link_1": _cyl(0.075, 0.16, (0.0, 0.0, -0.09)),
        # The upper arm is a side link (the forearm folds past it, A3 up to +155 deg).
        "link_2": _box((0.24, 0.04, 0.08), (UPPER_ARM / 2, -0.065, 0.0)),
        "link_3": _box((0.12, 0.10, 0.10), (0.02, 0.0, 0.01)),
        "link_4": _cyl(0.035, 0.18, (0.14, 0.0, 0.0), (0.0, h, 0.0)),
        "link_5": _cyl(0.035, 0.08, (0.0, 0.0, 0.0), (h, 0.0, 0.0)),
        "link_6": _cyl(0.03, 0.02, (FLANGE - 0.01, 0.0, 0.0), (0.0, h, 0.0)),
    }
    joints = [  # name, parent, child, xyz, axis
        ("joint_a1", "base_link", "link_1", (0.0, 0.0, BASE_HEIGHT), (0, 0, -1)),
        ("joint_a2", "link_1", "link_2", (SHOULDER_OFFSET, 0.0, 0.0), (0, 1, 0)),
        ("joint_a3", "link_2", "link_3", (UPPER_ARM, 0.0, 0.0), (0, 1, 0)),
        ("joint_a4", "link_3", "link_4", (0.0, 0.0, ELBOW_OFFSET), (-1, 0, 0)),
        ("joint_a5", "link_4", "link_5", (FOREARM, 0.0, 0.0), (0, 1, 0)),
        ("joint_a6", "link_5", "link_6", (FLANGE, 0.0, 0.0), (-1, 0, 0)),
    ]
    out = ['<?xml version="1.0"?>',
           "<!-- KUKA KR3 R540-like arm for the cellteach bezier_drawing sample: public",
           "     dimensions, datasheet limits, simple geometry. Generated by make_cell.py. -->",
           '<robot name="kr3r540">',
           '  <material name="kuka"><color rgba="1.0 0.4 0.0 1.0"/></material>']
    for name, body in links.items():
        out.append(f'  <link name="{name}">\n{body}  </link>')
    out.append('  <link name="flange"/>')
    for (name, parent, child, xyz, axis), (lo, hi), v in zip(joints, DATASHEET_LIMITS_DEG,
                                                              SPEEDS_DEG_S, strict=True):
        out.append(
            f'  <joint name="{name}" type="revolute"><parent link="{parent}"/>'
            f'<child link="{child}"/>\n'
            f'    <origin xyz="{" ".join(f"{c:g}" for c in xyz)}" rpy="0 0 0"/>'
            f'<axis xyz="{" ".join(str(a) for a in axis)}"/>\n'
            f'    <limit lower="{np.radians(lo):.6f}" upper="{np.radians(hi):.6f}" '
            f'effort="0" velocity="{np.radians(v):.6f}"/></joint>')
    out.append(f'  <joint name="joint_a6_flange" type="fixed"><parent link="link_6"/>'
               f'<child link="flange"/>\n    <origin xyz="0 0 0" rpy="0 {h:.10g} 0"/></joint>')
    out.append("</robot>")
    return "\n".join(out) + "\n"


def robot_spec() -> RobotSpec:
    """The KR3 with the pen; the URDF path is relative to the sample folder."""
    return RobotSpec(kind="urdf", urdf_path=URDF_NAME, base_link="base_link", tool_link="flange",
                     tool=ToolSpec.straight(PEN_LENGTH, PEN_RADIUS, name="pen",
                                            has_gripper=False),
                     limits_deg=CELL_LIMITS_DEG)


# ------------------------------------------------------------------ CAD
def _stl(parts: list[trimesh.Trimesh]) -> bytes:
    mesh = trimesh.util.concatenate(parts)
    return mesh.export(file_type="stl")


def _box_mm(size: tuple, centre: tuple) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=size, transform=trimesh.transformations
                                .translation_matrix(centre))


def pallet_stl() -> bytes:
    """Plate and rim in mm; origin at the middle of the bottom face, paper = plate top."""
    s, t = PALLET_SIZE * 1000, PALLET_THICK * 1000
    rh, rw = RIM_HEIGHT * 1000, RIM_WIDTH * 1000
    parts = [_box_mm((s, s, t), (0, 0, t / 2))]
    for sign in (-1, 1):
        parts.append(_box_mm((s, rw, rh), (0, sign * (s - rw) / 2, t + rh / 2)))
        parts.append(_box_mm((rw, s - 2 * rw, rh), (sign * (s - rw) / 2, 0, t + rh / 2)))
    return _stl(parts)


def pen_holder_stl() -> bytes:
    """A 90 x 60 x 50 mm block with three pens (r 6 mm) standing 70 mm out of it."""
    parts = [_box_mm((90, 60, 50), (0, 0, 25))]
    for x in (-30, 0, 30):
        pen = trimesh.creation.cylinder(radius=6.0, height=90.0, sections=24)
        pen.apply_translation((x, 0, 75))
        parts.append(pen)
    return _stl(parts)


# ------------------------------------------------------------------ geometry of the truth
def T_world_pallet() -> np.ndarray:
    return pose_from_mm_deg(np.array(PALLET_TRUE_MM_DEG))


def T_pallet_paper_origin() -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (PAPER_ORIGIN_MM[0] / 1000, PAPER_ORIGIN_MM[1] / 1000, PALLET_THICK)
    return T


def T_world_paper() -> np.ndarray:
    """The PALLET frame a perfect calibration finds: paper corner, axes of the pallet."""
    return T_world_pallet() @ T_pallet_paper_origin()


def calibration_points_world() -> np.ndarray:
    """The three points the pen touches (world, metres)."""
    T = T_world_paper()
    P = np.array([[x / 1000, y / 1000, 0.0, 1.0] for x, y in CALIBRATION_POINTS_MM])
    return (P @ T.T)[:, :3]


# ------------------------------------------------------------------ cell and mission
def make_cell(out: Path = HERE) -> Cell:
    (out / URDF_NAME).write_text(kr3_urdf(), encoding="utf-8")
    cad = out / "cad"
    cad.mkdir(parents=True, exist_ok=True)
    cell = Cell(robot_spec=robot_spec(), T_world_base=np.eye(4))
    for name, (c, s) in (("stand", STAND), ("conveyor", CONVEYOR)):
        cell.add_object(CellObject.box(name, s, make_T(p=c), role=ObjectRole.FIXTURE))
    for name, data, T, role in (
            ("pallet", pallet_stl(), T_world_pallet(), ObjectRole.FIXTURE),
            ("pen_holder", pen_holder_stl(), pose_from_mm_deg(np.array(PEN_HOLDER_MM_DEG)),
             ObjectRole.OBSTACLE)):
        (cad / f"{name}.stl").write_bytes(data)
        cell.add_object(CellObject.from_cad(name, load_cad(data, f"{name}.stl", units="mm"), T,
                                            role=role))
    cell.add_frame("PALLET", T_world_paper())
    return cell


def make_mission() -> ResolvedMission:
    from assistant.session.types import sample_robot_spec

    q = np.radians(np.array(HOME_Q_DEG))
    robot = sample_robot_spec(robot_spec(), HERE).build()
    home = Location("HOME", stored_pose(robot.fk(q)), LocationSource.ROBOT_POSE, q)
    paths = [drawing_path(name, T_world_paper(), _drawing_control(number),
                          at=(x / 1000, y / 1000), lift=PEN_LIFT, speed=DRAW_SPEED,
                          tool_angle=PEN_TURN)
             for name, number, (x, y) in DRAWINGS]
    return ResolvedMission(home, home, paths)


def main(out: Path = HERE) -> None:
    out.mkdir(parents=True, exist_ok=True)
    save_cell(make_cell(out), out / "cell")
    (out / "mission.json").write_text(json.dumps(make_mission().to_json(), indent=1) + "\n")
    pts = calibration_points_world() * 1000
    print(f"wrote {out / URDF_NAME}, cad/, cell/, mission.json; calibration points (mm): "
          + "; ".join(f"({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f})" for p in pts))


if __name__ == "__main__":
    main(Path(sys.argv[1]).resolve() if len(sys.argv) > 1 else HERE)
