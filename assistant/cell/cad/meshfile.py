"""Triangle-mesh formats trimesh reads: STL, OBJ, PLY, GLB/glTF, 3MF.

Quirks handled here: multi-body scenes are flattened with each node's transform applied;
3MF and glTF state their unit (3MF: `unit` attribute, millimetres by default; glTF: metres by
specification, or trimesh's `units` extra), STL/OBJ/PLY have none; a .gltf from bytes cannot
reach external buffer files, so those are refused with advice rather than half-loaded.
Files are read with `process=False` so that NaN coordinates and bad indices reach validation
instead of being dropped silently.
"""

from __future__ import annotations

import io
import json

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
    """All triangles of an STL/OBJ/PLY/GLB/glTF/3MF file, node transforms applied."""
    if fmt == "gltf":
        _check_gltf_self_contained(data, filename)
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


def _check_gltf_self_contained(data: bytes, filename: str) -> None:
    """A .gltf given as bytes must embed its buffers (data: URIs); say so before trimesh fails."""
    try:
        header = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CadImportError(filename, f"is not valid glTF JSON ({exc})",
                             "export it again, or use the binary .glb form") from exc
    if not isinstance(header, dict):
        raise CadImportError(filename, "is not a glTF document (no JSON object at the top)",
                             "export it again, or use the binary .glb form")
    for kind in ("buffers",):
        for item in header.get(kind) or []:
            uri = item.get("uri") if isinstance(item, dict) else None
            if isinstance(uri, str) and not uri.startswith("data:"):
                raise CadImportError(
                    filename,
                    f"refers to an external file {uri!r} that was not uploaded with it",
                    "export as a single binary .glb, or as .gltf with embedded buffers",
                )
