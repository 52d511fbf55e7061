"""CAD import of DXF (3-D faces, polyface/polymesh, outlines extruded) and STEP (units from
the file, curved surfaces tessellated), read through ezdxf and cascadio."""

from __future__ import annotations

import io
import itertools

import ezdxf
import numpy as np
import pytest
import trimesh
from cad_builders import DATA, _assert_box_m, _box_mm, _dxf, step_boxes, step_cylinder

from assistant.cell.cad import CadImportError, load_cad, load_cad_path

# -- DXF -------------------------------------------------------------------------------------------


def _faces_of(mesh: trimesh.Trimesh):
    return [list(map(tuple, tri)) for tri in mesh.triangles]


@pytest.mark.parametrize(("insunits", "units", "source", "factor"),
                         [(4, "mm", "file", 0.001), (1, "inch", "file", 0.0254),
                          (6, "m", "file", 1.0), (0, "mm", "size", 0.001)])
def test_dxf_3dfaces_with_insunits(insunits, units, source, factor):
    def build(doc, msp):
        for tri in _faces_of(_box_mm()):
            msp.add_3dface(tri)

    result = load_cad(_dxf(build, insunits), "box.dxf")
    assert (result.units, result.units_source) == (units, source)
    _assert_box_m(result, np.array([40.0, 30.0, 20.0]) * factor)


def test_dxf_polyface_polymesh_and_mesh_entities_and_blocks():
    box = trimesh.creation.box(extents=(10.0, 10.0, 10.0))

    def build(doc, msp):
        pf = msp.add_polyface()
        for tri in _faces_of(box):
            pf.append_face(tri)
        mesh = msp.add_mesh()
        with mesh.edit_data() as md:
            md.vertices = [tuple(v + (30.0, 0.0, 0.0)) for v in box.vertices]
            md.faces = [tuple(f) for f in box.faces]
        block = doc.blocks.new("CUBE")
        for tri in _faces_of(box):
            block.add_3dface(tri)
        msp.add_blockref("CUBE", (60.0, 0.0, 0.0))
        msp.add_blockref("CUBE", (90.0, 0.0, 0.0), dxfattribs={"rotation": 45})
        grid = msp.add_polymesh((2, 2))  # a flat 10 x 10 quad, far below the cubes
        for i, j in itertools.product((0, 1), repeat=2):
            grid.set_mesh_vertex((i, j), (10.0 * i, 10.0 * j, -100.0))

    result = load_cad(_dxf(build), "cubes.dxf")
    m = result.mesh
    assert len(m.split(only_watertight=False)) == 5
    s = np.sqrt(2.0) * 0.005  # the rotated cube reaches this far from its centre in x and y
    np.testing.assert_allclose(m.bounds, [[-0.005, -s, -0.1], [0.09 + s, 0.01, 0.005]], atol=1e-9)
    assert m.area == pytest.approx(4 * 6 * 1e-4 + 1e-4, rel=1e-9)


def test_binary_dxf_is_read_and_a_truncated_one_refused():
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 4
    for tri in _faces_of(_box_mm()):
        doc.modelspace().add_3dface(tri)
    stream = io.BytesIO()
    doc.write(stream, fmt="bin")
    data = stream.getvalue()
    assert data.startswith(b"AutoCAD Binary DXF")
    _assert_box_m(load_cad(data, "binary.dxf"), (0.04, 0.03, 0.02))
    with pytest.raises(CadImportError, match=r"cut\.dxf.*could not be read as DXF"):
        load_cad(data[:300], "cut.dxf")


def test_dxf_outline_needs_a_height():
    def build(doc, msp):
        msp.add_lwpolyline([(0, 0), (100, 0), (100, 50), (0, 50)], close=True)

    with pytest.raises(CadImportError, match=r"plate\.dxf.*2-D drawing.*dxf_extrude_height"):
        load_cad(_dxf(build), "plate.dxf")


def test_dxf_outline_with_hole_and_island_is_extruded():
    def build(doc, msp):
        msp.add_lwpolyline([(0, 0), (100, 0), (100, 50), (0, 50)], close=True)
        msp.add_circle((30, 25), 15)  # a hole ...
        msp.add_circle((30, 25), 5)  # ... with an island in it
        msp.add_lwpolyline([(60, 10), (90, 10), (90, 40), (60, 40)], close=True)  # a pocket

    result = load_cad(_dxf(build), "plate.dxf", dxf_extrude_height=0.008)
    area_mm2 = 100 * 50 - np.pi * 15**2 + np.pi * 5**2 - 30 * 30
    assert result.mesh.is_watertight
    assert result.mesh.volume == pytest.approx(area_mm2 * 8 * 1e-9, rel=2e-3)
    np.testing.assert_allclose(result.mesh.extents, (0.1, 0.05, 0.008), rtol=1e-6)
    assert len(result.mesh.split()) == 2  # the plate and the island


