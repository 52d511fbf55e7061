"""Triangle-mesh formats trimesh reads: STL, OBJ, PLY, GLB/glTF, 3MF.

Quirks handled here: multi-body scenes are flattened with each node's transform applied;
3MF and glTF state their unit (3MF: `unit` attribute, millimetres by default; glTF: metres by
specification, or trimesh's `units` extra), STL/OBJ/PLY have none; a .gltf from bytes cannot
reach external buffer files, so those are refused with advice rather than half-loaded.
Files are read with `process=False` so that NaN coordinates and bad indices reach validation
instead of being dropped silently. A binary STL is read straight into arrays (no scene, no
per-triangle normals: a third of the memory trimesh's reader takes on millions of triangles).
"""

from __future__ import annotations

import io
import struct

import numpy as np
import trimesh

from assistant.cell.cad.errors import CadImportError
from assistant.cell.cad.options import ImportOptions
from assistant.cell.cad.raw import RawGeometry, merge_meshes
from assistant.cell.cad.units import UNIT_TO_M, normalize_unit

#: Formats whose files declare a unit (others carry bare numbers).
_FORMATS_WITH_UNITS = {"glb", "gltf", "3mf"}


def read_mesh_file(data: bytes, filename: str, fmt: str,
                   options: ImportOptions | None = None) -> RawGeometry:
    """All triangles of an STL/OBJ/PLY/GLB/glTF/3MF file, node transforms applied.
    The file has passed `precheck.check_before_parsing`."""
    if fmt == "stl":
        soup = binary_stl_triangles(data)
        if soup is not None:
            return RawGeometry(mesh=_soup_mesh(soup), bodies=1)
    try:
        scene = trimesh.load_scene(io.BytesIO(data), file_type=fmt, process=False)
    except Exception as exc:  # trimesh raises many types for damaged files
        raise CadImportError(
            filename,
            f"could not be read as {fmt.upper()} ({type(exc).__name__}: {exc})",
            "the file may be truncated or damaged; export it again from CAD",
        ) from exc

    meshes: list[trimesh.Trimesh] = []
    units: list[str | None] = []
    skipped = 0
    for node in scene.graph.nodes_geometry:
        T_file_node, geom_name = scene.graph[node]
        geom = scene.geometry.get(geom_name)
        if not isinstance(geom, trimesh.Trimesh):
            skipped += 1
            continue
        m = trimesh.Trimesh(np.array(geom.vertices, dtype=np.float64),
                            np.array(geom.faces, dtype=np.int64), process=False)
        if len(m.faces) == 0:
            continue
        if not np.allclose(T_file_node, np.eye(4)):
            m.apply_transform(T_file_node)
        meshes.append(m)
        units.append(geom.metadata.get("units") if isinstance(geom.metadata, dict) else None)

    if not meshes:
        what = " (it holds only points or lines)" if skipped else ""
        raise CadImportError(
            filename,
            f"no triangle faces found{what}",
            f"the file is empty, damaged or not a valid {fmt.upper()} file; export the "
            "part again as a surface or solid mesh",
        )

    raw = RawGeometry(mesh=None, bodies=len(meshes))
    if skipped:
        raw.notes.append(f"ignored {skipped} non-surface element(s) (points/lines)")
    if fmt in _FORMATS_WITH_UNITS:
        scene_units = scene.metadata.get("units") if isinstance(scene.metadata, dict) else None
        if fmt == "3mf":
            units = [scene_units or "mm"] * len(meshes)
        else:
            units = [u or scene_units or "m" for u in units]
        norm = [normalize_unit(u, filename=filename) for u in units]
        raw.file_units = norm[0]
        for i, u in enumerate(norm):
            if u != raw.file_units:
                # Bodies in different units: bring all to the first body's unit.
                meshes[i].apply_scale(UNIT_TO_M[u] / UNIT_TO_M[raw.file_units])
                raw.notes.append(f"body {i} was in {u}; converted to {raw.file_units}")
    raw.mesh = merge_meshes(meshes)
    if len(meshes) > 1:
        raw.notes.append(f"merged {len(meshes)} bodies into one mesh")
    return raw


_STL_RECORD = np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def binary_stl_triangles(data: bytes) -> np.ndarray | None:
    """(n, 3, 3) float32 corners of a binary STL, or None if the bytes are not one (the
    header's count must match the length; an ASCII STL is left to trimesh)."""
    if len(data) < 84:
        return None
    (n,) = struct.unpack("<I", data[80:84])
    if n == 0 or len(data) != 84 + 50 * n:
        return None
    return np.frombuffer(data, dtype=_STL_RECORD, count=n, offset=84)["v"]


def _soup_mesh(corners: np.ndarray) -> trimesh.Trimesh:
    """Every triangle with its own three vertices (merged later, in repair)."""
    v = corners.reshape(-1, 3).astype(np.float64)
    f = np.arange(len(v), dtype=np.int64).reshape(-1, 3)
    return trimesh.Trimesh(v, f, process=False)
