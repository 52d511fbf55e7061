"""Saving and loading cells: exact round trips (folder and zip), and clean refusals of
tampered, damaged, newer or hostile files."""

from __future__ import annotations

import io
import json
import os
import shutil
import zipfile
from pathlib import Path

import ezdxf
import numpy as np
import pytest
import trimesh

from assistant.cell import storage as cell_io
from assistant.cell.cad import load_cad, load_cad_path
from assistant.cell.model import Cell, CellObject
from assistant.cell.storage import CellFileError, load_cell, save_cell
from assistant.robots.catalog import RobotSpec, ToolSpec
from assistant.transforms import pose_from_mm_deg

STEP_FIXTURE = Path(__file__).parent / "data" / "cad" / "two_blocks_mm.step"


def _outline_dxf() -> bytes:
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 4
    msp = doc.modelspace()
    msp.add_lwpolyline([(0, 0), (120, 0), (120, 60), (0, 60)], close=True)
    msp.add_circle((30, 30), 12)
    s = io.StringIO()
    doc.write(s)
    return s.getvalue().encode()


def _sample_cell() -> Cell:
    cell = Cell(robot_spec=RobotSpec(tool=ToolSpec.straight(0.12, 0.015)),
                T_world_base=pose_from_mm_deg([100.0, -50.0, 20.0, 30.0, 0.0, 0.0]))
    cell.add_object(CellObject.box("table", (1.2, 0.8, 0.04),
                                   pose_from_mm_deg([400, 0, -20, 0, 0, 0]), role="fixture"))
    cell.add_object(CellObject.cylinder("post", 0.03, 0.25,
                                        pose_from_mm_deg([300, 250, 125, 0, 0, 0])))
    cell.add_object(CellObject.sphere("ball", 0.0125, pose_from_mm_deg([350, 0, 12.5, 0, 0, 0]),
                                      role="workpiece", color=(255, 0, 0)))
    part = trimesh.creation.box(extents=(40.0, 30.0, 20.0))
    stl = load_cad(part.export(file_type="stl"), "Part #7 (rev B).stl")
    cell.add_object(CellObject.from_cad("part", stl, pose_from_mm_deg([320, 40, 10, 12.5, 0, 0]),
                                        role="workpiece"))
    glb = load_cad(trimesh.Scene(part).export(file_type="glb"), "housing.glb", units="mm")
    cell.add_object(CellObject.from_cad("housing", glb, pose_from_mm_deg([0, 300, 0, 0, 0, 90])))
    dxf = load_cad(_outline_dxf(), "plate.dxf", dxf_extrude_height=0.006)
    cell.add_object(CellObject.from_cad("plate", dxf, pose_from_mm_deg([500, -200, 0, 0, 0, 0]),
                                        role="fixture", color=(10, 20, 30)))
    step = load_cad_path(STEP_FIXTURE)
    cell.add_object(CellObject.from_cad("blocks", step, pose_from_mm_deg([450, 200, 0, 45, 0, 0])))
    # The same file twice: stored once.
    cell.add_object(CellObject.from_cad("part_copy", stl,
                                        pose_from_mm_deg([320, -40, 10, 0, 0, 0])))
    cell.add_frame("pallet", pose_from_mm_deg([350, 100, 0, 90, 0, 0]))
    cell.add_frame("camera", pose_from_mm_deg([0, 0, 1500, 0, 90, 0]))
    return cell


def _assert_same_cell(a: Cell, b: Cell) -> None:
    assert a.robot_spec == b.robot_spec
    assert np.array_equal(a.T_world_base, b.T_world_base)
    assert list(a.objects) == list(b.objects)
    for name, oa in a.objects.items():
        ob = b.objects[name]
        assert (oa.role, oa.color, oa.primitive) == (ob.role, ob.color, ob.primitive), name
        assert np.array_equal(oa.T_world_object, ob.T_world_object), name
        assert np.array_equal(oa.display_mesh.vertices, ob.display_mesh.vertices), name
        assert np.array_equal(oa.display_mesh.faces, ob.display_mesh.faces), name
        assert [s.kind for s in oa.collision] == [s.kind for s in ob.collision], name
        assert oa.proxy_deviation_m == ob.proxy_deviation_m
        if oa.source is None:
            assert ob.source is None
        else:
            sa, sb = oa.source, ob.source
            assert (sa.filename, sa.format, sa.units, sa.units_source, sa.scale_to_m,
                    sa.options, sa.data) == \
                   (sb.filename, sb.format, sb.units, sb.units_source, sb.scale_to_m,
                    sb.options, sb.data), name
    assert list(a.frames) == list(b.frames)
    for name in a.frames:
        assert np.array_equal(a.frames[name], b.frames[name])


