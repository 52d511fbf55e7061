"""A cell-layout DXF: parts per layer standing where drawn, labelled locations taught, start
and goal set - in one undoable action; bad labels are refused with the reason, losing nothing;
a saved cell re-imports each part from the layout file with its layer."""

from __future__ import annotations

import io
from pathlib import Path

import ezdxf
import numpy as np
import pytest

from assistant.cell.cad import CadImportError, load_cad
from assistant.cell.cad.layout import read_layout
from assistant.session import Session, SessionError

ROOT = Path(__file__).resolve().parents[2]
LAYOUT = ROOT / "sample_cells" / "thesis_rv2aj" / "dxf" / "cell_layout.dxf"


def drawing(labels: list[tuple[str, tuple[float, float, float]]], *, units: int = 4,
            boxes: dict[str, tuple[float, float]] | None = None, mtext: bool = False) -> bytes:
    """A layout in `units` ($INSUNITS): 100 x 100 x 200 boxes on their layers, labels."""
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = units
    msp = doc.modelspace()
    k = 1.0 if units == 4 else 0.001
    for layer, (x, y) in (boxes or {"A": (250.0, -150.0)}).items():
        doc.layers.add(layer)
        v = [(x - 50, y - 50, 0), (x + 50, y - 50, 0), (x + 50, y + 50, 0), (x - 50, y + 50, 0),
             (x - 50, y - 50, 200), (x + 50, y - 50, 200), (x + 50, y + 50, 200),
             (x - 50, y + 50, 200)]
        v = [tuple(k * c for c in p) for p in v]
        for q in ((0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6),
                  (3, 0, 4, 7)):
            msp.add_3dface([v[i] for i in q], dxfattribs={"layer": layer})
    doc.layers.add("LOCATIONS")
    for text, p in labels:
        at = tuple(k * c for c in p)
        if mtext:
            msp.add_mtext(text, dxfattribs={"layer": "LOCATIONS", "insert": at})
        else:
            msp.add_text(text, dxfattribs={"layer": "LOCATIONS"}).set_placement(at)
    buf = io.StringIO()
    doc.write(buf)
    return buf.getvalue().encode()


def test_the_thesis_layout_reads_two_parts_and_the_start_and_goal():
    layout = read_layout(LAYOUT.read_bytes(), LAYOUT.name)
    assert layout is not None
    assert layout.parts == {"O1": "O1", "O2": "O2"}
    assert [(loc.name, loc.role) for loc in layout.locations] == [("P1", "start"),
                                                                   ("P10", "goal")]
    assert layout.locations[0].xyz == pytest.approx((80.0, -340.0, 200.0))
    assert layout.locations[0].abc_deg == (0.0, 0.0, 180.0)  # tool down unless written
    # One layer of the file is one part, in cell coordinates (mm -> m by $INSUNITS).
    cad = load_cad(LAYOUT.read_bytes(), LAYOUT.name, dxf_layer="O1")
    assert cad.units == "mm"
    np.testing.assert_allclose(cad.mesh.bounds, [[0.17, -0.25, 0.0], [0.27, -0.15, 0.22]],
                               atol=1e-9)  # 1e-9 m: the box corners are exact in mm


def test_an_ordinary_drawing_is_not_a_layout():
    one_part = ROOT / "sample_cells" / "thesis_rv2aj" / "dxf" / "O1.dxf"
    assert read_layout(one_part.read_bytes(), one_part.name) is None
    assert read_layout(b"solid x\nendsolid x\n", "part.stl") is None


@pytest.mark.parametrize("label, problem", [
    ("P1 start 0 0", "cannot read the location label"),
    ("P1 sideways", "cannot read the location label"),
])
def test_bad_labels_are_refused_with_the_form_to_use(label, problem):
    data = drawing([(label, (80, -340, 200))])
    with pytest.raises(CadImportError, match=problem) as info:
        read_layout(data, "cell.dxf")
    assert "NAME [start|goal] [A B C]" in str(info.value)


