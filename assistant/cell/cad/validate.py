"""Refuse meshes that cannot be used, repair what trimesh can, and say what was done.

Checks run on the raw numbers (NaN/inf, indices, emptiness) before units are applied, so the
operator hears about a broken file rather than a confusing unit guess; repairs run in metres
so tolerances mean the same for every file.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from assistant.cell.cad.errors import CadImportError

#: Faces with less area than this (m^2, i.e. 1e-6 mm^2) are degenerate slivers.
DEGENERATE_AREA_M2 = 1e-12
#: A mesh with more triangles than this is refused (memory, and no cell part needs it).
MAX_FACES = 5_000_000


@dataclass
class RepairReport:
    repairs: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


def check_raw(mesh: trimesh.Trimesh | None, filename: str) -> None:
    """Refuse empty meshes, non-finite coordinates and face indices pointing nowhere."""
    if mesh is None or len(mesh.faces) == 0:
        raise CadImportError(filename, "holds no triangles",
                             "the file is empty or damaged; export the part again")
    if len(mesh.faces) > MAX_FACES:
        raise CadImportError(
            filename, f"has {len(mesh.faces):,} triangles, more than the {MAX_FACES:,} allowed",
            "export it with a coarser tessellation, or simplify it in CAD")
    v = np.asarray(mesh.vertices)
    f = np.asarray(mesh.faces)
    if f.min() < 0 or f.max() >= len(v):
        raise CadImportError(
            filename, f"has faces referring to vertex {int(f.max())} but only {len(v)} vertices",
            "the file is damaged; export the part again")
    used = v[np.unique(f)]
    bad = ~np.isfinite(used).all(axis=1)
    if bad.any():
        raise CadImportError(
            filename, f"has {int(bad.sum())} vertex(es) with NaN or infinite coordinates",
            "the CAD export is broken; repair the part in CAD and export it again")
    if float(np.ptp(used, axis=0).max()) <= 0.0:
        raise CadImportError(filename, "is degenerate: all its vertices are the same point",
                             "export the part again")


def repair(mesh: trimesh.Trimesh, filename: str) -> tuple[trimesh.Trimesh, RepairReport]:
    """A cleaned copy (merged vertices, no degenerate/duplicate faces, consistent outward
    normals, small holes filled) and what was changed. Refuses zero-area meshes."""
    rep = RepairReport()
    m = trimesh.Trimesh(np.array(mesh.vertices, dtype=np.float64),
                        np.array(mesh.faces, dtype=np.int64), process=False)

    n_v = len(m.vertices)
    m.merge_vertices(merge_tex=True, merge_norm=True)
    if len(m.vertices) < n_v:
        # Normal for STL and tessellated CAD (every face has its own corners): not a repair.
        rep.notes.append(f"merged {n_v - len(m.vertices)} coincident vertices")

    n_f = len(m.faces)
    keep = m.nondegenerate_faces() & (m.area_faces > DEGENERATE_AREA_M2)
    if not keep.all():
        m.update_faces(keep)
        rep.repairs.append(f"removed {n_f - len(m.faces)} degenerate (zero-area) faces")
    if len(m.faces) == 0:
        raise CadImportError(filename, "is degenerate: every face has zero area",
                             "the part is flat or collapsed; export it again from CAD")

    n_f = len(m.faces)
    m.update_faces(m.unique_faces())
    if len(m.faces) < n_f:
        rep.repairs.append(f"removed {n_f - len(m.faces)} duplicate faces")
    m.remove_unreferenced_vertices()

    if not m.is_watertight:
        added = _fill_small_holes(m)
        if added:
            rep.repairs.append(f"filled small holes with {added} faces")

    faces_before = m.faces.copy()
    trimesh.repair.fix_normals(m, multibody=True)  # consistent winding, outward per body
    flipped = int(np.sum(np.any(m.faces != faces_before, axis=1)))
    if flipped:
        rep.repairs.append(f"fixed the winding/normals of {flipped} faces")

    if float(m.area) <= DEGENERATE_AREA_M2:
        raise CadImportError(filename, "is degenerate: its surface has no area",
                             "export the part again from CAD")
    if not m.is_watertight:
        rep.warnings.append("the mesh is open (not watertight): collision uses its surface, "
                            "and points inside it are not detected as inside")
    elif abs(m.volume) < 1e-15:
        rep.warnings.append("the mesh encloses no volume (a flat sheet)")
    return m, rep


def _fill_small_holes(m: trimesh.Trimesh) -> int:
    """trimesh's fill (3- and 4-edge holes), except on flat pieces: closing the rim of a flat
    sheet (a single 3DFACE, a plate drawn as one quad) would glue a back face onto it."""
    n_f = len(m.faces)
    labels = np.full(n_f, -1)
    for k, group in enumerate(trimesh.graph.connected_components(
            m.face_adjacency, nodes=np.arange(n_f), min_len=1)):
        labels[group] = k
    flat = {}
    for k in np.unique(labels):
        v = m.vertices[np.unique(m.faces[labels == k])]
        c = v - v.mean(axis=0)
        sv = np.linalg.svd(c, compute_uv=False) if len(v) >= 3 else np.zeros(3)
        flat[int(k)] = len(sv) < 3 or sv[-1] <= 1e-9 * max(float(sv[0]), 1e-30)
    vertex_label = np.full(len(m.vertices), -1)
    vertex_label[m.faces.ravel()] = np.repeat(labels, 3)

    candidate = m.copy()
    trimesh.repair.fill_holes(candidate)
    new = candidate.faces[n_f:]
    if len(new) == 0 or len(candidate.vertices) != len(m.vertices):
        return 0
    keep = np.array([not flat.get(int(vertex_label[f[0]]), True) for f in new], dtype=bool)
    if not keep.any():
        return 0
    m.faces = np.vstack([m.faces, new[keep]])
    return int(keep.sum())
