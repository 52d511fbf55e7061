"""What a format reader hands back: triangles as the file has them, before units and repair.

Readers know their format's quirks (node transforms, declared units, outlines to extrude);
everything after that (units, validation, repair, collision proxy) is common and lives in
`assistant.cell.cad.importer`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import trimesh

Array = np.ndarray


@dataclass
class Outline:
    """Closed 2-D profiles (shapely polygons, file units) at height `z0`, waiting for a height.

    A DXF drawing often holds only a part's outline; it becomes a solid only once the operator
    says how thick the part is.
    """

    polygons: list  # list[shapely.geometry.Polygon], file units, in the plane z = z0
    z0: float = 0.0

    def bounds_size(self) -> float:
        xs = [p.bounds for p in self.polygons]
        b = np.array(xs, dtype=float)
        return float(max(b[:, 2].max() - b[:, 0].min(), b[:, 3].max() - b[:, 1].min()))

    def extrude(self, height: float) -> trimesh.Trimesh:
        """A solid of the given height (file units) above z0; several profiles are merged.

        Triangulated with manifold3d: earcut's bridges to several holes can reuse an edge,
        which leaves the solid non-watertight.
        """
        parts = [trimesh.creation.extrude_polygon(p, height, engine="manifold")
                 for p in self.polygons]
        mesh = merge_meshes(parts)
        mesh.apply_translation((0.0, 0.0, self.z0))
        return mesh


@dataclass
class RawGeometry:
    """Triangles in the file's own numbers, plus what the file says about its unit."""

    mesh: trimesh.Trimesh | None
    #: The length unit the file declares (normalised short name), None if it has none.
    file_units: str | None = None
    #: Set when the reader already converted the numbers to metres from this unit.
    converted_from: str | None = None
    bodies: int = 1
    outline: Outline | None = None
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


def merge_meshes(meshes: Sequence[trimesh.Trimesh]) -> trimesh.Trimesh:
    """One mesh from many, vertex order kept, no processing (repair comes later, on purpose)."""
    verts, faces, offset = [], [], 0
    for m in meshes:
        v = np.asarray(m.vertices, dtype=np.float64).reshape(-1, 3)
        f = np.asarray(m.faces, dtype=np.int64).reshape(-1, 3)
        verts.append(v)
        faces.append(f + offset)
        offset += len(v)
    if not verts:
        return trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), process=False)
    return trimesh.Trimesh(np.vstack(verts), np.vstack(faces), process=False)
