"""CAD import: every format, units (file / size / caller), repairs, bad files, collision proxies.

Test files are generated here with trimesh and ezdxf; STEP files are written as STEP text (a
B-rep of boxes or a cylinder) and read through the real cascadio/OpenCASCADE path. One STEP
file is committed under tests/data/cad as a fixed real-world-style input.
"""

from __future__ import annotations

import io
import itertools
import json
import zipfile
from pathlib import Path

import ezdxf
import numpy as np
import pytest
import trimesh
from trimesh.exchange.gltf import export_gltf

from assistant.cell.cad import CadImportError, load_cad, load_cad_path
from assistant.robots.model import ShapeKind

DATA = Path(__file__).parent / "data" / "cad"


# -- STEP text writers (tiny valid AP214 B-reps) ------------------------------------------------


class _Step:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def add(self, s: str) -> str:
        self.lines.append(f"#{len(self.lines) + 1}={s};")
        return f"#{len(self.lines)}"

    def pt(self, p) -> str:
        x, y, z = (float(v) for v in p)
        return self.add(f"CARTESIAN_POINT('',({x!r},{y!r},{z!r}))")

    def dir(self, d) -> str:
        x, y, z = (float(v) for v in d)
        return self.add(f"DIRECTION('',({x!r},{y!r},{z!r}))")

    def axis(self, o, z, x) -> str:
        return self.add(f"AXIS2_PLACEMENT_3D('',{self.pt(o)},{self.dir(z)},{self.dir(x)})")

    def face(self, edges, surface) -> str:
        oes = [self.add(f"ORIENTED_EDGE('',*,*,{e},{s})") for e, s in edges]
        loop = self.add(f"EDGE_LOOP('',({','.join(oes)}))")
        bound = self.add(f"FACE_OUTER_BOUND('',{loop},.T.)")
        return self.add(f"ADVANCED_FACE('',({bound}),{surface},.T.)")

    def document(self, solids_fn, unit: str) -> str:
        app = self.add("APPLICATION_CONTEXT('automotive design')")
        self.add(f"APPLICATION_PROTOCOL_DEFINITION('international standard',"
                 f"'automotive_design',2000,{app})")
        pc = self.add(f"PRODUCT_CONTEXT('',{app},'mechanical')")
        pr = self.add(f"PRODUCT('part','part','',({pc}))")
        pf = self.add(f"PRODUCT_DEFINITION_FORMATION('','',{pr})")
        pdc = self.add(f"PRODUCT_DEFINITION_CONTEXT('part definition',{app},'design')")
        pd = self.add(f"PRODUCT_DEFINITION('design','',{pf},{pdc})")
        pds = self.add(f"PRODUCT_DEFINITION_SHAPE('','',{pd})")
        if unit == "inch":
            mm = self.add("(LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.))")
            lm = self.add(f"LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(25.4),{mm})")
            dim = self.add("DIMENSIONAL_EXPONENTS(1.,0.,0.,0.,0.,0.,0.)")
            lu = self.add(f"(CONVERSION_BASED_UNIT('INCH',{lm}) LENGTH_UNIT() NAMED_UNIT({dim}))")
        else:
            prefix = {"mm": ".MILLI.", "m": "$", "cm": ".CENTI."}[unit]
            lu = self.add(f"(LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT({prefix},.METRE.))")
        au = self.add("(NAMED_UNIT(*) PLANE_ANGLE_UNIT() SI_UNIT($,.RADIAN.))")
        su = self.add("(NAMED_UNIT(*) SI_UNIT($,.STERADIAN.) SOLID_ANGLE_UNIT())")
        unc = self.add(f"UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE(1.E-07),{lu},"
                       "'distance_accuracy_value','')")
        ctx = self.add(f"(GEOMETRIC_REPRESENTATION_CONTEXT(3) GLOBAL_UNCERTAINTY_ASSIGNED_CONTEXT"
                       f"(({unc})) GLOBAL_UNIT_ASSIGNED_CONTEXT(({lu},{au},{su})) "
                       "REPRESENTATION_CONTEXT('',''))")
        solids = solids_fn(self)
        origin = self.axis((0, 0, 0), (0, 0, 1), (1, 0, 0))
        rep = self.add(f"ADVANCED_BREP_SHAPE_REPRESENTATION('',({','.join(solids)},{origin}),"
                       f"{ctx})")
        self.add(f"SHAPE_DEFINITION_REPRESENTATION({pds},{rep})")
        return ("ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION(('part'),'2;1');\n"
                "FILE_NAME('part.step','2024-01-01T00:00:00',(''),(''),'','','');\n"
                "FILE_SCHEMA(('AUTOMOTIVE_DESIGN { 1 0 10303 214 1 1 1 1 }'));\nENDSEC;\n"
                "DATA;\n" + "\n".join(self.lines) + "\nENDSEC;\nEND-ISO-10303-21;\n")


