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

Nothing the part occupies is left out: the chosen proxy carries a collision margin
(`CollisionShape.margin`) of at least the distance by which the part lies outside it - zero
for the hull (it holds every vertex by construction), else the one-sided Hausdorff distance
from the part to the proxy, bounded over every triangle of the full-resolution part
(`outside.outside_bound`). The collision checks count the margin as the proxy.

Big meshes are bounded work, not a longer wait (`ProxyReport.bounded` says what was bounded):
above `WORK_FACES` triangles the candidates are built and measured on a decimated work copy
(its distance from the part is added to each candidate's figure); above `HULL_EXACT_VERTICES`
the hull is a polytope of support planes over every vertex (still containing the whole part);
V-HACD runs in a child process killed after `DECOMPOSE_BUDGET_S` seconds (ordinary parts:
`DECOMPOSE_BUDGET_SMALL_S`) or on Cancel, and is not tried above `DECOMPOSE_MAX_FACES`
(there the decimated copy follows the part better in the time). The candidates' figure
(`deviation_m`) is a symmetric Hausdorff estimate from seeded surface samples (see
`_deviation`): how far the part sticks out of the proxy, and how far the proxy sticks out of
the part; it chooses the proxy. Being sampled, it can miss the very worst point (on a torus
it reads ~5 % low) - which is why the margin is a bound, not this estimate.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from assistant.cell.cad.outside import outside_bound
from assistant.cell.cad.raw import merge_meshes
from assistant.progress import Progress
from assistant.robots.model import CollisionShape, ShapeKind

Array = np.ndarray

SAMPLES = 2000
#: Exact point-to-mesh queries on big meshes are slow; screen with a KD-tree on dense samples
#: and measure exactly only the most distant candidates.
_EXACT_CANDIDATES = 128
_SEED = 7
#: Above this many triangles the proxy is built and measured on a decimated copy this size.
WORK_FACES = 20_000
#: Above this many vertices the hull is the bounded support-plane polytope (`_bounded_hull`).
HULL_EXACT_VERTICES = 100_000
#: V-HACD on a big part's work copy gets this long (wall clock, its own process) before it is
#: stopped; on an ordinary part (at most `WORK_FACES`) the longer budget, so the result does not
#: depend on how busy the machine is.
DECOMPOSE_BUDGET_S = 5.0
DECOMPOSE_BUDGET_SMALL_S = 90.0
#: Above this many triangles V-HACD is not tried: hull, else the decimated copy.
DECOMPOSE_MAX_FACES = 250_000
#: The big-part hull is pushed out from the work copy by its bound when that bound is below
#: this share of the tolerance, else from every vertex of the part; likewise its excess is
#: measured on the work copy, else on the part.
WORK_HULL_ERROR = 0.5


@dataclass(frozen=True)
class ProxyReport:
    """Which proxy was chosen and how far it deviates from the mesh (metres)."""

    kind: str  # "mesh", "convex_hull", "convex_decomposition", "decimated"
    #: Symmetric estimate (both ways) that chose the proxy.
    deviation_m: float
    faces: int
    parts: int
    tried: tuple[tuple[str, float], ...] = ()
    #: What was bounded to keep a big import short (empty for ordinary parts).
    bounded: tuple[str, ...] = ()
    #: The collision margin: no point of the part lies farther than this outside the proxy
    #: (one-sided Hausdorff from the part to the proxy, bounded over every triangle).
    margin_m: float = 0.0
    #: The largest of those distances found at a vertex of the part (<= margin_m).
    outside_at_vertices_m: float = 0.0


@dataclass(frozen=True)
class _Candidate:
    kind: str
    parts: tuple[trimesh.Trimesh, ...]
    deviation_m: float


def collision_proxy(
    mesh: trimesh.Trimesh, *, max_faces: int, tolerance_m: float,
    progress: Progress | None = None, lod: trimesh.Trimesh | None = None,
) -> tuple[tuple[CollisionShape, ...], ProxyReport, list[str]]:
    """Collision shapes (object frame) for `mesh`, the report, and any warnings. `lod`, a
    decimated copy of `mesh` already made for display, is decimated further for the work
    copy instead of `mesh` itself (seconds less on millions of triangles)."""
    if len(mesh.faces) <= max_faces:
        shape = CollisionShape(ShapeKind.MESH, mesh=mesh)
        return (shape,), ProxyReport("mesh", 0.0, len(mesh.faces), 1), []
    progress = progress or Progress()
    bounded: list[str] = []
    work, work_bound = mesh, None
    if len(mesh.faces) > WORK_FACES:
        progress.update(0.05, "decimating a work copy for the collision proxy")
        src = lod if lod is not None and len(lod.faces) > WORK_FACES else mesh
        dec = _decimate(src, WORK_FACES)
        if dec is not None and len(dec.faces) >= 4:
            work = dec
            work_bound = outside_bound(mesh.vertices, mesh.faces, (work,), convex=False,
                                       progress=progress.sub(0.08, 0.4, "measuring"))
            bounded.append(f"collision proxy built on a {len(work.faces):,}-triangle copy "
                           f"(the part lies within {work_bound.distance_m * 1000:.2f} mm of "
                           "it, included below)")
    work_error = work_bound.distance_m if work_bound is not None else 0.0

    progress.update(0.42, "measuring the part")
    samples = _surface_samples(work)
    tree = cKDTree(_dense_samples(work))
    tried: list[_Candidate] = []

    progress.update(0.45, "convex hull")
    if len(mesh.vertices) > HULL_EXACT_VERTICES:
        hull = _bounded_hull(mesh, work, work_error, tolerance_m)
        bounded.append(f"hull from support planes around all {len(mesh.vertices):,} vertices")
    else:
        hull = _hull(mesh, max_faces, tolerance_m)
    if work is mesh or work_error <= WORK_HULL_ERROR * tolerance_m:
        hull_dev = work_error + _deviation(work, samples, tree, (hull,))
    else:  # the work copy lost too much of the part to judge the hull: the part itself
        on_hull, _ = trimesh.sample.sample_surface(hull, 5 * SAMPLES, seed=_SEED)
        hull_dev = _excess(np.vstack([on_hull, hull.vertices]), mesh)
    tried.append(_Candidate("convex_hull", (hull,), hull_dev))
    if tried[-1].deviation_m > tolerance_m and len(mesh.faces) <= DECOMPOSE_MAX_FACES:
        progress.update(0.5, "convex decomposition")
        budget = DECOMPOSE_BUDGET_S if work is not mesh else DECOMPOSE_BUDGET_SMALL_S
        parts, note = _decompose(work, progress.sub(0.5, 0.75), budget)
        if note:
            bounded.append(note)
        if parts:
            tried.append(_Candidate("convex_decomposition", parts,
                                    work_error + _deviation(work, samples, tree, parts)))
    if min(c.deviation_m for c in tried) > tolerance_m:
        progress.update(0.78, "decimated proxy")
        dec = work if len(work.faces) <= max_faces else _decimate(work, max_faces)
        if dec is work and work is not mesh:  # measured already: the work copy's bound
            tried.append(_Candidate("decimated", (dec,), work_error))
        elif dec is not None:
            tried.append(_Candidate("decimated", (dec,), work_error + _deviation(
                work, samples, tree, (dec,), convex=False)))
    ok = [c for c in tried if c.deviation_m <= tolerance_m]
    best = ok[0] if ok else min(tried, key=lambda c: c.deviation_m)
    warnings = []
    if not ok:
        warnings.append(
            f"no collision proxy within {tolerance_m * 1000:.1f} mm of the mesh; using the "
            f"{best.kind.replace('_', ' ')} ({best.deviation_m * 1000:.1f} mm off)")

    progress.update(0.82, "bounding how far the part lies outside the proxy")
    if best.kind == "convex_hull":
        margin, at_vertices = 0.0, 0.0  # holds every vertex of the part by construction
    elif len(best.parts) == 1 and best.parts[0] is work and work_bound is not None:
        margin, at_vertices = work_bound.distance_m, work_bound.at_vertices_m
    else:
        b = outside_bound(mesh.vertices, mesh.faces, best.parts,
                          convex=best.kind == "convex_decomposition",
                          progress=progress.sub(0.82, 0.98, "measuring"))
        margin, at_vertices = b.distance_m, b.at_vertices_m
    # Rounding of the bound's own arithmetic (relative 1e-12 of the part's size) on top.
    size = float(np.ptp(mesh.vertices.view(np.ndarray), axis=0).max())
    margin = margin + 1e-12 * size if margin > 0.0 else 0.0
    if margin > tolerance_m:
        warnings.append(
            f"the part lies up to {margin * 1000:.1f} mm outside its collision proxy: the "
            f"collision checks keep the arm that much farther from the proxy")
    shapes = tuple(CollisionShape(ShapeKind.MESH, mesh=p, margin=margin) for p in best.parts)
    report = ProxyReport(best.kind, best.deviation_m, int(sum(len(p.faces) for p in best.parts)),
                         len(best.parts), tuple((c.kind, c.deviation_m) for c in tried),
                         tuple(bounded), margin, at_vertices)
    progress.update(1.0, "collision proxy ready")
    return shapes, report, warnings


def _bounded_hull(mesh: trimesh.Trimesh, work: trimesh.Trimesh, work_error: float,
                  tolerance_m: float) -> trimesh.Trimesh:
    """A convex polytope that contains every point of `mesh`, at bounded cost: the plane
    normals of the work copy's (merged) hull, each pushed out as far as the part reaches
    along it, then intersected. How far the part reaches: the work copy's farthest vertex
    plus `work_error` (every point of the part lies within that bound of the work copy) when
    that is small, else the part's own farthest vertex (a product over all its vertices)."""
    from scipy.spatial import ConvexHull, HalfspaceIntersection

    merged = ConvexHull(work.vertices, qhull_options=f"Qt C{tolerance_m / 4.0:.6g}")
    normals = np.unique(np.round(merged.equations[:, :3], 12), axis=0)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    if work_error <= WORK_HULL_ERROR * tolerance_m:
        v = work.vertices.view(np.ndarray)
        reach = (v @ normals.T).max(axis=0) + work_error
    else:
        v = mesh.vertices.view(np.ndarray)
        reach = np.full(len(normals), -np.inf)
        step = max(1, 20_000_000 // max(1, len(normals)))
        for k in range(0, len(v), step):
            reach = np.maximum(reach, (v[k:k + step] @ normals.T).max(axis=0))
    planes = np.column_stack([normals, -reach])
    inner = v[:: max(1, len(v) // 1000)].mean(axis=0)
    corners = HalfspaceIntersection(planes, inner).intersections
    return trimesh.convex.convex_hull(corners)


def _excess(points: Array, mesh: trimesh.Trimesh) -> float:
    """How far the farthest of `points` lies from the surface of a big `mesh` (exact
    distances to candidate triangles: an upper bound, tight where the candidates are right)."""
    from assistant.cell.cad.outside import nearest_distances

    return float(nearest_distances(points, mesh).max()) if len(points) else 0.0


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
    nearly coplanar facets (post-merge 'C' at a quarter of the tolerance), and each merged
    plane is pushed out to the farthest hull vertex along its normal before the planes are
    intersected, so every vertex is inside by construction. It is measured like every other
    candidate."""
    hull = mesh.convex_hull
    if len(hull.faces) <= max_faces:
        return hull
    from scipy.spatial import ConvexHull, HalfspaceIntersection

    merged = ConvexHull(hull.vertices, qhull_options=f"Qt C{tolerance_m / 4.0:.6g}")
    normals = np.unique(np.round(merged.equations[:, :3], 12), axis=0)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    reach = (hull.vertices @ normals.T).max(axis=0)
    corners = HalfspaceIntersection(np.column_stack([normals, -reach]),
                                    hull.vertices.mean(axis=0)).intersections
    coarse = trimesh.convex.convex_hull(corners)
    return coarse if len(coarse.faces) < len(hull.faces) else hull


_VHACD_CHILD = """
import sys, numpy as np
from vhacdx import compute_vhacd
d = np.load(sys.argv[1])
f = np.column_stack((np.full(len(d["f"]), 3, dtype=np.int64), d["f"])).ravel().astype(np.uint32)
parts = compute_vhacd(d["v"], f, maxConvexHulls=int(sys.argv[3]), resolution=int(sys.argv[4]),
                      asyncACD=False)
out = {}
for i, (v, ff) in enumerate(parts):
    out[f"v{i}"], out[f"f{i}"] = np.asarray(v, float), np.asarray(ff).reshape(-1, 3)
np.savez(sys.argv[2], n=np.array(len(parts)), **out)
"""


def _decompose(mesh: trimesh.Trimesh, progress: Progress | None = None,
               budget_s: float = DECOMPOSE_BUDGET_S) -> tuple[tuple[trimesh.Trimesh, ...], str]:
    """V-HACD (vhacdx) in a child process: stopped after `budget_s` or when the operator
    cancels (a C++ call cannot be interrupted in-process). Returns the parts and, when it was
    stopped, a note saying so; no parts if vhacdx is missing or fails."""
    progress = progress or Progress()
    with tempfile.TemporaryDirectory(prefix="cellteach-vhacd-") as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(src, v=np.asarray(mesh.vertices, float), f=np.asarray(mesh.faces, np.int64))
        env = dict(os.environ, OMP_NUM_THREADS="1")
        proc = subprocess.Popen([sys.executable, "-c", _VHACD_CHILD, str(src), str(dst),
                                 "32", "100000"], stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL, env=env)
        t0 = time.monotonic()
        try:
            while proc.poll() is None:
                elapsed = time.monotonic() - t0
                if elapsed > budget_s:
                    proc.kill()
                    proc.wait()
                    return (), f"convex decomposition stopped at its {budget_s:.0f} s budget"
                progress.update(min(0.95, elapsed / budget_s), "convex decomposition")
                time.sleep(0.05)
        finally:
            if proc.poll() is None:  # Cancelled (or any error) while it ran
                proc.kill()
                proc.wait()
        if proc.returncode != 0 or not dst.exists():
            return (), ""
        with np.load(dst) as d:
            parts = [trimesh.Trimesh(d[f"v{i}"], d[f"f{i}"]) for i in range(int(d["n"]))]
    return tuple(p for p in parts if len(p.faces) >= 4), ""


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
