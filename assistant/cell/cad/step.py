"""STEP (ISO 10303-21) through cascadio, the OpenCASCADE wheel that trimesh also uses.

Quirks: OpenCASCADE reads the file's own length unit and hands back a glTF in metres, so the
numbers arrive already converted; the unit is still parsed from the text to report what the
file said (and to rescale if the operator overrides it). The tessellation tolerance is in
OpenCASCADE's working unit, millimetres, whatever the file's unit. Meshing runs single-threaded
so that the same file always gives the same vertices (a saved cell re-imports it).
"""

from __future__ import annotations

import re

from assistant.cell.cad.errors import CadImportError
from assistant.cell.cad.formats import CadFormat
from assistant.cell.cad.meshfile import read_mesh_file
from assistant.cell.cad.options import ImportOptions
from assistant.cell.cad.precheck import gltf_triangles
from assistant.cell.cad.raw import RawGeometry
from assistant.cell.cad.validate import MAX_FACES

ANGULAR_TOLERANCE_RAD = 0.5

_ENTITY = re.compile(r"#(\d+)\s*=\s*(.*?);\s*(?=#\d+\s*=|ENDSEC)", re.S)
_SI_LENGTH = re.compile(r"SI_UNIT\s*\(\s*(\$|\.[A-Z]+\.)\s*,\s*\.METRE\.\s*\)")
_CONVERSION = re.compile(r"CONVERSION_BASED_UNIT\s*\(\s*'([^']*)'")
_SI_PREFIX = {"$": "m", ".MILLI.": "mm", ".CENTI.": "cm", ".DECI.": "dm", ".MICRO.": "um"}
_CONVERTED = {"INCH": "inch", "INCHES": "inch", "FOOT": "ft", "FEET": "ft"}


def read_step(data: bytes, filename: str, options: ImportOptions) -> RawGeometry:
    """Tessellate a STEP file; the mesh comes back in metres (see module doc)."""
    head = data[:4096].lstrip()
    if not head.startswith(b"ISO-10303-21"):
        raise CadImportError(filename, "is not a STEP file (it does not start with ISO-10303-21)",
                             "export the part again as STEP AP203/AP214/AP242")
    import cascadio

    glb = cascadio.load(
        data, file_type="step", tol_linear=options.step_tolerance_m * 1000.0,
        tol_angular=ANGULAR_TOLERANCE_RAD, tol_relative=False, merge_primitives=True,
        use_parallel=False,
    )
    if not glb:
        raise CadImportError(filename, "OpenCASCADE could not read or mesh this STEP file",
                             "the file may be truncated or damaged; export it again from CAD")
    # Its triangles exist only now: counted from the tessellation before it is read.
    n = gltf_triangles(glb, filename, CadFormat.GLB)
    if n > MAX_FACES:
        raise CadImportError(
            filename, f"tessellates to {n:,} triangles, more than the {MAX_FACES:,} an "
                      "import takes",
            "import it again with a coarser STEP tolerance, or leave out small details "
            "(screws, text) in CAD")
    try:
        raw = read_mesh_file(glb, filename, "glb")
    except CadImportError as exc:
        raise CadImportError(filename, "the STEP file holds no solid or surface geometry",
                             "export the bodies (not only sketches or wires) as STEP") from exc
    declared = step_length_unit(data)
    raw.converted_from = declared or "m"
    raw.file_units = declared or "m"
    if declared is None:
        raw.notes.append("no length unit recognised in the STEP text; OpenCASCADE's "
                         "conversion to metres was kept")
    return raw


def step_length_unit(data: bytes) -> str | None:
    """The length unit of the file's global unit context, e.g. 'mm' (None if not found)."""
    text = data.decode("latin-1", errors="replace")
    entities = {int(m.group(1)): m.group(2) for m in _ENTITY.finditer(text)}
    for body in entities.values():
        if "GLOBAL_UNIT_ASSIGNED_CONTEXT" not in body:
            continue
        refs = re.search(r"GLOBAL_UNIT_ASSIGNED_CONTEXT\s*\(\s*\(([^)]*)\)", body)
        if not refs:
            continue
        for ref in re.findall(r"#(\d+)", refs.group(1)):
            unit = _length_unit_of(entities.get(int(ref), ""))
            if unit:
                return unit
    return None


def _length_unit_of(body: str) -> str | None:
    if "LENGTH_UNIT" not in body:
        return None
    conv = _CONVERSION.search(body)
    if conv:
        return _CONVERTED.get(conv.group(1).strip().upper())
    si = _SI_LENGTH.search(body)
    if si:
        return _SI_PREFIX.get(si.group(1))
    return None
