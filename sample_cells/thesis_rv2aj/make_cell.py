"""Generate the thesis sample cell (SPEC §1, source 003 §10): re-run after changing a number.

    python sample_cells/thesis_rv2aj/make_cell.py [OUT_DIR]

Writes, next to this script (or into OUT_DIR):

* ``dxf/O1.dxf``, ``dxf/O2.dxf`` - the two known obstacles as DXF drawings of 3-D faces in
  millimetres (the thesis imported O1 and O2 from DXF); each drawing's origin is the middle of
  the part's footprint on the table, so the cell places it by a translation.
* ``dxf/cell_layout.dxf`` - the same two parts as one cell-layout drawing: each on its own
  layer where it stands, with the start P1 and goal P10 labelled on a LOCATIONS layer (the
  thesis' "locations stored within DXF"; `assistant.cell.cad.layout`).
* ``cell/`` - the cell saved with `save_cell`: the RV-2AJ with a 100 mm straight gripper, its
  base at the world origin on the table, the table top (z = 0) as a fixture, O1 and O2.
* ``hidden.json`` - obstacle O3, a box the planner does not know; only the simulated robot
  has it, so it is found through collision indications as in the thesis.
* ``mission.json`` - what ``session.yaml`` teaches before it plans: start P1 and goal P10
  from the layout drawing, P7 and P8 by the simulated marker pointer, the application line
  SEAM from P7 to P8 (tool pointing down, gripper closed before the line and opened after
  it). The served sample starts with it, so the page's program is the script's.

Layout (world = robot base frame, metres): P1 on the robot's right (-y), P10 on its left (+y),
O1 and O2 between them and the application line in front (+x). O3 stands across the arc the
planner takes from P8 to P10 when it does not know O3, and leaves room to pass inside it.
Everything stays inside the RV-2AJ's reach with the tool (flange ~0.41 m + 0.1 m tool).
"""

from __future__ import annotations

import json
import sys
from collections import OrderedDict
from pathlib import Path

import ezdxf
import numpy as np

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

#: Tool pointing straight down (approach = -z), the usual pose over a table.
R_DOWN = np.diag([1.0, -1.0, -1.0])

#: Known obstacles: name -> (footprint centre x, y; size x, y, z), metres; they stand on z = 0.
KNOWN = {
    "O1": ((0.22, -0.20), (0.10, 0.10, 0.22)),
    "O2": ((0.22, 0.20), (0.10, 0.10, 0.22)),
}
#: Hidden obstacle O3: centre and size (metres).
HIDDEN_O3 = ((0.37, 0.22, 0.10), (0.06, 0.05, 0.20))
#: Table top: the robot stands on it; its top face is z = 0.
TABLE = ((0.0, 0.0, -0.01), (1.2, 1.2, 0.02))

#: Taught locations (world frame, tool pointing down).
P1 = (0.08, -0.34, 0.20)
P7 = (0.34, -0.07, 0.06)
P8 = (0.34, 0.07, 0.06)
P10 = (0.08, 0.34, 0.20)


def box_faces(size_xyz: tuple[float, float, float],
              at_mm: tuple[float, float] = (0.0, 0.0)) -> list[list[tuple[float, ...]]]:
    """The six faces of a closed box in millimetres, its bottom face centred at `at_mm`."""
    sx, sy, sz = (1000.0 * v for v in size_xyz)
    x, y = sx / 2.0, sy / 2.0
    cx, cy = at_mm
    v = [(cx - x, cy - y, 0.0), (cx + x, cy - y, 0.0), (cx + x, cy + y, 0.0),
         (cx - x, cy + y, 0.0), (cx - x, cy - y, sz), (cx + x, cy - y, sz),
         (cx + x, cy + y, sz), (cx - x, cy + y, sz)]
    # Outward faces, counter-clockwise seen from outside.
    quads = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return [[v[i] for i in q] for q in quads]


def dxf_bytes(fill) -> bytes:
    """A millimetre R2010 drawing filled by `fill(doc)`, with the same bytes on every run."""
    # Fixed dates and GUIDs: a re-run writes the same bytes (the cell names files by hash).
    ezdxf.options.write_fixed_meta_data_for_testing = True
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 4  # millimetres
    fill(doc)
    # ezdxf collects the CLASSES section from a set: sort it so the bytes do not depend on
    # the interpreter's hash seed.
    classes = doc.classes
    export = classes.export_dxf

    def export_sorted(tagwriter) -> None:
        classes.classes = OrderedDict(sorted(classes.classes.items()))
        export(tagwriter)

    classes.export_dxf = export_sorted  # type: ignore[method-assign]
    from io import StringIO

    buf = StringIO()
    doc.write(buf)
    return buf.getvalue().encode("utf-8")


