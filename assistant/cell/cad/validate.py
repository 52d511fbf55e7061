"""Refuse meshes that cannot be used, repair what trimesh can, and say what was done.

Checks run on the raw numbers (NaN/inf, indices, emptiness) before units are applied, so the
operator hears about a broken file rather than a confusing unit guess; repairs run in metres
so tolerances mean the same for every file.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from assistant.cell.cad import mesh_ops as ops
from assistant.cell.cad.errors import CadImportError
from assistant.cell.cad.precheck import too_many
from assistant.progress import Progress

#: Faces with less area than this (m^2, i.e. 1e-6 mm^2) are degenerate slivers.
DEGENERATE_AREA_M2 = 1e-12
#: A mesh with more triangles than this is refused, before parsing where its file says how
#: many it holds (`precheck`). Time and memory grow with the count (benchmarks/cad_import.py,
#: grooved fixture, 2 shared cores: 2 M triangles ~13 s of CPU and 1.4 GB peak, 4 M ~24 s
#: and 2.2 GB); 10 M would take ~6 GB (trimesh alone took 5.5 GB to load and decimate it)
#: for a part that collision, display and teaching need far coarser.
MAX_FACES = 4_000_000


@dataclass
class RepairReport:
    repairs: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


def check_raw(mesh: trimesh.Trimesh | None, filename: str) -> tuple[float, float]:
    """Refuse empty meshes, non-finite coordinates and face indices pointing nowhere; return
    the largest dimension and the farthest coordinate from the origin of the vertices in
    use (file units)."""
    if mesh is None or len(mesh.faces) == 0:
        raise CadImportError(filename, "holds no triangles",
                             "the file is empty or damaged; export the part again")
    if len(mesh.faces) > MAX_FACES:
        raise too_many(filename, len(mesh.faces), MAX_FACES, parsed=True)
    v = mesh.vertices.view(np.ndarray)
    f = mesh.faces.view(np.ndarray)
    if f.min() < 0 or f.max() >= len(v):
        raise CadImportError(
            filename, f"has faces referring to vertex {int(f.max())} but only {len(v)} vertices",
            "the file is damaged; export the part again")
    used = used_vertices(f, len(v))
    if not used.all():  # a soup (STL) uses every vertex: no copy
        v = v[used]
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise CadImportError(
            filename, f"has {int(bad.sum())} vertex(es) with NaN or infinite coordinates",
            "the CAD export is broken; repair the part in CAD and export it again")
    lo, hi = v.min(axis=0), v.max(axis=0)
    size = float((hi - lo).max())
    if size <= 0.0:
        raise CadImportError(filename, "is degenerate: all its vertices are the same point",
                             "export the part again")
    return size, float(max(np.abs(lo).max(), np.abs(hi).max()))


def used_vertices(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Mask of the vertices some face refers to (one linear pass, no sort)."""
    used = np.zeros(n_vertices, dtype=bool)
    used[np.asarray(faces).ravel()] = True
    return used