def test_dxf_outline_from_lines_and_arcs_in_size_units():
    def build(doc, msp):
        msp.add_line((0, 0), (100, 0))
        msp.add_arc((100, 25), 25, -90, 90)
        msp.add_line((100, 50), (0, 50))
        msp.add_line((0, 50), (0, 0))
        msp.add_line((200, 0), (300, 0))  # a stray open line: ignored with a warning

    result = load_cad(_dxf(build, insunits=0), "tab.dxf", dxf_extrude_height=0.01)
    assert (result.units, result.units_source) == ("mm", "size")
    area_mm2 = 100 * 50 + np.pi * 25**2 / 2
    assert result.mesh.volume == pytest.approx(area_mm2 * 10 * 1e-9, rel=2e-3)
    assert any("open line" in w for w in result.warnings)


def test_dxf_with_only_open_lines_is_refused():
    def build(doc, msp):
        msp.add_line((0, 0), (100, 0))
        msp.add_line((100, 0), (100, 50))

    with pytest.raises(CadImportError, match=r"lines\.dxf.*only open lines.*close"):
        load_cad(_dxf(build), "lines.dxf", dxf_extrude_height=0.01)


def test_dxf_outline_height_must_be_positive():
    def build(doc, msp):
        msp.add_circle((0, 0), 10)

    with pytest.raises(CadImportError, match="dxf_extrude_height must be a positive"):
        load_cad(_dxf(build), "disc.dxf", dxf_extrude_height=-0.01)


# -- STEP --------------------------------------------------------------------------------------


@pytest.mark.parametrize(("unit", "factor"), [("mm", 0.001), ("m", 1.0), ("inch", 0.0254),
                                              ("cm", 0.01)])
def test_step_unit_comes_from_the_file(unit, factor):
    data = step_boxes([((0, 0, 0), (40, 30, 20)), ((100, 0, 0), (110, 10, 10))], unit)
    result = load_cad(data, "two_blocks.step")
    assert (result.units, result.units_source, result.file_units) == (unit, "file", unit)
    np.testing.assert_allclose(result.mesh.bounds, np.array([[0, 0, 0], [110, 30, 20]]) * factor,
                               rtol=1e-6, atol=1e-9)
    assert result.mesh.volume == pytest.approx((40 * 30 * 20 + 1000) * factor**3, rel=1e-5)
    assert result.mesh.is_watertight


def test_step_unit_override_rescales_from_the_declared_unit():
    data = step_boxes([((0, 0, 0), (40, 30, 20))], "mm")
    result = load_cad(data, "block.stp", units="inch")  # "those numbers are really inches"
    assert (result.units, result.units_source, result.file_units) == ("inch", "caller", "mm")
    np.testing.assert_allclose(result.mesh.extents, np.array([40, 30, 20]) * 0.0254, rtol=1e-6)


def test_step_cylinder_curved_surfaces_are_tessellated_within_tolerance():
    result = load_cad(step_cylinder(20.0, 50.0, "mm"), "pin.step")
    m = result.mesh
    assert m.is_watertight
    np.testing.assert_allclose(m.extents, (0.04, 0.04, 0.05), atol=2e-4)
    assert m.volume == pytest.approx(np.pi * 0.02**2 * 0.05, rel=0.01)
    radial = np.linalg.norm(m.vertices[:, :2], axis=1)
    on_side = radial > 0.019
    assert np.abs(radial[on_side] - 0.02).max() < 1e-6  # vertices lie on the true surface


def test_committed_step_fixture_imports():
    result = load_cad_path(DATA / "two_blocks_mm.step")
    assert (result.units, result.units_source) == ("mm", "file")
    assert result.mesh.is_watertight
    assert result.mesh.volume == pytest.approx((80 * 50 * 10 + 10 * 50 * 40) * 1e-9, rel=1e-5)
    np.testing.assert_allclose(result.mesh.bounds, [[0, 0, 0], [0.08, 0.05, 0.06]], atol=1e-7)


# -- repairs --------------------------------------------------------------------------------------