def test_two_starts_or_a_name_twice_are_refused():
    with pytest.raises(CadImportError, match="all as the start"):
        read_layout(drawing([("P1 start", (80, -340, 200)), ("P2 start", (80, 340, 200))]),
                    "c.dxf")
    with pytest.raises(CadImportError, match="more than once"):
        read_layout(drawing([("P1", (80, -340, 200)), ("p1", (80, 340, 200))]), "c.dxf")


def test_the_session_imports_a_layout_in_one_undoable_action(tmp_path):
    s = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                            with_mission=False)
    s.fire("next")  # 2. import CAD
    before = (set(s.cell.objects), dict(s.locations))
    objs = s.import_layout_path(LAYOUT)
    assert [o.name for o in objs] == ["O1", "O2"]
    np.testing.assert_allclose(s.cell.objects["O1"].T_world_object, np.eye(4))  # as drawn
    assert s.mission.start == "P1" and s.mission.goal == "P10"
    np.testing.assert_allclose(s.locations["P10"].T_world_tool[:3, 3], [0.08, 0.34, 0.2],
                               atol=1e-12)  # exact mm -> m conversions
    assert s.locations["P1"].source.value == "cad_file"
    s.undo()  # one action: parts and locations go together
    assert (set(s.cell.objects), dict(s.locations)) == before
    assert s.mission.start is None


def test_a_layout_in_metres_scales_its_locations_like_its_parts(tmp_path):
    s = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                            with_mission=False)
    s.fire("next")
    data = drawing([("P3 0 0 180", (250, -150, 300))], units=6)
    s.import_layout(data, "metres.dxf")
    np.testing.assert_allclose(s.locations["P3"].T_world_tool[:3, 3], [0.25, -0.15, 0.3],
                               atol=1e-12)
    lo, hi = s.cell.objects["A"].display_mesh.bounds
    np.testing.assert_allclose([lo[2], hi[2]], [0.0, 0.2], atol=1e-12)


def test_an_unreachable_location_refuses_the_whole_layout(tmp_path):
    s = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                            with_mission=False)
    s.fire("next")
    data = drawing([("P1", (80, -340, 200)), ("FAR", (3000, 0, 200))], mtext=True)
    with pytest.raises(Exception, match="FAR"):
        s.import_layout(data, "far.dxf")
    assert "A" not in s.cell.objects and not s.locations  # nothing half-imported
    with pytest.raises(SessionError, match="not a cell layout"):
        s.import_layout(LAYOUT.with_name("O1.dxf").read_bytes(), "O1.dxf")


def test_a_saved_cell_reimports_the_layout_parts(tmp_path, monkeypatch):
    """Each part from the layout file with its layer; the drawing parsed once, on import and
    on load (ezdxf's parse counted), not once more per part."""
    from ezdxf import recover

    s = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                            with_mission=False)
    s.fire("next")
    parses: list[int] = []
    real_parse = recover.read

    def parse(stream, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        parses.append(len(stream.getvalue()))
        return real_parse(stream, *args, **kwargs)

    monkeypatch.setattr(recover, "read", parse)
    s.import_layout_path(LAYOUT)
    assert parses == [LAYOUT.stat().st_size]
    s.save(tmp_path / "saved")
    parses.clear()
    again = Session.load(tmp_path / "saved", autosave=False)
    assert parses == [LAYOUT.stat().st_size]
    for name in ("O1", "O2"):
        np.testing.assert_allclose(again.cell.objects[name].display_mesh.bounds,
                                   s.cell.objects[name].display_mesh.bounds, atol=1e-12)
        assert again.cell.objects[name].source.options["dxf_layer"] == name


def test_the_same_layout_again_replaces_its_parts_another_adds_beside(tmp_path):
    s = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                            with_mission=False)
    s.fire("next")
    s.import_layout_path(LAYOUT)
    s.import_layout_path(LAYOUT)  # updated in CAD and imported again
    assert sorted(s.cell.objects) == ["O1", "O2"]
    s.import_layout(LAYOUT.read_bytes(), "other_layout.dxf")  # another drawing, same layers
    assert sorted(s.cell.objects) == ["O1", "O1_2", "O2", "O2_2"]
