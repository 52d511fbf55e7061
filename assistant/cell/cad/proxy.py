"""Collision geometry for a mesh: itself when small, a cheaper proxy when big, with its error.

Display keeps every triangle; collision checking runs millions of times during planning, so a
big mesh (more than `max_faces` triangles) is replaced by, in order of preference:

1. its convex hull, when the hull stays within `tolerance_m` of the mesh (most machined
   blocks, housings, cylinders): one convex piece, the cheapest and always conservative;
2. a convex decomposition (V-HACD via vhacdx), which follows concave parts (brackets, frames)
   and still overfills rather than cuts in, so a proxy never hides a real collision;
3. a quadric-decimated mesh (only if the optional `fast_simplification` package is present),
   which is closest on smooth free-form parts but may cut slightly into the part.

If none is within tolerance the closest is kept and a warning says by how much it deviates.
The deviation is a symmetric Hausdorff estimate from seeded surface samples (see
`_deviation`): how far the part sticks out of the proxy, and how far the proxy sticks out of
the part. Being sampled, it can miss the very worst point: on a torus it reads ~5 % low.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from assistant.cell.cad.raw import merge_meshes
from assistant.robots.model import CollisionShape, ShapeKind

Array = np.ndarray

SAMPLES = 2000
#: Exact point-to-mesh queries on big meshes are slow; screen with a KD-tree on dense samples
#: and measure exactly only the most distant candidates.
_EXACT_CANDIDATES = 128
_SEED = 7


@dataclass(frozen=True)
class ProxyReport:
    """Which proxy was chosen and how far it deviates from the mesh (metres)."""

    kind: str  # "mesh", "convex_hull", "convex_decomposition", "decimated"
    deviation_m: float
    faces: int
    parts: int
    tried: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class _Candidate:
    kind: str
    parts: tuple[trimesh.Trimesh, ...]
    deviation_m: float


def collision_proxy(
    mesh: trimesh.Trimesh, *, max_faces: int, tolerance_m: float
) -> tuple[tuple[CollisionShape, ...], ProxyReport, list[str]]:
    """Collision shapes (object frame) for `mesh`, the report, and any warnings."""
    if len(mesh.faces) <= max_faces:
        shape = CollisionShape(ShapeKind.MESH, mesh=mesh)
        return (shape,), ProxyReport("mesh", 0.0, len(mesh.faces), 1), []

    samples = _surface_samples(mesh)
    tree = cKDTree(_dense_samples(mesh))
    tried: list[_Candidate] = []

    hull = _hull(mesh, max_faces, tolerance_m)
    tried.append(_Candidate("convex_hull", (hull,), _deviation(mesh, samples, tree, (hull,))))
    if tried[-1].deviation_m > tolerance_m:
        parts = _decompose(mesh)
        if parts:
            tried.append(_Candidate("convex_decomposition", parts,
                                    _deviation(mesh, samples, tree, parts)))
    if min(c.deviation_m for c in tried) > tolerance_m:
        dec = _decimate(mesh, max_faces)
        if dec is not None:
            tried.append(_Candidate("decimated", (dec,), _deviation(mesh, samples, tree, (dec,),
                                                                    convex=False)))
    ok = [c for c in tried if c.deviation_m <= tolerance_m]
    best = ok[0] if ok else min(tried, key=lambda c: c.deviation_m)
    warnings = []
    if not ok:
        warnings.append(
            f"no collision proxy within {tolerance_m * 1000:.1f} mm of the mesh; using the "
            f"{best.kind.replace('_', ' ')} ({best.deviation_m * 1000:.1f} mm off)")
    shapes = tuple(CollisionShape(ShapeKind.MESH, mesh=p) for p in best.parts)
    report = ProxyReport(best.kind, best.deviation_m, int(sum(len(p.faces) for p in best.parts)),
                         len(best.parts), tuple((c.kind, c.deviation_m) for c in tried))
    return shapes, report, warnings


def _surface_samples(mesh: trimesh.Trimesh, n: int = SAMPLES) -> Array:
    pts, _ = trimesh.sample.sample_surface(mesh, n, seed=_SEED)
    # Vertices carry the corners and sharp edges that area sampling tends to miss.
    step = max(1, len(mesh.vertices) // n)
    return np.vstack([pts, mesh.vertices[::step]])


def _dense_samples(mesh: trimesh.Trimesh) -> Array:
    pts, _ = trimesh.sample.sample_surface(mesh, 20 * SAMPLES, seed=_SEED + 1)
    return np.vstack([pts, mesh.vertices, mesh.triangles_center])


def _hull(mesh: trimesh.Trimesh, max_faces: int, tolerance_m: float) -> trimesh.Trimesh:
    """The convex hull; if it alone has more than `max_faces` triangles (a finely tessellated
    round part), a coarser convex polytope that still contains every point: qhull merges
    nearly coplanar facets (post-merge 'C' at a quarter of the tolerance keeps all points
    inside the merged planes) and the polytope is the intersection of those planes. It is
    measured like every other candidate."""
    hull = mesh.convex_hull
    if len(hull.faces) <= max_faces:
        return hull
    from scipy.spatial import ConvexHull, HalfspaceIntersection

    merged = ConvexHull(hull.vertices, qhull_options=f"Qt C{tolerance_m / 4.0:.6g}")
    planes = np.unique(np.round(merged.equations, 12), axis=0)
    corners = HalfspaceIntersection(planes, hull.vertices.mean(axis=0)).intersections
    coarse = trimesh.convex.convex_hull(corners)
    return coarse if len(coarse.faces) < len(hull.faces) else hull


def _decompose(mesh: trimesh.Trimesh) -> tuple[trimesh.Trimesh, ...]:
    try:
        parts = mesh.convex_decomposition(maxConvexHulls=32, resolution=100_000,
                                          asyncACD=False)
    except Exception:  # vhacdx missing or failing on odd input: fall through to decimation
        return ()
    return tuple(p for p in parts if len(p.faces) >= 4)


def _decimate(mesh: trimesh.Trimesh, max_faces: int) -> trimesh.Trimesh | None:
    try:
        return mesh.simplify_quadric_decimation(face_count=max_faces)
    except Exception:  # fast_simplification not installed (optional)
        return None


def _inside_convex(points: Array, part: trimesh.Trimesh, tol: float) -> Array:
    n = part.face_normals
    offs = np.einsum("ij,ij->i", n, part.triangles[:, 0])
    inside = np.ones(len(points), dtype=bool)
    step = max(1, 2_000_000 // max(1, len(points)))  # bound the (points x faces) block
    for k in range(0, len(n), step):
        inside &= np.all(points @ n[k:k + step].T - offs[k:k + step] <= tol, axis=1)
    return inside


def _inside(points: Array, part: trimesh.Trimesh, convex: bool, tol: float) -> Array:
    if convex:
        return _inside_convex(points, part, tol)
    if part.is_watertight:
        return part.contains(points)
    return np.zeros(len(points), dtype=bool)


def _deviation(mesh: trimesh.Trimesh, samples: Array, tree: cKDTree,
               parts: tuple[trimesh.Trimesh, ...], *, convex: bool = True) -> float:
    """Hausdorff estimate between the part and the proxy, as solids where they are closed.

    Missed: points of the mesh surface outside every proxy part, measured to the nearest part.
    Excess: points of the proxy surface outside the mesh, measured to the mesh surface.
    Points inside the other solid count zero: the shared walls between convex pieces are not
    on the proxy's outside, and proxy surface buried in the part cannot cause a false contact.
    For an open mesh (no inside) this falls back to plain surface-to-surface distances.
    """
    tol = 1e-6 * float(mesh.scale)
    covered = np.zeros(len(samples), dtype=bool)
    for p in parts:
        covered |= _inside(samples, p, convex, tol)
    missed = 0.0
    if not covered.all():
        out = samples[~covered]
        if len(out) > _EXACT_CANDIDATES:
            # Same screening as below: the nearest dense proxy sample bounds the distance.
            approx, _ = cKDTree(_dense_samples(merge_meshes(parts))).query(out)
            out = out[np.argsort(approx)[-_EXACT_CANDIDATES:]]
        d = np.full(len(out), np.inf)
        for p in parts:
            d = np.minimum(d, trimesh.proximity.closest_point(p, out)[1])
        missed = float(d.max())

    union = merge_meshes(parts)
    on_proxy, _ = trimesh.sample.sample_surface(union, 5 * SAMPLES, seed=_SEED)
    pts = np.vstack([on_proxy, union.vertices])
    if mesh.is_watertight:
        pts = pts[~mesh.contains(pts)]
    excess = 0.0
    if len(pts):
        approx, _ = tree.query(pts)
        worst = pts[np.argsort(approx)[-_EXACT_CANDIDATES:]]
        excess = float(trimesh.proximity.closest_point(mesh, worst)[1].max())
    return max(missed, excess)
