"""DXF drawings through ezdxf: 3-D faces as a mesh, or a closed 2-D outline to extrude.

Quirks: trimesh reads DXF only as 2-D paths, so the 3-D entities (3DFACE, POLYFACE and
POLYMESH polylines, MESH) are read with ezdxf, block references expanded with their
transforms. The unit is the header's $INSUNITS (0 = unitless). A drawing with no 3-D faces
may hold a part's outline (closed polylines, circles, or chains of lines and arcs); it becomes
a solid only with a thickness from the operator, since a flat drawing does not say how thick
the part is. ACIS solids (3DSOLID, BODY, REGION) are opaque to us and reported as such.
Binary DXF is read through ezdxf's plain file reader, the only one that detects it.
"""

from __future__ import annotations

import io
import tempfile
from pathlib import Path
from typing import Any

import ezdxf
import numpy as np
import trimesh
from ezdxf import disassemble, recover

from assistant.cell.cad.errors import CadImportError
from assistant.cell.cad.options import ImportOptions
from assistant.cell.cad.raw import Outline, RawGeometry

#: $INSUNITS codes we accept, by our short unit names (others fall back to the size guess).
_INSUNITS = {1: "inch", 2: "ft", 4: "mm", 5: "cm", 6: "m", 13: "um", 14: "dm"}
_CURVES = {"LWPOLYLINE", "CIRCLE", "ARC", "LINE", "ELLIPSE", "SPLINE"}
_ACIS = {"3DSOLID", "BODY", "REGION", "SURFACE"}
_BINARY_SENTINEL = b"AutoCAD Binary DXF"


def read_dxf(data: bytes, filename: str, options: ImportOptions, *,
             document: Any = None) -> RawGeometry:
    """Faces of a DXF's model space (or its closed outlines) in drawing units.
    `document`: these bytes already parsed (a cell layout's parts share one reading)."""
    doc = document if document is not None else read_document(data, filename)

    raw = RawGeometry(mesh=None)
    try:
        code = int(doc.header.get("$INSUNITS", 0) or 0)
    except (TypeError, ValueError):
        code = 0
    raw.file_units = _INSUNITS.get(code)
    if code and raw.file_units is None:
        raw.warnings.append(f"unusual drawing unit ($INSUNITS={code}) ignored; "
                            "the unit is guessed from the size")

    try:
        triangles, curves, acis, open_polylines = _collect(doc, options.dxf_layer)
    except Exception as exc:  # odd entities or broken block references in untrusted data
        raise CadImportError(filename, f"its entities could not be interpreted ({exc})",
                             "the drawing may be damaged; export it again") from exc

    if acis:
        raw.warnings.append(f"{acis} ACIS solid(s) (3DSOLID/BODY/REGION) cannot be read and were "
                            "skipped; export those bodies as STEP or STL")
    if open_polylines:
        raw.notes.append(f"ignored {open_polylines} 3-D polyline(s) (wires, not surfaces)")
    if triangles:
        tri = np.stack(triangles)
        raw.mesh = trimesh.Trimesh(tri.reshape(-1, 3), np.arange(len(tri) * 3).reshape(-1, 3),
                                   process=False)
        if curves:
            raw.notes.append(f"the drawing has 3-D faces; {len(curves)} 2-D curve(s) ignored")
        return raw

    if not curves:
        hint = " (only ACIS solids)" if acis else ""
        raise CadImportError(filename, f"holds no 3-D faces and no outlines{hint}",
                             "export the part as 3-D faces/mesh, or as STEP or STL")
    try:
        raw.outline = _outline_from_curves(curves, filename, raw)
    except CadImportError:
        raise
    except Exception as exc:  # shapely/ezdxf on odd curves
        raise CadImportError(filename, f"its 2-D outline could not be traced ({exc})",
                             "clean up the outline in CAD, or export the part in 3-D") from exc
    if options.dxf_extrude_height is None:
        n = len(raw.outline.polygons)
        raise CadImportError(
            filename,
            f"is a 2-D drawing: {n} closed outline(s) but no 3-D faces",
            "give the part's thickness (dxf_extrude_height) to extrude the outline, "
            "or export the part in 3-D",
        )
    return raw


def _collect(doc, layer: str | None = None) -> tuple[list[np.ndarray], list, int, int]:
    """Triangles of the 3-D entities, the 2-D curves, and counts of what cannot be used
    (of one layer only, for a part of a cell-layout drawing)."""
    triangles: list[np.ndarray] = []
    curves = []
    acis = 0
    open_polylines = 0
    entities = doc.modelspace() if layer is None else \
        [e for e in doc.modelspace() if str(e.dxf.get("layer", "0")) == layer]
    for e in disassemble.recursive_decompose(entities):
        kind = e.dxftype()
        if kind == "3DFACE":
            v = np.array([tuple(p) for p in e.wcs_vertices()], dtype=float)
            if len(v) >= 3:
                triangles.append(v[[0, 1, 2]])
                if len(v) == 4:
                    triangles.append(v[[0, 2, 3]])
        elif kind == "POLYLINE" and (e.is_poly_face_mesh or e.is_polygon_mesh):
            triangles.extend(_builder_triangles(_mesh_builder(e, polyface=True)))
        elif kind == "MESH":
            triangles.extend(_builder_triangles(_mesh_builder(e, polyface=False)))
        elif kind == "POLYLINE" and e.is_2d_polyline:
            curves.append(e)
        elif kind == "POLYLINE":
            open_polylines += 1
        elif kind in _CURVES:
            curves.append(e)
        elif kind in _ACIS:
            acis += 1
    return triangles, curves, acis, open_polylines


