"""Saving and loading a cell: `cell.json` plus the original CAD files, in a folder or a zip.

The CAD bytes the operator uploaded are the source of truth: they are stored unchanged (named
by their sha256, which the JSON records and loading verifies) and re-imported on load with the
same options and units, so no derived mesh can drift from its file. Only JSON and the CAD
readers ever see the data: no pickle, no eval. Saving writes to a temporary name and renames,
so an interrupted save leaves the previous cell intact.
Owns the cell file format only (the session's own file may embed it); must not import the UI.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import re
import secrets
import zipfile
from dataclasses import replace
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from assistant.cell.cad import CadImportError, ImportOptions, import_with_options
from assistant.cell.cad.importer import MAX_FILE_BYTES
from assistant.cell.cad.layout import parse_drawing
from assistant.cell.model import Cell, CellError, CellObject, PrimitiveSpec, check_transform
from assistant.file_guard import FileRefused, check_archive, load_json, read_file
from assistant.robots.catalog import RobotModelError, RobotSpec

SCHEMA_VERSION = 1
CELL_JSON = "cell.json"
CAD_DIR = "cad"
MAX_JSON_BYTES = 64 * 1024 * 1024
MAX_OBJECTS = 10_000
MAX_TOTAL_BYTES = 4 * 1024 * 1024 * 1024
#: A zip member expanding more than this many times its compressed size is a zip bomb.
MAX_COMPRESSION_RATIO = 200

_CAD_NAME = re.compile(r"^cad/[0-9a-f]{16}_[A-Za-z0-9._-]{1,80}$")


class CellFileError(ValueError):
    """A saved cell that cannot be loaded (or a cell that cannot be saved); nothing was changed."""

    def __init__(self, path: str | Path, problem: str):
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")


# -- saving ------------------------------------------------------------------------------------


def save_cell(cell: Cell, path: str | Path) -> Path:
    """Save to `path`: a `.zip` file, or else a folder (created if needed). Returns the path."""
    path = Path(path)
    doc, files = _cell_to_json(cell, path)
    text = json.dumps(doc, indent=1, allow_nan=False).encode("utf-8")
    if path.suffix.lower() == ".zip":
        _save_zip(path, text, files)
    else:
        _save_folder(path, text, files)
    return path


def _matrix(T: np.ndarray) -> list[list[float]]:
    return [[float(v) for v in row] for row in np.asarray(T, dtype=float)]


def _cad_member(sha: str, filename: str) -> str:
    stem = re.sub(r"[^A-Za-z0-9._-]", "_", Path(filename).name)[-80:].lstrip(".") or "part"
    return f"{CAD_DIR}/{sha[:16]}_{stem}"


def _cell_to_json(cell: Cell, path: Path) -> tuple[dict[str, Any], dict[str, bytes]]:
    files: dict[str, bytes] = {}
    objects = []
    for obj in cell.objects.values():
        entry: dict[str, Any] = {
            "name": obj.name,
            "role": obj.role.value,
            "color": list(obj.color or ()),
            "T_world_object": _matrix(obj.T_world_object),
            "primitive": None,
            "cad": None,
        }
        if obj.primitive is not None:
            entry["primitive"] = obj.primitive.to_json()
        elif obj.source is not None:
            src = obj.source
            member = _cad_member(src.sha256, src.filename)
            files[member] = src.data
            entry["cad"] = {
                "file": member,
                "filename": src.filename,
                "format": src.format,
                "sha256": src.sha256,
                "bytes": len(src.data),
                "units": src.units,
                "units_source": src.units_source,
                "scale_to_m": src.scale_to_m,
                "options": dict(src.options),
            }
        else:
            raise CellFileError(path, f"object {obj.name!r} has neither a primitive nor an "
                                "original CAD file, so it cannot be saved; import it with "
                                "load_cad or make it a box/cylinder/sphere")
        objects.append(entry)
    doc = {
        "schema_version": SCHEMA_VERSION,
        "generator": "cellteach",
        "robot": cell.robot_spec.to_json(),
        "T_world_base": _matrix(cell.T_world_base),
        "objects": objects,
        "frames": [{"name": n, "T_world_frame": _matrix(T)} for n, T in cell.frames.items()],
    }
    return doc, files


def _tmp_sibling(path: Path) -> Path:
    return path.with_name(f".{path.name}.tmp-{os.getpid()}-{secrets.token_hex(4)}")


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = _tmp_sibling(path)
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def _save_zip(path: Path, text: bytes, files: dict[str, bytes]) -> None:
    if path.is_dir():
        raise CellFileError(path, "is a folder; give a .zip file name or a folder without .zip")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_sibling(path)
    try:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as z:
            z.writestr(CELL_JSON, text)
            for member, data in sorted(files.items()):
                z.writestr(member, data)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def _save_folder(path: Path, text: bytes, files: dict[str, bytes]) -> None:
    """CAD files first (content-addressed, never overwritten with other bytes), then cell.json
    by rename: whichever cell.json a reader sees, every file it names is complete."""
    if path.exists() and not path.is_dir():
        raise CellFileError(path, "exists and is not a folder; choose another name or a .zip")
    cad_dir = path / CAD_DIR
    cad_dir.mkdir(parents=True, exist_ok=True)
    for member, data in files.items():
        target = path / member
        if target.is_file() and hashlib.sha256(target.read_bytes()).hexdigest() == \
                hashlib.sha256(data).hexdigest():
            continue
        _write_atomic(target, data)
    _write_atomic(path / CELL_JSON, text)
    for old in cad_dir.iterdir():  # files of objects removed since the last save
        if f"{CAD_DIR}/{old.name}" not in files and _CAD_NAME.match(f"{CAD_DIR}/{old.name}"):
            with contextlib.suppress(OSError):
                old.unlink()


# -- loading -----------------------------------------------------------------------------------


class _Reader:
    """Reads cell.json and its CAD files from a folder or a zip, with size and name checks."""

    def __init__(self, path: Path):
        self.path = path
        self.zip: zipfile.ZipFile | None = None
        self.folder: Path | None = None
        #: Layout drawings parsed this load, by checksum: a layout's parts share one.
        self.drawings: dict[str, Any] = {}
        if path.is_dir():
            self.folder = path
        elif path.is_file() and path.name == CELL_JSON:
            self.folder = path.parent
        elif path.is_file():
            try:
                self.zip = zipfile.ZipFile(path)
            except (zipfile.BadZipFile, OSError) as exc:
                raise CellFileError(path, f"is not a cell folder or a valid zip ({exc})") from exc
            self._check_zip()
        else:
            raise CellFileError(path, "no saved cell here (no such file or folder)")

    def close(self) -> None:
        if self.zip is not None:
            self.zip.close()

    def _check_zip(self) -> None:
        assert self.zip is not None
        for info in self.zip.infolist():
            name = info.filename
            parts = PurePosixPath(name.replace("\\", "/")).parts
            if name.startswith(("/", "\\")) or ".." in parts or re.match(r"^[A-Za-z]:", name):
                raise CellFileError(self.path, f"contains an unsafe member name {name!r}; "
                                    "refusing to open it")
        try:  # expansion ratio and total size, judged before anything is inflated
            check_archive(self.zip.infolist(), what="cell zip", max_total=MAX_TOTAL_BYTES,
                          max_ratio=MAX_COMPRESSION_RATIO)
        except FileRefused as exc:
            raise CellFileError(self.path, f"{exc}; refusing to open it") from None

    def read(self, member: str, limit: int) -> bytes:
        if self.zip is not None:
            try:
                info = self.zip.getinfo(member)
            except KeyError:
                raise CellFileError(self.path, f"{member!r} is missing from the zip") from None
            if info.file_size > limit:
                raise CellFileError(self.path, f"{member!r} is {info.file_size:,} bytes, more "
                                    f"than the {limit:,} allowed")
            with self.zip.open(info) as f:
                data = f.read(limit + 1)
        else:
            assert self.folder is not None
            target = self.folder / member
            try:
                size = target.stat().st_size
            except OSError:
                raise CellFileError(self.path, f"{member!r} is missing") from None
            if size > limit:
                raise CellFileError(self.path, f"{member!r} is {size:,} bytes, more than the "
                                    f"{limit:,} allowed")
            try:  # a regular file only (not a device or a pipe planted in the folder)
                data = read_file(target, limit=limit, what="file of a saved cell")
            except FileRefused as exc:
                raise CellFileError(self.path, f"{member!r}: {exc}") from None
        if len(data) > limit:
            raise CellFileError(self.path, f"{member!r} is larger than the {limit:,} allowed")
        return data


def load_cell(path: str | Path) -> Cell:
    """Load a cell saved by `save_cell` (folder, its cell.json, or a zip).

    Raises:
        CellFileError: missing/damaged/tampered files, an unknown schema version, wrong types,
            unsafe names or absurd sizes; the message names the file and the problem.
    """
    path = Path(path)
    reader = _Reader(path)
    try:
        raw = reader.read(CELL_JSON, MAX_JSON_BYTES)
        try:  # nesting depth bounded before the (recursive) parser runs
            doc = load_json(raw, what=CELL_JSON, limit=MAX_JSON_BYTES)
        except FileRefused as exc:
            problem = exc.problem.replace(f"the {CELL_JSON} is", f"{CELL_JSON} is")
            raise CellFileError(path, problem) from None
        return _cell_from_json(doc, reader)
    finally:
        reader.close()


def _need(d: Any, key: str, kind: type | tuple[type, ...], where: str, path: Path) -> Any:
    if not isinstance(d, dict) or key not in d:
        raise CellFileError(path, f"{where}: missing '{key}'")
    v = d[key]
    if not isinstance(v, kind) or (isinstance(v, bool) and bool not in _as_tuple(kind)):
        names = "/".join(t.__name__ for t in _as_tuple(kind))
        raise CellFileError(path, f"{where}.{key}: expected {names}, got {type(v).__name__}")
    return v


def _as_tuple(kind: type | tuple[type, ...]) -> tuple[type, ...]:
    return kind if isinstance(kind, tuple) else (kind,)


def _transform(v: Any, where: str, path: Path) -> np.ndarray:
    if not (isinstance(v, list) and len(v) == 4 and all(
            isinstance(r, list) and len(r) == 4 and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) for x in r) for r in v)):
        raise CellFileError(path, f"{where}: expected a 4x4 list of numbers")
    try:
        return check_transform(v, where)
    except CellError as exc:
        raise CellFileError(path, str(exc)) from exc


def _cell_from_json(doc: Any, reader: _Reader) -> Cell:
    path = reader.path
    if not isinstance(doc, dict):
        raise CellFileError(path, f"{CELL_JSON} must hold a JSON object")
    version = _need(doc, "schema_version", int, CELL_JSON, path)
    if version > SCHEMA_VERSION:
        raise CellFileError(path, f"was saved by a newer cellteach (schema {version}); this "
                            f"version reads schema {SCHEMA_VERSION} — update cellteach")
    if version < 1:
        raise CellFileError(path, f"unknown schema version {version}")
    try:
        robot_spec = RobotSpec.from_json(_need(doc, "robot", dict, CELL_JSON, path))
    except (RobotModelError, KeyError, TypeError, ValueError) as exc:
        raise CellFileError(path, f"robot: {exc}") from exc
    cell = Cell(robot_spec=robot_spec,
                T_world_base=_transform(_need(doc, "T_world_base", list, CELL_JSON, path),
                                        "T_world_base", path))

    objects = _need(doc, "objects", list, CELL_JSON, path)
    if len(objects) > MAX_OBJECTS:
        raise CellFileError(path, f"has {len(objects):,} objects, more than {MAX_OBJECTS:,}")
    for i, entry in enumerate(objects):
        where = f"objects[{i}]"
        obj = _object_from_json(entry, where, reader)
        try:
            cell.add_object(obj)
        except CellError as exc:
            raise CellFileError(path, f"{where}: {exc}") from exc

    frames = _need(doc, "frames", list, CELL_JSON, path)
    for i, f in enumerate(frames):
        where = f"frames[{i}]"
        name = _need(f, "name", str, where, path)
        T = _transform(_need(f, "T_world_frame", list, where, path), f"{where}.T_world_frame",
                       path)
        try:
            cell.add_frame(name, T)
        except CellError as exc:
            raise CellFileError(path, f"{where}: {exc}") from exc
    return cell


def _object_from_json(entry: Any, where: str, reader: _Reader) -> CellObject:
    path = reader.path
    name = _need(entry, "name", str, where, path)
    where = f"{where} ({name!r})"
    role = _need(entry, "role", str, where, path)
    color = _need(entry, "color", list, where, path)
    T = _transform(_need(entry, "T_world_object", list, where, path), f"{where}.T_world_object",
                   path)
    primitive = entry.get("primitive")
    cad = entry.get("cad")
    try:
        if primitive is not None:
            spec = PrimitiveSpec.from_json(primitive)
            return CellObject.from_primitive(name, spec, T, role=role, color=tuple(color))
        if cad is not None:
            return _cad_object(name, role, color, T, cad, where, reader)
    except CellError as exc:
        raise CellFileError(path, f"{where}: {exc}") from exc
    raise CellFileError(path, f"{where}: has neither 'primitive' nor 'cad'")


def _cad_object(name: str, role: str, color: list, T: np.ndarray, cad: Any, where: str,
                reader: _Reader) -> CellObject:
    path = reader.path
    where = f"{where}.cad"
    member = _need(cad, "file", str, where, path)
    if not _CAD_NAME.match(member):
        raise CellFileError(path, f"{where}.file: {member!r} is not a name this program writes "
                            "(expected cad/<hash>_<name>); refusing it")
    filename = _need(cad, "filename", str, where, path)
    sha = _need(cad, "sha256", str, where, path)
    units = _need(cad, "units", str, where, path)
    units_source = _need(cad, "units_source", str, where, path)
    stored_options = _need(cad, "options", dict, where, path)
    scale = _need(cad, "scale_to_m", (int, float), where, path)
    if not math.isfinite(scale) or scale <= 0:
        raise CellFileError(path, f"{where}.scale_to_m: must be a positive number")
    try:
        data = reader.read(member, MAX_FILE_BYTES)
    except CellFileError as exc:
        raise CellFileError(path, f"{where}: {exc.problem}") from exc
    actual = hashlib.sha256(data).hexdigest()
    if actual != sha.lower():
        raise CellFileError(path, f"{member!r} does not match its recorded checksum (the file "
                            "was changed or damaged after saving); restore the original file")
    try:
        options = ImportOptions.from_json(stored_options)
    except (TypeError, ValueError) as exc:
        raise CellFileError(path, f"{where}.options: {exc}") from exc
    # Re-import with the units decided at the first import, so a changed size heuristic in a
    # later version cannot rescale a saved part.
    try:
        imp = import_with_options(data, filename, replace(options, units=units),
                                  dxf_document=_layout_drawing(reader, data, actual, filename,
                                                               options))
    except CadImportError as exc:
        raise CellFileError(path, f"{where}: re-importing {member!r} failed: {exc}") from exc
    if not math.isclose(imp.scale_to_m, scale, rel_tol=1e-12):
        raise CellFileError(path, f"{where}: re-import gives scale {imp.scale_to_m} instead of "
                            f"the recorded {scale}")
    obj = CellObject.from_cad(name, imp, T, role=role, color=tuple(color))
    source = replace(imp.source, units_source=units_source, options=options.to_json())
    return replace(obj, source=source)


def _layout_drawing(reader: _Reader, data: bytes, sha: str, filename: str,
                    options: ImportOptions) -> Any:
    """The parsed drawing of a cell layout's part (one layer of a DXF), parsed once for all
    the parts this load reads from it; None for any other part."""
    if options.dxf_layer is None or Path(filename).suffix.lower() != ".dxf":
        return None
    if sha not in reader.drawings:
        reader.drawings[sha] = parse_drawing(data, filename)
    return reader.drawings[sha]