@pytest.fixture(scope="module")
def sample_cell() -> Cell:
    return _sample_cell()


@pytest.mark.parametrize("target", ["saved_cell", "saved_cell.zip"])
def test_round_trip_is_exact(tmp_path, sample_cell, target):
    path = save_cell(sample_cell, tmp_path / target)
    loaded = load_cell(path)
    _assert_same_cell(sample_cell, loaded)
    # Saving what was loaded writes the same document again.
    again = save_cell(loaded, tmp_path / ("again_" + target))
    assert _json_of(path) == _json_of(again)
    assert not [p for p in tmp_path.rglob("*") if ".tmp-" in p.name]


def _json_of(path: Path) -> dict:
    if path.suffix == ".zip":
        with zipfile.ZipFile(path) as z:
            return json.loads(z.read("cell.json"))
    return json.loads((path / "cell.json").read_text())


def test_saved_document_is_plain_json_with_the_original_files(tmp_path, sample_cell):
    path = save_cell(sample_cell, tmp_path / "cell")
    doc = _json_of(path)
    assert doc["schema_version"] == cell_io.SCHEMA_VERSION
    by_name = {o["name"]: o for o in doc["objects"]}
    assert by_name["table"]["primitive"] == {"kind": "box", "size": [1.2, 0.8, 0.04]}
    part = by_name["part"]["cad"]
    assert part["units"] == "mm" and part["units_source"] == "size"
    assert part["filename"] == "Part #7 (rev B).stl"
    assert by_name["part_copy"]["cad"]["file"] == part["file"]
    assert (path / part["file"]).read_bytes() == sample_cell.objects["part"].source.data
    assert by_name["plate"]["cad"]["options"]["dxf_extrude_height"] == 0.006
    assert by_name["housing"]["cad"]["units_source"] == "caller"
    assert len(list((path / "cad").iterdir())) == 4  # part (twice), housing, plate, blocks
    assert load_cell(path / "cell.json").objects.keys() == sample_cell.objects.keys()


def test_folder_save_drops_files_of_removed_objects(tmp_path, sample_cell):
    cell = load_cell(save_cell(sample_cell, tmp_path / "cell"))
    cell.remove_object("plate")
    save_cell(cell, tmp_path / "cell")
    names = [p.name for p in (tmp_path / "cell" / "cad").iterdir()]
    assert not any("plate" in n for n in names) and len(names) == 3
    assert "plate" not in load_cell(tmp_path / "cell").objects


def test_object_without_a_source_cannot_be_saved(tmp_path):
    cell = Cell()
    mesh = trimesh.creation.box()
    from assistant.robots.model import CollisionShape, ShapeKind
    cell.add_object(CellObject("bare", "obstacle", np.eye(4), mesh,
                               (CollisionShape(ShapeKind.MESH, mesh=mesh),)))
    with pytest.raises(CellFileError, match="'bare' has neither a primitive nor an original CAD"):
        save_cell(cell, tmp_path / "c.zip")
    assert not list(tmp_path.iterdir())


# -- an interrupted save leaves the previous cell intact ------------------------------------------


def test_crash_while_writing_a_zip_keeps_the_old_one(tmp_path, sample_cell, monkeypatch):
    path = save_cell(sample_cell, tmp_path / "cell.zip")
    before = path.read_bytes()
    cell = load_cell(path)
    cell.remove_object("ball")

    def boom(self, name, data, *a, **k):
        if name.startswith("cad/"):
            raise OSError("disk full")
        return original(self, name, data, *a, **k)

    original = zipfile.ZipFile.writestr
    monkeypatch.setattr(zipfile.ZipFile, "writestr", boom)
    with pytest.raises(OSError, match="disk full"):
        save_cell(cell, path)
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["cell.zip"]
    assert "ball" in load_cell(path).objects


