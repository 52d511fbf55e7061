"""A cell-layout drawing: one DXF holding several parts and the locations attached to them.

The thesis (source 003, section 10.2 and Table 11) imports its parts "by absolute data of the
DXF file" and reads start and goal "from the locations attached to the CAD objects", which
makes placing the parts and teaching those locations cost the operator nothing. A DXF is a
cell layout when it has a layer named `LOCATIONS`:

* every other layer holding geometry is one part, named after its layer (layer "0" after the
  file), drawn in cell coordinates (the robot base's frame), so it is placed as drawn;
* every TEXT or MTEXT on `LOCATIONS` is a location at the text's insertion point, labelled
  `NAME [start|goal] [A B C]` (A, B, C in degrees, default 0 0 180: the tool pointing down).

Each part is the file read with `ImportOptions.dxf_layer` set to its layer, so it takes the
ordinary import path (units, repair, collision proxy) and a saved cell re-imports it the same
way; on import the parts share the one parsed drawing `read_layout` read (`document`). The
locations are in drawing units, scaled like the parts.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from assistant.cell.cad.dxf import read_document
from assistant.cell.cad.errors import CadImportError
from assistant.cell.cad.formats import CadFormat
from assistant.cell.cad.precheck import check_before_parsing
from assistant.cell.cad.validate import MAX_FACES

LOCATION_LAYER = "LOCATIONS"
#: The tool pointing down, as typed poses default to.
TOOL_DOWN_ABC_DEG = (0.0, 0.0, 180.0)
_ROLES = ("start", "goal")
_LABEL_HINT = "label each location 'NAME [start|goal] [A B C]', e.g. 'P1 start' or 'P7 0 0 180'"


@dataclass(frozen=True)
class LayoutLocation:
    """A labelled point of the drawing (drawing units; angles in degrees as written)."""

    name: str
    xyz: tuple[float, float, float]
    abc_deg: tuple[float, float, float]
    role: str | None  # "start", "goal" or None


@dataclass
class CellLayout:
    """The parts (part name -> its layer) and the labelled locations."""

    parts: dict[str, str]
    locations: list[LayoutLocation]
    notes: list[str] = field(default_factory=list)
    #: The parsed drawing (an ezdxf document) the parts are read from (`load_cad`'s
    #: `dxf_document`): the file is parsed once for its layout and all its parts.
    document: Any = field(default=None, repr=False, compare=False)


def might_be_layout(data: bytes, filename: str) -> bool:
    """Cheap first look (no parsing): a DXF mentioning a LOCATIONS layer."""
    return Path(filename).suffix.lower() == ".dxf" and \
        re.search(rb"(?im)^\s*" + LOCATION_LAYER.encode() + rb"\s*$", data) is not None


def read_layout(data: bytes, filename: str) -> CellLayout | None:
    """The layout of a DXF with a LOCATIONS layer; None for an ordinary one-part drawing."""
    if not might_be_layout(data, filename):
        return None
    doc = parse_drawing(data, filename)
    msp = doc.modelspace()
    by_layer: dict[str, list] = {}
    for e in msp:
        by_layer.setdefault(str(e.dxf.get("layer", "0")), []).append(e)
    loc_layer = next((k for k in by_layer if k.upper() == LOCATION_LAYER), None)
    if loc_layer is None:
        return None
    layout = CellLayout(parts={}, locations=[], document=doc)
    for e in by_layer.pop(loc_layer):
        if e.dxftype() not in ("TEXT", "MTEXT"):
            layout.notes.append(f"a {e.dxftype()} on {LOCATION_LAYER} was ignored "
                                "(locations are labelled texts)")
            continue
        layout.locations.append(_location(e, filename))
    names = [loc.name.upper() for loc in layout.locations]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise CadImportError(filename, f"names {', '.join(dup)} more than once on "
                             f"{LOCATION_LAYER}", "give every location its own name")
    for role in _ROLES:
        marked = [loc.name for loc in layout.locations if loc.role == role]
        if len(marked) > 1:
            raise CadImportError(filename, f"marks {', '.join(marked)} all as the {role}",
                                 f"mark one location as the {role}")
    stem = Path(filename).stem
    for layer, entities in by_layer.items():
        name = stem if layer == "0" else layer
        if any(e.dxftype() not in ("TEXT", "MTEXT", "POINT") for e in entities):
            layout.parts[name] = layer
    if not layout.parts:
        raise CadImportError(filename, "has locations but no part geometry",
                             "draw the parts on layers of their own beside LOCATIONS")
    return layout


def parse_drawing(data: bytes, filename: str) -> Any:
    """A layout's drawing parsed once for all its parts (`CellLayout.document`), sized up
    before ezdxf reads it (`CadImportError` when too large or unreadable)."""
    check_before_parsing(data, filename, CadFormat.DXF, MAX_FACES)
    return read_document(data, filename)


def _location(e, filename: str) -> LayoutLocation:
    if e.dxftype() == "TEXT":
        text = e.dxf.text
        xyz = e.ocs().to_wcs(e.dxf.insert)
    else:
        text = e.plain_text()
        xyz = e.dxf.insert
    tokens = [t for t in re.split(r"[\s,;]+", str(text).strip()) if t]
    if not tokens:
        raise CadImportError(filename, f"has an empty label on {LOCATION_LAYER}", _LABEL_HINT)
    name, rest = tokens[0], tokens[1:]
    role = None
    if rest and rest[0].lower() in _ROLES:
        role, rest = rest[0].lower(), rest[1:]
    if not rest:
        abc = TOOL_DOWN_ABC_DEG
    else:
        try:
            values = tuple(float(t) for t in rest)
        except ValueError:
            values = ()
        if len(values) != 3:
            raise CadImportError(filename, f"cannot read the location label {text!r}",
                                 _LABEL_HINT)
        abc = values  # type: ignore[assignment]
    return LayoutLocation(name, (float(xyz[0]), float(xyz[1]), float(xyz[2])), abc, role)
