"""Which CAD formats we read, recognised by file suffix (their readers: `importer.reader_for`)."""

from __future__ import annotations

from enum import Enum
from pathlib import PurePath

from assistant.cell.cad.errors import CadImportError


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
