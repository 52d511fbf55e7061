"""What a CAD file will cost, judged from its bytes before any reader parses it.

A reader's memory grows with what the file expands to, not with its size: a 2 MB 3MF can
inflate to gigabytes of XML, a glTF accessor without data becomes an array of zeros as long
as it declares, and 10 million triangles take more memory than an import may. So before a
reader runs, each format is sized from what it states:

- binary STL: the triangle count of its header (and the file must be that long);
  ASCII STL, OBJ, DXF: the facet / face / 3DFACE lines counted (one pass over the bytes);
  PLY: the header's face element;
- GLB/glTF: the JSON part (size, nesting depth), no external buffers, the bytes every
  accessor implies against the bytes the file holds, triangles from the primitives;
- 3MF (a zip): its directory through `file_guard.check_archive` (total and ratio), then the
  model's triangles counted while inflating it in blocks (never all of it at once).

STEP is sized only by its file (its triangles exist only after tessellation, and are counted
then, like every format's). Raises `CadImportError` naming the file, the figure and the limit.
"""

from __future__ import annotations

import re
import struct
import zipfile

from assistant.cell.cad.errors import CadImportError
from assistant.cell.cad.formats import CadFormat
from assistant.file_guard import FileRefused, load_json, open_zip

#: The most triangles an import takes (see `validate.MAX_FACES` for why).
#: DXF entities are read one Python object each (ezdxf): ~1 KB and ~50 us per face.
DXF_MAX_FACES = 250_000
#: A glTF's JSON part and what its accessors may imply beyond the bytes the file holds.
GLTF_MAX_JSON_BYTES = 64 * 2**20
GLTF_MAX_IMPLIED_RATIO = 4.0
#: A 3MF inflates to at most this much (its XML holds ~100 bytes a triangle).
THREEMF_MAX_EXPANDED = 1024 * 2**20

_BLOCK = 16 * 2**20
_TRIANGLE_TAG = re.compile(rb"<(?:[A-Za-z_][\w.-]{0,31}:)?triangle[\s/>]")
_PLY_FACES = re.compile(rb"element\s+face\s+(\d+)")
_COMPONENTS = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_TYPES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def check_before_parsing(data: bytes, filename: str, fmt: CadFormat, max_faces: int) -> None:
    """Refuse a file whose reader would take more than an import may (see the module doc)."""
    if fmt == CadFormat.STL:
        n, how = _stl_triangles(data), "triangles"
    elif fmt == CadFormat.OBJ:
        n, how = _lines_starting(data, b"f"), "faces"
    elif fmt == CadFormat.PLY:
        m = _PLY_FACES.search(data[:65536])
        n, how = (int(m.group(1)) if m else 0), "faces"
    elif fmt in (CadFormat.GLB, CadFormat.GLTF):
        n, how = gltf_triangles(data, filename, fmt), "triangles"
    elif fmt == CadFormat.THREEMF:
        n, how = _threemf_triangles(data, filename, max_faces), "triangles"
    elif fmt == CadFormat.DXF:
        n, how = 2 * _lines_starting(data, b"3DFACE"), "triangles (3-D faces)"
        if n > DXF_MAX_FACES:
            raise CadImportError(
                filename, f"holds about {n:,} {how}, more than the {DXF_MAX_FACES:,} a DXF "
                          "import reads (DXF entities are read one by one)",
                "export the part as binary STL, 3MF or STEP instead")
    else:
        return
    if n > max_faces:
        raise too_many(filename, n, max_faces, how)


def too_many(filename: str, n: int, max_faces: int, how: str = "triangles", *,
             parsed: bool = False) -> CadImportError:
    """The refusal of a part with too many triangles, saying what to do."""
    when = "" if parsed else " (refused before reading it)"
    return CadImportError(
        filename, f"has {n:,} {how}, more than the {max_faces:,} an import takes{when}",
        "export it with a coarser tessellation (a larger chordal tolerance), decimate it "
        "(e.g. Blender's Decimate, MeshLab's quadric edge collapse), or leave out small "
        "details such as screws and text, then import it again")


def _stl_triangles(data: bytes) -> int:
    """The triangle count of a binary STL (its header, checked against its length), else
    the facets of an ASCII one."""
    if len(data) >= 84:
        (n,) = struct.unpack("<I", data[80:84])
        if len(data) == 84 + 50 * n:
            return n
    return data.count(b"endfacet")


def _lines_starting(data: bytes, word: bytes) -> int:
    """Lines whose first token is `word` (OBJ faces, DXF entity names), in one pass."""
    count = data.count(b"\n" + word + b" ") + data.count(b"\n" + word + b"\r") + \
        data.count(b"\n" + word + b"\n") + data.count(b"\n" + word + b"\t")
    return count + (1 if data.startswith(word) else 0)