def test_crash_before_the_folder_commit_keeps_the_old_cell(tmp_path, sample_cell, monkeypatch):
    path = save_cell(sample_cell, tmp_path / "cell")
    cell = load_cell(path)
    cell.remove_object("ball")
    cell.set_object_pose("part", np.eye(4))

    def boom(src, dst):
        if Path(dst).name == "cell.json":
            raise OSError("power cut")
        return original(src, dst)

    original = os.replace
    monkeypatch.setattr(cell_io.os, "replace", boom)
    with pytest.raises(OSError, match="power cut"):
        save_cell(cell, path)
    monkeypatch.undo()
    _assert_same_cell(sample_cell, load_cell(path))
    assert not [p for p in path.rglob("*") if ".tmp-" in p.name]


# -- refusals ----------------------------------------------------------------------------------


@pytest.fixture()
def saved(tmp_path, sample_cell) -> Path:
    return save_cell(sample_cell, tmp_path / "cell")


def _edit(folder: Path, change) -> None:
    doc = json.loads((folder / "cell.json").read_text())
    change(doc)
    (folder / "cell.json").write_text(json.dumps(doc))


def _cad_entry(doc: dict, name: str) -> dict:
    return next(o for o in doc["objects"] if o["name"] == name)["cad"]


def test_tampered_cad_file_fails_its_checksum(saved):
    f = saved / _cad_entry(_json_of(saved), "part")["file"]
    data = bytearray(f.read_bytes())
    data[100] ^= 0xFF
    f.write_bytes(bytes(data))
    with pytest.raises(CellFileError, match="does not match its recorded checksum"):
        load_cell(saved)


def test_tampered_zip_member_fails_its_checksum(tmp_path, sample_cell):
    path = save_cell(sample_cell, tmp_path / "cell.zip")
    with zipfile.ZipFile(path) as z:
        members = {i.filename: z.read(i) for i in z.infolist()}
    victim = next(n for n in members if n.endswith("plate.dxf"))
    members[victim] = members[victim].replace(b"120.0", b"121.0", 1)
    with zipfile.ZipFile(path, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)
    with pytest.raises(CellFileError, match="checksum"):
        load_cell(path)


@pytest.mark.parametrize(("change", "match"), [
    (lambda d: d.update(schema_version=99), "newer cellteach \\(schema 99\\).*update"),
    (lambda d: d.update(schema_version="1"), "schema_version: expected int, got str"),
    (lambda d: d.update(schema_version=0), "unknown schema version 0"),
    (lambda d: d.pop("objects"), "missing 'objects'"),
    (lambda d: d["objects"][0].update(T_world_object=[[1, 0, 0]]), "4x4 list of numbers"),
    (lambda d: d["objects"][0]["T_world_object"][0].__setitem__(0, 2.0), "proper rotation"),
    (lambda d: d["objects"][0].update(role="wall"), "unknown role 'wall'"),
    (lambda d: d["objects"][0].update(color=[0, 0, 300]), "0-255"),
    (lambda d: d["objects"][0].update(primitive={"kind": "box", "size": [1, -1, 1]}), "> 0"),
    (lambda d: d["objects"][0].update(primitive=None), "neither 'primitive' nor 'cad'"),
    (lambda d: d["objects"].append(dict(d["objects"][0])), "already exists"),
    (lambda d: d.update(robot={"kind": "rv2aj", "tool": {"T_flange_tool": "x"}}), "robot"),
    (lambda d: d["frames"][0].update(T_world_frame=[[0] * 4] * 4), "last row"),
    (lambda d: _cad_entry(d, "part").update(file="../../etc/passwd"), "not a name this program"),
    (lambda d: _cad_entry(d, "part").update(file="cad/0123456789abcdef_missing.stl"),
     "is missing"),
    (lambda d: _cad_entry(d, "part").update(options={"units": None, "evil": 1}),
     "unknown import option"),
    (lambda d: _cad_entry(d, "part").update(options={"proxy_max_faces": "many"}),
     "proxy_max_faces must be an integer"),
    (lambda d: _cad_entry(d, "part").update(scale_to_m=1.0), "recorded 1.0"),
    (lambda d: _cad_entry(d, "part").update(units="furlong"), "unknown length unit"),
])
def test_bad_documents_are_refused_with_a_clear_message(saved, change, match):
    _edit(saved, change)
    with pytest.raises(CellFileError, match=match) as info:
        load_cell(saved)
    assert str(saved) in str(info.value)


