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
#: A mesh with more triangles than this is refused before any heavy work: import time and
#: memory grow with the triangle count (benchmarks/cad_import.py: 200 k triangles ~10-25 s
#: and < 0.5 GB on two shared cores, 500 k 35-58 s; 2 M took minutes and 5 GB), and collision,
#: display and teaching need a few thousand at most.
MAX_FACES = 250_000


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
            filename, f"has {len(mesh.faces):,} triangles, more than the {MAX_FACES:,} an "
                      "import handles in half a minute",
            "export it with a coarser tessellation (a larger chordal tolerance), decimate it "
            "(e.g. Blender's Decimate, MeshLab's quadric edge collapse), or leave out small "
            "details such as screws and text, then import it again")
    v = np.asarray(mesh.vertices)
    f = np.asarray(mesh.faces)
    if f.min() < 0 or f.max() >= len(v):
        raise CadImportError(
            filename, f"has faces referring to vertex {int(f.max())} but only {len(v)} vertices",
            "the file is damaged; export the part again")
    used = v[used_vertices(f, len(v))]
    bad = ~np.isfinite(used).all(axis=1)
    if bad.any():
        raise CadImportError(
            filename, f"has {int(bad.sum())} vertex(es) with NaN or infinite coordinates",
            "the CAD export is broken; repair the part in CAD and export it again")
    if float(np.ptp(used, axis=0).max()) <= 0.0:
        raise CadImportError(filename, "is degenerate: all its vertices are the same point",
                             "export the part again")


