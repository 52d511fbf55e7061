"""Every CAD reader guarded (issue 54): devices and pipes refused by name, files sized up from
what they state before a reader parses them - 3MF bombs by their zip directory, glTF
accessors by the bytes they imply, triangle counts from headers - and nesting bounded. Each
refusal names the file, the figure and what to do, and costs no memory."""

from __future__ import annotations

import io
import json
import os
import struct
import subprocess
import sys
import threading
import zipfile
from pathlib import Path

import numpy as np
import pytest
import trimesh
from test_file_guard import zip_bomb

from assistant.cell.cad import CadImportError, load_cad, load_cad_path

ROOT = Path(__file__).resolve().parents[2]


def _peak_after(code: str) -> tuple[str, float]:
    """Run `code` (which prints one line) in a fresh interpreter: (its line, its peak RSS in
    MB). A fresh process, so the peak is the import's own, not the test worker's."""
    wrapped = (f"{code}\nfrom pathlib import Path\n"
               "hwm = [l for l in Path('/proc/self/status').read_text().splitlines() "
               "if l.startswith('VmHWM:')][0].split()[1]\nprint(int(hwm) / 1024)")
    p = subprocess.run([sys.executable, "-c", wrapped], capture_output=True, text=True,
                       timeout=300, cwd=ROOT, env=dict(os.environ, OMP_NUM_THREADS="1"))
    assert p.returncode == 0, p.stderr[-3000:]
    lines = p.stdout.strip().splitlines()
    return lines[-2], float(lines[-1])


_REFUSED = ("from assistant.cell.cad import CadImportError, load_cad_path\n"
            "try:\n    load_cad_path({path!r})\n    print('imported')\n"
            "except CadImportError as e:\n    print(e)")


def test_a_2_mb_3mf_that_expands_to_2_gib_is_refused_without_growing(tmp_path):
    bomb = tmp_path / "fixture.3mf"
    bomb.write_bytes(zip_bomb())
    line, peak_mb = _peak_after(_REFUSED.format(path=str(bomb)))
    assert "fixture.3mf" in line and "would expand from 2 MiB to 2,048 MiB" in line
    assert "not inflated" in line
    # Inflating would take 2 GB; the interpreter with trimesh loaded is ~150-250 MB.
    assert peak_mb < 600, peak_mb


def test_a_10_million_triangle_stl_is_refused_before_it_is_parsed(tmp_path):
    """The header says 10 M triangles (a sparse file of the right length stands in for one:
    the refusal comes from the header, before any triangle is parsed)."""
    path = tmp_path / "huge_fixture.stl"
    n = 10_000_000
    with open(path, "wb") as f:
        f.write(b"binary STL".ljust(80) + struct.pack("<I", n))
        f.truncate(84 + 50 * n)
    line, peak_mb = _peak_after(_REFUSED.format(path=str(path)))
    assert "huge_fixture.stl" in line and "10,000,000 triangles" in line
    assert "4,000,000 an import takes (refused before reading it)" in line
    assert "decimate" in line  # what to do
    assert peak_mb < 1200, peak_mb  # the 477 MiB file, not the 5+ GB a parse would take


def test_devices_and_pipes_are_named_not_read(tmp_path):
    with pytest.raises(CadImportError, match=r"/dev/zero is a character device, not a CAD "
                                             r"file — give the path of the CAD file itself"):
        load_cad_path("/dev/zero")
    fifo = tmp_path / "part.stl"
    os.mkfifo(fifo)
    out: list[str] = []

    def run() -> None:
        try:
            load_cad_path(fifo)
        except CadImportError as exc:
            out.append(str(exc))

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(timeout=30)  # no writer ever comes: a blocking read would hang for good
    assert out and "named pipe (FIFO)" in out[0]


def _glb_with(accessor: dict) -> bytes:
    """A valid GLB box whose POSITION accessor is replaced by `accessor` (no bufferView)."""
    glb = trimesh.Scene(trimesh.creation.box(extents=(10, 10, 10))).export(file_type="glb")
    (length,) = struct.unpack("<I", glb[12:16])
    doc = json.loads(glb[20:20 + length])
    doc["accessors"].append(accessor)
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = len(doc["accessors"]) - 1
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    out = glb[:12] + struct.pack("<I", len(text)) + b"JSON" + text + glb[20 + length:]
    return out[:8] + struct.pack("<I", len(out)) + out[12:]


def test_glb_accessors_implying_gigabytes_are_refused_before_reading():
    """An accessor without data is an array of zeros as long as it says: 12 GB here."""
    data = _glb_with({"count": 1_000_000_000, "componentType": 5126, "type": "VEC3"})
    with pytest.raises(CadImportError, match=r"huge\.glb.*declares arrays of 11,4\d\d MiB in a "
                                             r"file of .*without mesh compression"):
        load_cad(data, "huge.glb")
    with pytest.raises(CadImportError, match="accessor with count -5"):
        load_cad(_glb_with({"count": -5, "componentType": 5126, "type": "VEC3"}), "neg.glb")