def test_invalid_json_and_nan_are_refused(saved):
    (saved / "cell.json").write_text("{ not json")
    with pytest.raises(CellFileError, match="not valid JSON"):
        load_cell(saved)
    (saved / "cell.json").write_text('{"schema_version": 1, "x": NaN}')
    with pytest.raises(CellFileError, match="NaN is not a number"):
        load_cell(saved)


def test_missing_things_are_refused(tmp_path, saved):
    with pytest.raises(CellFileError, match="no saved cell here"):
        load_cell(tmp_path / "nowhere")
    (tmp_path / "junk.zip").write_bytes(b"PK not really")
    with pytest.raises(CellFileError, match="not a cell folder or a valid zip"):
        load_cell(tmp_path / "junk.zip")
    shutil.rmtree(saved / "cad")
    with pytest.raises(CellFileError, match="is missing"):
        load_cell(saved)
    (saved / "cell.json").unlink()
    with pytest.raises(CellFileError, match="'cell.json' is missing"):
        load_cell(saved)


def test_zip_with_path_traversal_is_refused(tmp_path, sample_cell):
    path = save_cell(sample_cell, tmp_path / "cell.zip")
    with zipfile.ZipFile(path, "a") as z:
        z.writestr("../../evil.sh", b"rm -rf /")
    with pytest.raises(CellFileError, match="unsafe member name '../../evil.sh'"):
        load_cell(path)
    assert not (tmp_path.parent / "evil.sh").exists()


def test_zip_bomb_and_absurd_sizes_are_refused(tmp_path, sample_cell, monkeypatch):
    path = save_cell(sample_cell, tmp_path / "cell.zip")
    with zipfile.ZipFile(path, "a", compression=zipfile.ZIP_DEFLATED) as z:
        z.writestr("cad/padding.bin", bytes(50 * 1024 * 1024))
    with pytest.raises(CellFileError, match="zip bomb"):
        load_cell(path)

    folder = save_cell(sample_cell, tmp_path / "cell")
    monkeypatch.setattr(cell_io, "MAX_OBJECTS", 3)
    with pytest.raises(CellFileError, match="more than 3"):
        load_cell(folder)
    monkeypatch.setattr(cell_io, "MAX_JSON_BYTES", 100)
    with pytest.raises(CellFileError, match="'cell.json' is .* bytes, more than the 100 allowed"):
        load_cell(folder)


def test_saving_over_the_wrong_kind_of_path_is_refused(tmp_path, sample_cell):
    (tmp_path / "file").write_text("x")
    with pytest.raises(CellFileError, match="not a folder"):
        save_cell(sample_cell, tmp_path / "file")
    (tmp_path / "dir.zip").mkdir()
    with pytest.raises(CellFileError, match="is a folder"):
        save_cell(sample_cell, tmp_path / "dir.zip")


def test_a_device_or_pipe_planted_in_a_cell_folder_is_refused_not_read(tmp_path, sample_cell):
    """Issue 54: the CAD file of a saved cell replaced by a FIFO (no writer: a blocking read
    would hang the session) or a link to /dev/zero (it would fill the memory)."""
    folder = save_cell(sample_cell, tmp_path / "cell")
    member = next((folder / "cad").iterdir())
    member.unlink()
    os.mkfifo(member)
    with pytest.raises(CellFileError, match=r"named pipe \(FIFO\)"):
        load_cell(folder)
    member.unlink()
    member.symlink_to("/dev/zero")
    with pytest.raises(CellFileError, match="character device"):
        load_cell(folder)


def test_cell_json_nested_too_deep_is_refused_before_parsing(saved):
    doc = json.loads((saved / "cell.json").read_text())
    (saved / "cell.json").write_text(json.dumps(doc)[:-1] + ', "x": ' + "[" * 50_000
                                     + "]" * 50_000 + "}")
    with pytest.raises(CellFileError, match="nests 50001 levels deep, more than the 64"):
        load_cell(saved)