def gltf_triangles(data: bytes, filename: str, fmt: CadFormat) -> int:
    """Triangles a GLB/glTF declares, after checking what its accessors would allocate."""
    if fmt == CadFormat.GLB:
        if len(data) < 20 or data[:4] != b"glTF":
            return 0  # not a GLB: the reader says so
        (length,) = struct.unpack("<I", data[12:16])
        if data[16:20] != b"JSON" or length > len(data) - 20:
            return 0
        text = data[20:20 + length]
    else:
        text = data
    try:
        doc = load_json(text, what="glTF JSON", limit=GLTF_MAX_JSON_BYTES)
    except FileRefused as exc:
        problem = exc.problem.replace("the glTF JSON is not valid JSON", "is not valid glTF JSON")
        raise CadImportError(filename, problem,
                             "export it again, or use the binary .glb form") from None
    if not isinstance(doc, dict):
        raise CadImportError(filename, "is not a glTF document (no JSON object at the top)",
                             "export it again, or use the binary .glb form")
    for item in doc.get("buffers") or []:
        uri = item.get("uri") if isinstance(item, dict) else None
        if isinstance(uri, str) and not uri.startswith("data:"):
            raise CadImportError(
                filename, f"refers to an external file {uri!r} that was not uploaded with it",
                "export as a single binary .glb, or as .gltf with embedded buffers")
    accessors = [a for a in doc.get("accessors") or [] if isinstance(a, dict)]
    implied = 0
    for a in accessors:
        count, size = a.get("count"), _TYPES.get(a.get("type"), 16)
        comp = _COMPONENTS.get(a.get("componentType"), 8)
        if not isinstance(count, int) or count < 0:
            raise CadImportError(filename, f"has an accessor with count {count!r}",
                                 "the file is damaged; export it again")
        implied += count * size * comp
    limit = max(GLTF_MAX_IMPLIED_RATIO * len(data), 2**20)
    if implied > limit:
        raise CadImportError(
            filename, f"declares arrays of {implied / 2**20:,.0f} MiB in a file of "
                      f"{len(data) / 2**20:,.1f} MiB (they would be made before reading; a "
                      "compressed or damaged glTF)",
            "export it again without mesh compression (Draco/meshopt), or as binary STL")
    per_mesh = []
    for mesh in doc.get("meshes") or []:
        n = 0
        for prim in (mesh.get("primitives") or []) if isinstance(mesh, dict) else []:
            if not isinstance(prim, dict) or prim.get("mode", 4) not in (4, 5, 6):
                continue
            ref = prim.get("indices")
            if ref is None:
                ref = (prim.get("attributes") or {}).get("POSITION")
            if isinstance(ref, int) and 0 <= ref < len(accessors):
                count = accessors[ref].get("count", 0)
                n += count // 3 if prim.get("mode", 4) == 4 else max(0, count - 2)
        per_mesh.append(n)
    # the reader flattens the scene: a mesh counts once for every node that shows it
    shown = [n.get("mesh") for n in doc.get("nodes") or [] if isinstance(n, dict)]
    shown = [m for m in shown if isinstance(m, int) and 0 <= m < len(per_mesh)]
    return sum(per_mesh[m] for m in shown) if shown else sum(per_mesh)


def _threemf_triangles(data: bytes, filename: str, max_faces: int) -> int:
    """Triangles in a 3MF's model parts, counted while inflating them block by block; stops
    counting once past `max_faces`."""
    try:
        zf = open_zip(data, what="3MF archive", max_total=THREEMF_MAX_EXPANDED)
    except FileRefused as exc:
        if "not a valid zip" in exc.problem:
            return 0  # the reader says it cannot be read as 3MF
        raise CadImportError(filename, exc.problem, exc.advice) from None
    total = 0
    with zf:
        for info in zf.infolist():
            if not info.filename.lower().endswith(".model"):
                continue
            tail = b""
            try:
                with zf.open(info) as member:
                    while total <= max_faces:
                        block = member.read(_BLOCK)
                        if not block:
                            break
                        chunk = tail + block
                        # tags wholly inside the carried-over tail were counted before
                        total += len(_TRIANGLE_TAG.findall(chunk)) - \
                            len(_TRIANGLE_TAG.findall(tail))
                        tail = chunk[-64:]
            except (zipfile.BadZipFile, OSError, EOFError, RuntimeError) as exc:
                raise CadImportError(filename, f"could not be read as 3MF ({exc})",
                                     "the file may be truncated or damaged; export it "
                                     "again") from None
    return total