def used_vertices(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Mask of the vertices some face refers to (one linear pass, no sort)."""
    used = np.zeros(n_vertices, dtype=bool)
    used[np.asarray(faces).ravel()] = True
    return used


def repair(mesh: trimesh.Trimesh, filename: str, *, copy: bool = True
           ) -> tuple[trimesh.Trimesh, RepairReport]:
    """A cleaned mesh (merged vertices, no degenerate/duplicate faces, consistent outward
    normals, small holes filled) and what was changed. Refuses zero-area meshes.

    `copy=False` lets a caller that no longer needs `mesh` save the copy (big files)."""
    rep = RepairReport()
    if copy:
        m = trimesh.Trimesh(np.array(mesh.vertices, dtype=np.float64),
                            np.array(mesh.faces, dtype=np.int64), process=False)
    else:
        m = trimesh.Trimesh(np.asarray(mesh.vertices, dtype=np.float64),
                            np.asarray(mesh.faces, dtype=np.int64), process=False)

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
    trimesh.repair.fix_winding(m)  # consistent winding within each body
    _fix_inversion(m)  # then outward per closed body
    flipped = int(np.sum(np.any(m.faces != faces_before, axis=1)))
    del faces_before
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
    sheet (a single 3DFACE, a plate drawn as one quad) would glue a back face onto it.

    Linear in the mesh size: flatness is judged for every connected piece at once from its
    vertices' summed moments (one pass), not piece by piece (which grew with pieces x faces
    and took minutes on a file of many small parts)."""
    n_f = len(m.faces)
    n_labels, face_label = _face_components(m)
    vertex_label = np.full(len(m.vertices), -1)
    vertex_label[m.faces.ravel()] = np.repeat(face_label, 3)
    flat = _flat_components(m.vertices, vertex_label, n_labels)

    candidate = trimesh.Trimesh(m.vertices, m.faces, process=False)
    trimesh.repair.fill_holes(candidate)
    new = candidate.faces[n_f:]
    if len(new) == 0 or len(candidate.vertices) != len(m.vertices):
        return 0
    keep = ~flat[vertex_label[new[:, 0]]]
    if not keep.any():
        return 0
    m.faces = np.vstack([m.faces, new[keep]])
    return int(keep.sum())


def _face_components(m: trimesh.Trimesh) -> tuple[int, np.ndarray]:
    """How many edge-connected pieces, and each face's piece (scipy, linear)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n_f = len(m.faces)
    adj = np.asarray(m.face_adjacency, dtype=np.int64).reshape(-1, 2)
    graph = coo_matrix((np.ones(len(adj), dtype=np.int8), (adj[:, 0], adj[:, 1])),
                       shape=(n_f, n_f))
    n, labels = connected_components(graph, directed=False)
    return int(n), labels


def _flat_components(vertices: np.ndarray, vertex_label: np.ndarray, n: int) -> np.ndarray:
    """Per piece: True if all its vertices lie in one plane (smallest principal spread is
    ~0 relative to the largest), computed from per-piece sums of x and x x^T."""
    used = vertex_label >= 0
    lab = vertex_label[used]
    v = vertices[used]
    count = np.bincount(lab, minlength=n).astype(float)
    # Centre each piece on one of its own vertices first: moments about a far origin would
    # cancel catastrophically for a small part placed far away.
    first = np.full(n, -1)
    first[lab[::-1]] = np.arange(len(lab))[::-1]
    c = v - v[first[lab]]
    s1 = np.stack([np.bincount(lab, c[:, a], minlength=n) for a in range(3)], axis=1)
    s2 = np.empty((n, 3, 3))
    for a in range(3):
        for b in range(a, 3):
            s2[:, a, b] = s2[:, b, a] = np.bincount(lab, c[:, a] * c[:, b], minlength=n)
    safe = np.maximum(count, 1.0)
    mean = s1 / safe[:, None]
    cov = s2 / safe[:, None, None] - mean[:, :, None] * mean[:, None, :]
    ev = np.linalg.eigvalsh(cov)  # ascending; variances = squared singular values / count
    # Thinner than 1e-6 of its size (squared: variances); roundoff of the moments is ~1e-16.
    flat = (count < 4) | (ev[:, 0] <= 1e-12 * np.maximum(ev[:, 2], 1e-60))
    return flat


def _fix_inversion(m: trimesh.Trimesh) -> None:
    """Turn every closed, consistently wound body whose volume is negative inside out.

    What `trimesh.repair.fix_inversion(multibody=True)` does, for all bodies at once: that
    one loops over bodies in Python (two minutes for 160 k small parts)."""
    faces = np.asarray(m.faces, dtype=np.int64)
    n_f, n_v = len(faces), len(m.vertices)
    if n_f == 0:
        return
    n, label = _face_components(m)
    # Directed edges a->b of every face; a body is closed and wound when each of its directed
    # edges occurs once and its reverse once (every edge shared by exactly two faces).
    a = faces.ravel()
    b = faces[:, [1, 2, 0]].ravel()
    key = a * n_v + b
    rev = b * n_v + a
    order = np.argsort(key, kind="stable")
    ks = key[order]
    dup = np.zeros(len(key), dtype=bool)
    same = ks[1:] == ks[:-1]
    dup[order[1:][same]] = True
    dup[order[:-1][same]] = True
    pos = np.searchsorted(ks, rev)
    has_rev = (pos < len(ks)) & (ks[np.minimum(pos, len(ks) - 1)] == rev)
    bad_edge = dup | ~has_rev
    edge_label = np.repeat(label, 3)
    bad = np.bincount(edge_label[bad_edge], minlength=n) > 0
    small = np.bincount(label, minlength=n) < 4
    # Signed volume per body, about one of its own vertices (no cancellation far away).
    first = np.full(n, -1)
    first[label[::-1]] = faces[::-1, 0]
    o = m.vertices[first[label]]
    v0, v1, v2 = (m.vertices[faces[:, k]] - o for k in range(3))
    det = np.einsum("ij,ij->i", v0, np.cross(v1, v2))
    volume = np.bincount(label, det, minlength=n)
    flip_body = (volume < 0.0) & ~bad & ~small
    flip = flip_body[label]
    if flip.any():
        new = faces.copy()
        new[flip] = new[flip][:, ::-1]
        m.faces = new