def _box_solid(s: _Step, lo, hi) -> str:
    corner = {k: tuple(hi[i] if k[i] else lo[i] for i in range(3))
              for k in itertools.product((0, 1), repeat=3)}
    vert = {k: s.add(f"VERTEX_POINT('',{s.pt(p)})") for k, p in corner.items()}
    edges: dict = {}

    def edge(a, b):
        if (b, a) in edges:
            return edges[(b, a)], ".F."
        if (a, b) not in edges:
            d = np.subtract(corner[b], corner[a])
            n = float(np.linalg.norm(d))
            vec = s.add(f"VECTOR('',{s.dir(d / n)},{n!r})")
            line = s.add(f"LINE('',{s.pt(corner[a])},{vec})")
            edges[(a, b)] = s.add(f"EDGE_CURVE('',{vert[a]},{vert[b]},{line},.T.)")
        return edges[(a, b)], ".T."

    faces = []
    for ax in range(3):
        u, v = (ax + 1) % 3, (ax + 2) % 3
        for side in (0, 1):
            uv = [(0, 0), (1, 0), (1, 1), (0, 1)]
            uv = uv if side else uv[::-1]  # counter-clockwise about the outward normal
            keys = []
            for a, b in uv:
                k = [0, 0, 0]
                k[ax], k[u], k[v] = side, a, b
                keys.append(tuple(k))
            normal = [0, 0, 0]
            normal[ax] = 1 if side else -1
            ref = [0, 0, 0]
            ref[u] = 1
            plane = s.add(f"PLANE('',{s.axis(corner[keys[0]], normal, ref)})")
            faces.append(s.face([edge(keys[i], keys[(i + 1) % 4]) for i in range(4)], plane))
    shell = s.add(f"CLOSED_SHELL('',({','.join(faces)}))")
    return s.add(f"MANIFOLD_SOLID_BREP('',{shell})")


def step_boxes(boxes, unit: str = "mm") -> bytes:
    """STEP text of axis-aligned boxes [(lo, hi), ...] in the given unit."""
    return _Step().document(lambda s: [_box_solid(s, lo, hi) for lo, hi in boxes],
                            unit).encode()


def step_cylinder(r: float, h: float, unit: str = "mm") -> bytes:
    """STEP text of a cylinder (radius r, height h along z from z=0): curved faces and seams."""

    def solid(s: _Step) -> list[str]:
        v0 = s.add(f"VERTEX_POINT('',{s.pt((r, 0, 0))})")
        v1 = s.add(f"VERTEX_POINT('',{s.pt((r, 0, h))})")
        c0 = s.add(f"CIRCLE('',{s.axis((0, 0, 0), (0, 0, 1), (1, 0, 0))},{float(r)!r})")
        c1 = s.add(f"CIRCLE('',{s.axis((0, 0, h), (0, 0, 1), (1, 0, 0))},{float(r)!r})")
        e0 = s.add(f"EDGE_CURVE('',{v0},{v0},{c0},.T.)")
        e1 = s.add(f"EDGE_CURVE('',{v1},{v1},{c1},.T.)")
        vec = s.add(f"VECTOR('',{s.dir((0, 0, 1))},{float(h)!r})")
        seam = s.add(f"EDGE_CURVE('',{v0},{v1},{s.add(f'LINE({chr(39) * 2},{s.pt((r, 0, 0))},{vec})')},.T.)")  # noqa: E501
        bottom = s.face([(e0, ".F.")], s.add(f"PLANE('',{s.axis((0, 0, 0), (0, 0, -1), (1, 0, 0))})"))  # noqa: E501
        top = s.face([(e1, ".T.")], s.add(f"PLANE('',{s.axis((0, 0, h), (0, 0, 1), (1, 0, 0))})"))
        surf = s.add(f"CYLINDRICAL_SURFACE('',{s.axis((0, 0, 0), (0, 0, 1), (1, 0, 0))},"
                     f"{float(r)!r})")
        side = s.face([(e0, ".T."), (seam, ".T."), (e1, ".F."), (seam, ".F.")], surf)
        shell = s.add(f"CLOSED_SHELL('',({bottom},{top},{side}))")
        return [s.add(f"MANIFOLD_SOLID_BREP('',{shell})")]

    return _Step().document(solid, unit).encode()