def repair(mesh: trimesh.Trimesh, filename: str, *, copy: bool = True, scale: float = 1.0,
           progress: Progress | None = None) -> tuple[trimesh.Trimesh, RepairReport]:
    """A cleaned mesh (merged vertices, no degenerate/duplicate faces, consistent outward
    normals, small holes filled) and what was changed, its vertices first multiplied by
    `scale` (to metres: the repair's tolerances are in metres). Refuses zero-area meshes.

    Runs on plain arrays (`mesh_ops`): a few seconds for millions of triangles. `copy=False`
    lets a caller that no longer needs `mesh` save a copy of its arrays (big files)."""
    rep = RepairReport()
    step = (progress or Progress()).update  # between steps: reports, and stops on Cancel
    dtype_copy = np.array if copy else np.asarray
    v = dtype_copy(mesh.vertices.view(np.ndarray), dtype=np.float64)
    f = dtype_copy(mesh.faces.view(np.ndarray), dtype=np.int64)
    if scale != 1.0:
        v = v * scale

    n_v = int(used_vertices(f, len(v)).sum())
    step(0.05, "merging vertices")
    v, f = ops.merge_vertices(v, f)
    if len(v) < n_v:
        # Normal for STL and tessellated CAD (every face has its own corners): not a repair.
        rep.notes.append(f"merged {n_v - len(v)} coincident vertices")

    step(0.3, "degenerate and duplicate faces")
    bad = ops.degenerate_faces(v, f, DEGENERATE_AREA_M2)
    if bad.any():
        f = f[~bad]
        rep.repairs.append(f"removed {int(bad.sum())} degenerate (zero-area) faces")
    if len(f) == 0:
        raise CadImportError(filename, "is degenerate: every face has zero area",
                             "the part is flat or collapsed; export it again from CAD")
    dup = ops.duplicate_faces(f)
    if dup.any():
        f = f[~dup]
        rep.repairs.append(f"removed {int(dup.sum())} duplicate faces")
    v, f = ops.compact(v, f)

    faces_before = f.copy()
    step(0.5, "winding")
    edges = ops.EdgeTable.of(f, len(v))
    fi, fj, same = ops.face_adjacency(f, edges)
    n_pieces, labels = ops.face_components(len(f), fi, fj)
    if same.any():  # neighbours running a shared edge the same way: wound inconsistently
        flip = ops.consistent_flips(len(f), fi, fj, same, labels)
        f[flip] = f[flip][:, ::-1]
        edges = ops.EdgeTable.of(f, len(v))  # a turned face's edges change places
        fi, fj, same = ops.face_adjacency(f, edges)
    if not edges.watertight:
        step(0.75, "small holes")
        added = _fill_small_holes(v, f, edges, labels, n_pieces)
        if len(added):
            f = np.vstack([f, added])
            rep.repairs.append(f"filled small holes with {len(added)} faces")
            edges = ops.EdgeTable.of(f, len(v))
            fi, fj, same = ops.face_adjacency(f, edges)
            n_pieces, labels = ops.face_components(len(f), fi, fj)
    step(0.85, "outward normals")
    # Outward: every closed, consistently wound piece with a negative volume is turned.
    closed = ops.closed_pieces(f, edges, fi, same, labels, n_pieces)
    volume = ops.piece_volumes(v, f, labels, n_pieces)
    small = np.bincount(labels, minlength=n_pieces) < 4
    turn = (volume < 0.0) & closed & ~small
    if turn.any():
        t = turn[labels]
        f[t] = f[t][:, ::-1]
    n_old = len(faces_before)
    flipped = int(np.sum(np.any(f[:n_old] != faces_before, axis=1)))
    del faces_before
    if flipped:
        rep.repairs.append(f"fixed the winding/normals of {flipped} faces")

    area = float(ops.triangle_areas(v, f).sum())
    if area <= DEGENERATE_AREA_M2:
        raise CadImportError(filename, "is degenerate: its surface has no area",
                             "export the part again from CAD")
    if not edges.watertight:
        rep.warnings.append("the mesh is open (not watertight): collision uses its surface, "
                            "and points inside it are not detected as inside")
    elif abs(float(np.abs(volume).sum())) < 1e-15:
        rep.warnings.append("the mesh encloses no volume (a flat sheet)")
    return trimesh.Trimesh(v, f, process=False), rep


def _fill_small_holes(v: np.ndarray, f: np.ndarray, edges: ops.EdgeTable, labels: np.ndarray,
                      n_pieces: int) -> np.ndarray:
    """Faces for the 3- and 4-edge holes trimesh's fill closes, except on flat pieces:
    closing the rim of a flat sheet (a single 3DFACE, a plate drawn as one quad) would glue
    a back face onto it. Flatness is judged for every piece at once from its vertices'
    summed moments."""
    vertex_label = np.full(len(v), -1)
    vertex_label[f.ravel()] = np.repeat(labels, 3)
    flat = ops.flat_pieces(v, vertex_label, n_pieces)
    fillable = (vertex_label >= 0) & ~flat[np.maximum(vertex_label, 0)]
    return ops.small_hole_faces(f, edges, fillable)