def read_document(data: bytes, filename: str) -> Any:
    """The parsed drawing (an ezdxf document), or `CadImportError` saying why not."""
    if not (data.startswith(_BINARY_SENTINEL) or b"SECTION" in data[:65536]):
        raise CadImportError(filename, "is not a DXF file (no DXF sections found)",
                             "export the drawing again as DXF")
    try:
        return _read_document(data)
    except Exception as exc:  # a parser of untrusted bytes: any failure means "unreadable"
        raise CadImportError(filename, f"could not be read as DXF ({exc})",
                             "the file may be truncated or damaged; export it again") from exc


def _read_document(data: bytes) -> Any:
    """ASCII DXF from memory with the forgiving reader; binary DXF only through ezdxf's plain
    file reader (the recover module does not read binary), via a temporary file."""
    if not data.startswith(_BINARY_SENTINEL):
        return recover.read(io.BytesIO(data))[0]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "drawing.dxf"
        path.write_bytes(data)
        return ezdxf.readfile(str(path))


def _mesh_builder(entity, *, polyface: bool):
    from ezdxf.render import MeshBuilder

    return MeshBuilder.from_polyface(entity) if polyface else MeshBuilder.from_mesh(entity)


def _builder_triangles(builder) -> list[np.ndarray]:
    out = []
    for face in builder.tessellation(max_vertex_count=3):
        v = np.array([tuple(p) for p in face], dtype=float)
        if len(v) == 3:
            out.append(v)
    return out


def _outline_from_curves(curves: list, filename: str, raw: RawGeometry) -> Outline:
    """Closed regions formed by the curves, material where nested an even number of times."""
    import shapely
    from ezdxf import path as dxfpath
    from shapely.geometry import LineString, Polygon
    from shapely.ops import polygonize_full, unary_union

    paths = []
    for e in curves:
        try:
            p = dxfpath.make_path(e)
        except (TypeError, ValueError):
            continue
        if len(p) or p.has_sub_paths:
            paths.append(p)
    pts = [np.array([tuple(v) for v in p.control_vertices()], dtype=float) for p in paths]
    pts = [a for a in pts if len(a)]
    if not pts:
        raise CadImportError(filename, "holds no 3-D faces and no usable outlines",
                             "export the part as 3-D faces/mesh, or as STEP or STL")
    allp = np.vstack(pts)
    extent = float(np.max(allp.max(axis=0) - allp.min(axis=0)))
    if not np.isfinite(extent) or extent <= 0.0:
        raise CadImportError(filename, "its outline has no size", "check the drawing")
    flat_tol = extent * 1e-4
    lines = []
    zs = []
    for p in paths:
        for sub in (p.sub_paths() if p.has_sub_paths else [p]):
            v = np.array([tuple(q) for q in sub.flattening(flat_tol)], dtype=float)
            if len(v) >= 2:
                zs.append(v[:, 2])
                lines.append(LineString(v[:, :2]))
    z = np.concatenate(zs) if zs else np.zeros(1)
    if np.ptp(z) > extent * 1e-6:
        raise CadImportError(filename, "its 2-D outline is not flat in the XY plane",
                             "draw the outline in the XY plane, or export the part in 3-D")
    grid = extent * 1e-7
    lines = [shapely.set_precision(line, grid) for line in lines]
    faces, cuts, dangles, invalid = polygonize_full(unary_union(lines))
    loose = len(getattr(cuts, "geoms", [])) + len(getattr(dangles, "geoms", []))
    regions = [g for g in getattr(faces, "geoms", []) if g.area > 0.0]
    if not regions:
        raise CadImportError(
            filename,
            f"has only open lines ({len(lines)} curve(s)) and no closed outline",
            "close the part's outline in CAD (or export the part in 3-D)",
        )
    if loose:
        raw.warnings.append(f"{loose} open line piece(s) not part of a closed outline ignored")
    shells = [Polygon(r.exterior) for r in regions]
    material = []
    for i, r in enumerate(regions):
        inside = r.representative_point()
        depth = sum(1 for j, s in enumerate(shells) if j != i and s.contains(inside))
        if depth % 2 == 0:
            material.append(r)
    merged = unary_union(material)
    polys = [g for g in getattr(merged, "geoms", [merged]) if isinstance(g, Polygon) and g.area]
    raw.notes.append(f"{len(polys)} closed outline(s) found in the 2-D drawing")
    return Outline(polygons=polys, z0=float(z.mean()))