# -- helpers -------------------------------------------------------------------------------------


def _export(mesh_or_scene, file_type: str) -> bytes:
    data = mesh_or_scene.export(file_type=file_type)
    return data.encode() if isinstance(data, str) else data


def _box_mm() -> trimesh.Trimesh:
    """A 40 x 30 x 20 part in millimetre numbers, off-centre so frames matter."""
    box = trimesh.creation.box(extents=(40.0, 30.0, 20.0))
    box.apply_translation((100.0, 50.0, 10.0))
    return box


def _dxf(build, insunits: int = 4) -> bytes:
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = insunits
    build(doc, doc.modelspace())
    s = io.StringIO()
    doc.write(s)
    return s.getvalue().encode()


def _assert_box_m(result, extents_m, volume_m3=None) -> None:
    np.testing.assert_allclose(result.mesh.extents, extents_m, rtol=1e-6)
    assert result.mesh.is_watertight
    if volume_m3 is not None:
        assert result.mesh.volume == pytest.approx(volume_m3, rel=1e-5)


# -- every format, with the unit each one implies -------------------------------------------------


@pytest.mark.parametrize(
    ("file_type", "suffix", "units", "source"),
    [
        ("stl", ".stl", "mm", "size"),
        ("stl_ascii", ".stl", "mm", "size"),
        ("obj", ".obj", "mm", "size"),
        ("ply", ".ply", "mm", "size"),
        ("3mf", ".3mf", "mm", "file"),  # 3MF states millimetre
    ],
)
def test_mesh_formats_in_millimetres(file_type, suffix, units, source):
    result = load_cad(_export(_box_mm(), file_type), "bracket" + suffix)
    assert (result.units, result.units_source) == (units, source)
    assert result.scale_to_m == 0.001
    _assert_box_m(result, (0.04, 0.03, 0.02), 0.04 * 0.03 * 0.02)
    # The file's own frame is kept (no recentring): CAD coordinates stay meaningful.
    np.testing.assert_allclose(result.mesh.bounds[0], (0.08, 0.035, 0.0), atol=1e-9)
    assert result.collision[0].kind == ShapeKind.MESH
    assert result.proxy.kind == "mesh" and result.proxy.deviation_m == 0.0


def test_glb_is_metres_by_specification():
    box = trimesh.creation.box(extents=(0.4, 0.3, 0.2))
    result = load_cad(_export(trimesh.Scene(box), "glb"), "table.glb")
    assert (result.units, result.units_source, result.scale_to_m) == ("m", "file", 1.0)
    _assert_box_m(result, (0.4, 0.3, 0.2), 0.024)


def test_glb_in_millimetre_numbers_warns_about_implausible_size():
    # A GLB whose author wrote millimetres anyway: by the spec it is 40 m; we say so.
    result = load_cad(_export(trimesh.Scene(_box_mm()), "glb"), "wrong.glb")
    assert result.units == "m"
    assert any("units='mm'" in w for w in result.warnings)
    fixed = load_cad(_export(trimesh.Scene(_box_mm()), "glb"), "wrong.glb", units="mm")
    assert (fixed.units, fixed.units_source) == ("mm", "caller")
    _assert_box_m(fixed, (0.04, 0.03, 0.02))
    assert not any("units=" in w for w in fixed.warnings)


def test_gltf_with_embedded_buffers():
    box = trimesh.creation.box(extents=(0.1, 0.2, 0.3))
    files = export_gltf(trimesh.Scene(box), embed_buffers=True)
    result = load_cad(files["model.gltf"], "part.gltf")
    assert (result.units, result.units_source) == ("m", "file")
    _assert_box_m(result, (0.1, 0.2, 0.3), 0.006)


