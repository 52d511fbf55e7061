"""Which CAD formats we read, recognised by file suffix, and which reader handles each."""

from __future__ import annotations

from collections.abc import Callable
from enum import Enum
from pathlib import PurePath

from assistant.cell.cad.errors import CadImportError
from assistant.cell.cad.options import ImportOptions
from assistant.cell.cad.raw import RawGeometry


class CadFormat(str, Enum):
    STL = "stl"
    OBJ = "obj"
    PLY = "ply"
    GLB = "glb"
    GLTF = "gltf"
    THREEMF = "3mf"
    DXF = "dxf"
    STEP = "step"


_SUFFIXES: dict[str, CadFormat] = {
    ".stl": CadFormat.STL,
    ".obj": CadFormat.OBJ,
    ".ply": CadFormat.PLY,
    ".glb": CadFormat.GLB,
    ".gltf": CadFormat.GLTF,
    ".3mf": CadFormat.THREEMF,
    ".dxf": CadFormat.DXF,
    ".step": CadFormat.STEP,
    ".stp": CadFormat.STEP,
}

SUPPORTED_SUFFIXES = tuple(_SUFFIXES)


def format_from_filename(filename: str) -> CadFormat:
    """The format a file name's suffix announces (case-insensitive)."""
    suffix = PurePath(filename).suffix.lower()
    try:
        return _SUFFIXES[suffix]
    except KeyError:
        raise CadImportError(
            filename,
            f"unsupported file type {suffix or '(no suffix)'!r}",
            "export the part as one of " + ", ".join(SUPPORTED_SUFFIXES),
        ) from None


def reader_for(fmt: CadFormat) -> Callable[[bytes, str, ImportOptions], RawGeometry]:
    """The reader function for a format (imported lazily: STEP pulls in OpenCASCADE)."""
    if fmt == CadFormat.DXF:
        from assistant.cell.cad.dxf import read_dxf

        return read_dxf
    if fmt == CadFormat.STEP:
        from assistant.cell.cad.step import read_step

        return read_step
    from assistant.cell.cad.meshfile import read_mesh_file

    return lambda data, filename, options: read_mesh_file(data, filename, fmt.value, options)