def box_dxf(size_xyz: tuple[float, float, float]) -> bytes:
    """A closed box of 3DFACE entities in millimetres, origin at the bottom face's centre."""
    def fill(doc) -> None:
        for face in box_faces(size_xyz):
            doc.modelspace().add_3dface(face)
    return dxf_bytes(fill)


def layout_dxf() -> bytes:
    """The cell-layout drawing (`assistant.cell.cad.layout`): O1 and O2 drawn where they
    stand, each on its own layer, and the start P1 and goal P10 as labels on LOCATIONS."""
    def fill(doc) -> None:
        msp = doc.modelspace()
        for name, ((x, y), size) in KNOWN.items():
            doc.layers.add(name)
            for face in box_faces(size, (1000.0 * x, 1000.0 * y)):
                msp.add_3dface(face, dxfattribs={"layer": name})
        doc.layers.add("LOCATIONS")
        for label, p in (("P1 start", P1), ("P10 goal", P10)):
            msp.add_text(label, height=10.0, dxfattribs={"layer": "LOCATIONS"}).set_placement(
                tuple(1000.0 * v for v in p))
    return dxf_bytes(fill)


def make_cell(out: Path = HERE) -> Cell:
    spec = RobotSpec(kind="rv2aj", tool=ToolSpec.straight(0.1))
    cell = Cell(robot_spec=spec, T_world_base=np.eye(4))
    (c, s) = TABLE
    cell.add_object(CellObject.box("table", s, make_T(p=c), role=ObjectRole.FIXTURE))
    dxf_dir = out / "dxf"
    dxf_dir.mkdir(parents=True, exist_ok=True)
    for name, ((x, y), size) in KNOWN.items():
        data = box_dxf(size)
        (dxf_dir / f"{name}.dxf").write_bytes(data)
        cad = load_cad(data, f"{name}.dxf")
        cell.add_object(CellObject.from_cad(name, cad, make_T(p=(x, y, 0.0)),
                                            role=ObjectRole.OBSTACLE))
    (dxf_dir / "cell_layout.dxf").write_bytes(layout_dxf())
    return cell


def make_mission() -> ResolvedMission:
    line = ApplicationPath(
        "P7-P8", [PathSegment(SegmentKind.LINE, (np.array(P7), np.array(P8)))],
        R_world_tool=R_DOWN,
        actions_before=[ToolAction(ToolActionKind.GRIPPER_CLOSE, 1)],
        actions_after=[ToolAction(ToolActionKind.GRIPPER_OPEN, 1)],
        speed=0.05)
    return ResolvedMission(Location("P1", make_T(R_DOWN, P1)), Location("P10", make_T(R_DOWN, P10)),
                           [line])


def hidden_json() -> dict:
    (c, s) = HIDDEN_O3
    return {"schema_version": 1,
            "note": "obstacles only the simulated robot knows (metres, world frame)",
            "obstacles": [{"name": "O3", "kind": "box", "size": list(s),
                           "T_world_object": make_T(p=c).tolist()}]}


def mission_from_script() -> dict:
    """The mission and locations `session.yaml` teaches (P1/P10 from the layout drawing, P7/P8
    by the simulated marker pointer, the SEAM line), as the served sample starts with them:
    the page's program is then the script's, byte for byte."""
    from assistant.session import Session
    from assistant.session.script import parse_script, run_action

    script = parse_script(HERE / "session.yaml")
    s = Session.from_sample(HERE, None, with_objects=script.with_objects,
                            with_mission=script.with_mission)
    for action in script.actions:
        if action.verb == "build_world":
            break
        run_action(s, action, script.path.parent, script.path)
    doc = s.teaching.resolved_mission().to_json()  # the file holds start and goal whole
    named = {n for n in (s.mission.start, s.mission.goal) if n is not None}
    doc["locations"] = [loc.to_json() for name, loc in s.locations.items() if name not in named]
    return _rounded(doc)


def _rounded(doc: object) -> object:
    """Every float to 1e-9 (m, rad): the pointer's measurement may differ in its last bits
    between processors (OpenCV's and numpy's SIMD forms), the file must not."""
    if isinstance(doc, float):
        return round(doc, 9) + 0.0  # + 0.0: no "-0.0"
    if isinstance(doc, dict):
        return {k: _rounded(v) for k, v in doc.items()}
    if isinstance(doc, list):
        return [_rounded(v) for v in doc]
    return doc


def main(out: Path = HERE) -> None:
    out.mkdir(parents=True, exist_ok=True)
    save_cell(make_cell(out), out / "cell")
    (out / "hidden.json").write_text(json.dumps(hidden_json(), indent=1) + "\n")
    (out / "mission.json").write_text(json.dumps(mission_from_script(), indent=1) + "\n")
    print(f"wrote {out / 'cell'}, hidden.json, mission.json")


if __name__ == "__main__":
    main(Path(sys.argv[1]).resolve() if len(sys.argv) > 1 else HERE)