def test_gltf_with_external_buffer_is_refused_with_advice():
    files = export_gltf(trimesh.Scene(trimesh.creation.box()))
    with pytest.raises(CadImportError, match=r"part\.gltf.*external file.*\.glb"):
        load_cad(files["model.gltf"], "part.gltf")


def test_multibody_scene_is_merged_with_node_transforms():
    a = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    b = trimesh.creation.cylinder(radius=0.05, height=0.2, sections=16)
    scene = trimesh.Scene()
    T_a = trimesh.transformations.translation_matrix((0.5, 0.0, 0.0))
    T_b = trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0), (0, 0, 0))
    T_b[:3, 3] = (0.0, 0.3, 0.1)
    scene.add_geometry(a, node_name="a", transform=T_a)
    scene.add_geometry(b, node_name="b", transform=T_b)
    for ft in ("glb", "3mf"):
        result = load_cad(_export(scene, ft), "assembly." + ft, units="m")
        assert result.bodies == 2
        assert len(result.mesh.faces) == len(a.faces) + len(b.faces)
        np.testing.assert_allclose(result.mesh.bounds, scene.bounds, atol=1e-6)
        assert result.mesh.volume == pytest.approx(a.volume + b.volume, rel=1e-6)


def test_3mf_unit_attribute_is_honoured_and_overridable():
    data = _export(trimesh.Scene(trimesh.creation.box(extents=(4.0, 3.0, 2.0))), "3mf")
    src = zipfile.ZipFile(io.BytesIO(data))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        for info in src.infolist():
            body = src.read(info)
            if info.filename.lower().endswith(".model"):
                assert b'unit="millimeter"' in body
                body = body.replace(b'unit="millimeter"', b'unit="inch"')
            z.writestr(info, body)
    result = load_cad(out.getvalue(), "plate.3mf")
    assert (result.units, result.units_source, result.file_units) == ("inch", "file", "inch")
    _assert_box_m(result, (4 * 0.0254, 3 * 0.0254, 2 * 0.0254))
    override = load_cad(out.getvalue(), "plate.3mf", units="mm")
    assert (override.units, override.units_source, override.file_units) == ("mm", "caller", "inch")
    _assert_box_m(override, (0.004, 0.003, 0.002))


@pytest.mark.parametrize(("largest", "units"), [(0.9, "m"), (2.9, "m"), (3.1, "mm"), (400, "mm")])
def test_size_heuristic_threshold(largest, units):
    box = trimesh.creation.box(extents=(largest, largest / 2, largest / 4))
    result = load_cad(_export(box, "stl"), "part.stl")
    assert (result.units, result.units_source) == (units, "size")
    expected = largest * (0.001 if units == "mm" else 1.0)
    assert result.mesh.extents.max() == pytest.approx(expected, rel=1e-6)
    assert "largest dimension" in result.units_reason


@pytest.mark.parametrize(("units", "factor"), [("m", 1.0), ("millimetres", 0.001),
                                              ("inch", 0.0254), ("cm", 0.01)])
def test_caller_units_override_for_unitless_formats(units, factor):
    result = load_cad(_export(_box_mm(), "stl"), "part.stl", units=units)
    assert result.units_source == "caller"
    assert result.mesh.extents.max() == pytest.approx(40.0 * factor, rel=1e-6)


def test_unknown_unit_is_refused():
    with pytest.raises(CadImportError, match="unknown length unit 'furlong'"):
        load_cad(_export(_box_mm(), "stl"), "part.stl", units="furlong")


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


def test_repairs_are_made_and_reported():
    box = trimesh.creation.box(extents=(40.0, 30.0, 20.0))
    faces = box.faces.copy()
    faces[[1, 4, 7]] = faces[[1, 4, 7]][:, ::-1]  # three faces wound the wrong way
    faces = np.delete(faces, 5, axis=0)  # a hole
    faces = np.vstack([faces, faces[0], [[0, 0, 1]]])  # a duplicate and a degenerate face
    broken = trimesh.Trimesh(box.vertices, faces, process=False)
    assert not broken.is_watertight
    result = load_cad(_export(broken, "stl"), "broken.stl")
    text = " | ".join(result.repairs)
    assert "degenerate" in text and "duplicate" in text
    assert "filled small holes" in text and "winding" in text
    _assert_box_m(result, (0.04, 0.03, 0.02), 0.04 * 0.03 * 0.02)
    assert len(result.mesh.faces) == 12


