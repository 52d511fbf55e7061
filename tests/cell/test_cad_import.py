"""CAD import: every format, units (file / size / caller), repairs, bad files, collision proxies.

Test files are generated here with trimesh and ezdxf; STEP files are written as STEP text (a
B-rep of boxes or a cylinder) and read through the real cascadio/OpenCASCADE path. One STEP
file is committed under tests/cell/data/cad as a fixed real-world-style input.
"""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest
import trimesh
from cad_builders import _assert_box_m, _box_mm, _dxf, _export, step_boxes
from trimesh.exchange.gltf import export_gltf

from assistant.cell.cad import CadImportError, load_cad, load_cad_path
from assistant.robots.model import ShapeKind


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