def test_nesting_is_bounded_in_gltf_json_and_3mf_xml():
    deep = b'{"asset": ' * 100_000 + b"1" + b"}" * 100_000
    with pytest.raises(CadImportError, match=r"deep\.gltf.*nests 100000 levels deep"):
        load_cad(deep, "deep.gltf")
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("3D/3dmodel.model", b'<?xml version="1.0"?><model unit="millimeter" '
                   b'xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">'
                   + b"<a>" * 5000 + b"</a>" * 5000 + b"</model>")
    with pytest.raises(CadImportError, match=r"deep\.3mf.*Excessive depth"):
        load_cad(buf.getvalue(), "deep.3mf")


def _exports() -> dict[str, bytes]:
    """A 2 x 2 x 2-subdivided cube (256 triangles) in every triangle-mesh format."""
    box = trimesh.creation.box(extents=(10, 10, 10)).subdivide().subdivide()
    out = {f"part.{k}": box.export(file_type=k) for k in ("stl", "obj", "ply", "glb", "3mf")}
    out = {k: v.encode() if isinstance(v, str) else v for k, v in out.items()}
    out["ascii.stl"] = trimesh.exchange.stl.export_stl_ascii(box).encode()
    return out


@pytest.mark.parametrize("name", list(_exports()))
def test_triangle_counts_are_read_from_the_file_before_parsing(name, monkeypatch):
    """With the limit set below the part's 192 triangles every format is refused before its
    reader runs (the reader is replaced by one that fails the test if called)."""
    import assistant.cell.cad.importer as importer

    data = _exports()[name]
    assert load_cad(data, name).mesh.faces.shape == (192, 3)
    monkeypatch.setattr(importer, "MAX_FACES", 100)

    def never(*args, **kwargs):
        raise AssertionError("the reader ran")

    monkeypatch.setattr(importer, "reader_for", lambda fmt: never)
    with pytest.raises(CadImportError, match=r"has 192 (triangles|faces), more than the 100 "
                                             r"an import takes \(refused before reading it\)"):
        load_cad(data, name)


def test_a_dxf_of_too_many_3d_faces_is_refused_before_ezdxf_reads_it():
    dxf = (b"0\nSECTION\n2\nENTITIES\n" + b"0\n3DFACE\n8\n0\n" * 130_000
           + b"0\nENDSEC\n0\nEOF\n")
    with pytest.raises(CadImportError, match=r"many\.dxf.*about 260,000 triangles \(3-D faces\)"
                                             r".*250,000 a DXF import reads.*binary STL"):
        load_cad(dxf, "many.dxf")


def test_the_summary_names_the_full_part_and_what_is_drawn(monkeypatch):
    """A part bigger than the display limit is drawn decimated; the import keeps and reports
    the full one."""
    import assistant.cell.cad.importer as importer

    sphere = trimesh.creation.icosphere(subdivisions=5, radius=50.0)  # 20480 faces
    monkeypatch.setattr(importer, "DISPLAY_MAX_FACES", 5000)
    cad = load_cad(sphere.export(file_type="stl"), "ball.stl")
    assert len(cad.mesh.faces) == 20480 and len(cad.display_mesh.faces) <= 5000
    assert np.allclose(cad.mesh.extents, 0.1, rtol=1e-3)
    assert "ball.stl: 20,480 triangles" in cad.summary()
    assert any("drawn with" in b and "20,480" in b for b in cad.bounded)


def test_a_step_file_is_sized_by_its_tessellation_before_it_is_read(monkeypatch):
    from cad_builders import step_boxes

    import assistant.cell.cad.step as step

    data = step_boxes([((0, 0, 0), (10, 10, 10))])
    assert len(load_cad(data, "box.step").mesh.faces) == 12
    monkeypatch.setattr(step, "MAX_FACES", 10)
    with pytest.raises(CadImportError, match=r"box\.step.*tessellates to 12 triangles, more "
                                             r"than the 10.*coarser STEP tolerance"):
        load_cad(data, "box.step")


def test_a_cell_layout_dxf_is_sized_before_ezdxf_reads_it():
    from assistant.cell.cad.layout import read_layout

    dxf = (b"0\nSECTION\n2\nENTITIES\n0\nTEXT\n8\nLOCATIONS\n1\nP1 start\n"
           + b"0\n3DFACE\n8\n0\n" * 130_000 + b"0\nENDSEC\n0\nEOF\n")
    with pytest.raises(CadImportError, match=r"layout\.dxf.*about 260,000 triangles"):
        read_layout(dxf, "layout.dxf")