def test_inside_out_mesh_is_turned_outward():
    box = trimesh.creation.box(extents=(40.0, 30.0, 20.0))
    inverted = trimesh.Trimesh(box.vertices, box.faces[:, ::-1], process=False)
    assert inverted.volume < 0
    result = load_cad(_export(inverted, "obj"), "inside_out.obj")
    assert result.mesh.volume == pytest.approx(0.04 * 0.03 * 0.02, rel=1e-6)
    assert result.repairs


def test_open_sheet_is_accepted_with_a_warning():
    sheet = b"v 0 0 0\nv 100 0 0\nv 100 100 0\nv 0 100 0\nf 1 2 3\nf 1 3 4\n"
    result = load_cad(sheet, "sheet.obj")
    assert result.mesh.area == pytest.approx(0.01)
    assert any("not watertight" in w for w in result.warnings)


# -- bad input ----------------------------------------------------------------------------------


def _truncated_glb() -> bytes:
    return _export(trimesh.Scene(_box_mm()), "glb")[:200]


BAD_FILES = {
    "random.stl": (np.random.default_rng(1).bytes(1000), "no triangle faces"),
    "truncated.glb": (_truncated_glb(), "could not be read as GLB"),
    "empty.obj": (b"", "is empty"),
    "comments.obj": (b"# nothing here\n", "no triangle faces"),
    "nan.obj": (b"v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "NaN or infinite"),
    "inf.obj": (b"v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n", "NaN or infinite"),
    "collinear.obj": (b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "degenerate"),
    "point.obj": (b"v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n", "degenerate"),
    "wires.obj": (b"v 0 0 0\nv 1 0 0\nl 1 2\n", "only points or lines"),
    "random.ply": (np.random.default_rng(2).bytes(500), "could not be read as PLY"),
    "random.3mf": (np.random.default_rng(3).bytes(500), "could not be read as 3MF"),
    "random.dxf": (np.random.default_rng(4).bytes(500), "not a DXF"),
    "text.step": (b"solid cube\nendsolid\n", "not a STEP file"),
    "truncated.step": (step_boxes([((0, 0, 0), (1, 1, 1))])[:900], "could not read"),
    "empty_data.step": (b"ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\nENDSEC;\nEND-ISO-10303-21;\n",
                        "could not read"),
    "part.iges": (b"IGES", "unsupported file type '.iges'"),
    "noext": (b"solid", "unsupported file type"),
}


@pytest.mark.parametrize("name", list(BAD_FILES))
def test_bad_files_are_refused_with_a_clear_message(name):
    data, expected = BAD_FILES[name]
    with pytest.raises(CadImportError) as info:
        load_cad(data, name)
    message = str(info.value)
    assert name in message and expected in message
    assert " — " in message, "the message must say what to do"


def test_dxf_without_geometry_is_refused():
    with pytest.raises(CadImportError, match=r"empty\.dxf.*no 3-D faces and no outlines"):
        load_cad(_dxf(lambda doc, msp: None), "empty.dxf")


def test_missing_path_is_reported(tmp_path):
    with pytest.raises(CadImportError, match="cannot be opened"):
        load_cad_path(tmp_path / "nope.stl")


def test_load_cad_path_reads_the_file(tmp_path):
    p = tmp_path / "part.ply"
    p.write_bytes(_export(_box_mm(), "ply"))
    result = load_cad_path(p)
    assert result.filename == "part.ply" and result.source.data == p.read_bytes()


def test_gltf_that_is_not_json_is_refused():
    with pytest.raises(CadImportError, match="not valid glTF JSON"):
        load_cad(b"\xff\xfe garbage", "x.gltf")
    with pytest.raises(CadImportError, match="not a glTF document"):
        load_cad(json.dumps([1, 2]).encode(), "x.gltf")


# -- big meshes: display keeps detail, collision gets a proxy ----------------------------------


def test_big_convex_mesh_gets_its_hull():
    block = trimesh.creation.box(extents=(0.3, 0.2, 0.1))
    for _ in range(4):
        block = block.subdivide()  # 3072 faces, as a scanner or a fine export would give
    result = load_cad(_export(block, "ply"), "block.ply", proxy_max_faces=1000)
    assert len(result.mesh.faces) == 3072  # display keeps every triangle
    assert result.proxy.kind == "convex_hull" and result.proxy.faces == 12
    assert result.proxy.deviation_m < 1e-9
    assert len(result.collision) == 1 and result.collision[0].kind == ShapeKind.MESH


def test_finely_tessellated_round_part_gets_a_small_conservative_hull():
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.1)  # 20480 faces
    result = load_cad(_export(sphere, "stl"), "ball.stl", units="m", proxy_max_faces=2000,
                      proxy_tolerance_m=0.005)
    hull = result.collision[0].mesh
    assert result.proxy.kind == "convex_hull" and len(hull.faces) <= 2000
    assert 0.0 < result.proxy.deviation_m <= 0.005
    # Conservative: every point of the part is inside the proxy ...
    n, p0 = hull.face_normals, hull.triangles[:, 0]
    outside = (result.mesh.vertices @ n.T - np.einsum("ij,ij->i", n, p0)).max()
    assert outside <= 1e-9
    # ... and the proxy reaches no farther out than the reported deviation (exact sphere).
    assert np.linalg.norm(hull.vertices, axis=1).max() - 0.1 <= result.proxy.deviation_m + 1e-6


def test_tight_tolerance_keeps_the_closest_candidate_and_warns():
    torus = trimesh.creation.torus(0.2, 0.05, major_sections=48, minor_sections=24)  # 2304 faces
    result = load_cad(_export(torus, "stl"), "ring.stl", units="m", proxy_max_faces=500,
                      proxy_tolerance_m=0.0001)
    tried = dict(result.proxy.tried)
    assert {"convex_hull", "convex_decomposition"} <= set(tried)
    assert result.proxy.deviation_m == min(tried.values())
    assert tried[result.proxy.kind] == result.proxy.deviation_m
    assert any("no collision proxy within 0.1 mm" in w for w in result.warnings)


def test_big_concave_mesh_gets_a_closer_proxy_and_a_measured_deviation():
    R, r = 0.2, 0.05
    torus = trimesh.creation.torus(R, r, major_sections=64, minor_sections=40)  # 5120 faces
    result = load_cad(_export(torus, "stl"), "ring.stl", units="m", proxy_max_faces=1000,
                      proxy_tolerance_m=0.02)
    tried = dict(result.proxy.tried)
    # The hull's worst point is the middle of its cap, sqrt(R^2 + r^2) - r from the tube.
    assert tried["convex_hull"] == pytest.approx(np.hypot(R, r) - r, abs=0.005)
    assert result.proxy.kind != "convex_hull"
    assert result.proxy.deviation_m <= 0.02
    assert len(result.collision) == result.proxy.parts >= 2

    # Check the reported deviation against the exact torus, independently of the estimator.
    def tube_distance(p):  # > 0 outside the (ideal) torus
        return np.hypot(np.hypot(p[:, 0], p[:, 1]) - R, p[:, 2]) - r

    # The report is a sampled estimate (it may miss the worst point by a little), and the
    # tessellated torus lies up to ~0.5 mm inside the ideal one.
    parts = [shape.mesh for shape in result.collision]
    bound = 1.1 * result.proxy.deviation_m + 0.001
    on_proxy = np.vstack([trimesh.sample.sample_surface(p, 300, seed=5)[0] for p in parts])
    assert tube_distance(on_proxy).max() <= bound
    u, v = np.random.default_rng(9).uniform(0, 2 * np.pi, (2, 2000))
    on_part = np.column_stack([(R + r * np.cos(v)) * np.cos(u), (R + r * np.cos(v)) * np.sin(u),
                               r * np.sin(v)])
    inside = np.any([p.contains(on_part) for p in parts], axis=0)
    gap = np.min([trimesh.proximity.closest_point(p, on_part[~inside])[1] for p in parts], axis=0)
    assert gap.max(initial=0.0) <= bound


def test_small_mesh_collides_as_itself():
    result = load_cad(_export(_box_mm(), "stl"), "part.stl")
    assert result.collision[0].mesh is result.mesh
    assert "units: mm" in result.summary()
