"""How far a part lies outside its collision proxy: a bound over every triangle, not a sample.

The proxy of a big part is simpler than the part, so parts of the part may stick out of it;
the collision checks count everything within a margin of the proxy as the proxy
(`CollisionShape.margin`), and this module finds a margin that is enough: an upper bound of
the one-sided Hausdorff distance from the part's surface to the proxy,

    H = max over points p of the part's surface of distance(p, proxy).

It holds for every point of every triangle, not only for the points looked at, because the
distance to a convex set (a proxy triangle, a convex proxy piece) is a convex function: over
a triangle of the part it is largest at a corner. So a triangle of the part whose three
corners all lie within d of one proxy triangle (or inside/within d of one convex piece) lies
within d of the proxy everywhere. For each corner the nearest proxy triangles are found
through a KD-tree of points spread over the proxy (any triangle gives a valid bound, the
nearest the tightest) and measured exactly. A triangle whose corners share no candidate is
bounded by the best of: its corners' distances plus its size (distance is 1-Lipschitz), its
three corners against each corner's nearest proxy triangle, and - where that is still above
the largest bound of the others - splitting it in four, again and again, each piece bounded
against the triangle's candidates (a piece straddling two proxy triangles lies close to one
of them everywhere the smaller it is).

`OutsideBound.at_vertices_m` is the largest corner distance found; the bound exceeds it only
where the proxy bends within a triangle of the part.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from assistant.progress import Progress

Array = np.ndarray

#: Nearest proxy triangles measured per corner of the part.
CANDIDATES = 2
#: About this many points are spread over the proxy to find each corner's candidates.
PROXY_POINTS = 400_000
#: Triangles split to tighten their bound, at most (largest bounds first), and how often.
REFINE_MAX = 200_000
REFINE_DEPTH = 4
REFINE_BATCH = 16_384
_CHUNK = 400_000


@dataclass(frozen=True)
class OutsideBound:
    """The part's surface lies within `distance_m` of the proxy, everywhere."""

    distance_m: float
    #: The largest distance found at a corner of the part (to its nearest candidate: at most
    #: the bound, and only above the true corner distance where a candidate was not the
    #: nearest proxy triangle).
    at_vertices_m: float
    triangles: int
    #: Triangles bounded by measuring all their corners' candidates.
    refined: int


def point_triangle_distance(p: Array, a: Array, b: Array, c: Array) -> Array:
    """Exact distance from each point p[i] to the triangle (a[i], b[i], c[i]), including
    degenerate triangles (then the nearest of its edges)."""
    table = _Triangles(np.stack([a, b, c], axis=1))
    return table.distance(p, np.arange(len(p)))


class _Triangles:
    """Per-triangle quantities for exact point-triangle distances, computed once: corner a,
    edges, unit normal and the in-plane edge normals of the inside test."""

    def __init__(self, tris: Array):
        a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
        n = np.cross(b - a, c - a)
        nn = np.einsum("ij,ij->i", n, n)
        self.flat = nn <= 0.0
        unit = n / np.sqrt(np.where(self.flat, 1.0, nn))[:, None]
        self.a, self.ab, self.ac = a, b - a, c - a
        self.bc = c - b
        # p is inside the prism over the triangle iff (p - corner) . (n x edge) >= 0 for
        # each edge (a->b from a, b->c from b, c->a from a)
        self.m1, self.m2, self.m3 = np.cross(unit, b - a), np.cross(unit, c - b), \
            np.cross(unit, a - c)
        self.unit = unit
        self.ll = np.stack([np.einsum("ij,ij->i", e, e) for e in (self.ab, self.bc, -self.ac)],
                           axis=1)

    def distance(self, p: Array, idx: Array) -> Array:
        """Exact distances from points p[i] to triangles idx[i] (chunked)."""
        out = np.empty(len(p))
        for k in range(0, len(p), _CHUNK):
            out[k:k + _CHUNK] = self._distance(p[k:k + _CHUNK], idx[k:k + _CHUNK])
        return out

    def _distance(self, p: Array, i: Array) -> Array:
        ap = p - self.a[i]
        inside = ((np.einsum("ij,ij->i", ap, self.m1[i]) >= 0.0)
                  & (np.einsum("ij,ij->i", ap - self.ab[i], self.m2[i]) >= 0.0)
                  & (np.einsum("ij,ij->i", ap, self.m3[i]) >= 0.0) & ~self.flat[i])
        out = np.abs(np.einsum("ij,ij->i", ap, self.unit[i]))
        o = np.flatnonzero(~inside)  # beyond an edge: the nearest edge (segment distances)
        if len(o):
            io, apo = i[o], ap[o]
            ab, ll = self.ab[io], self.ll[io]
            d2 = np.minimum(np.minimum(_segment_d2(apo, ab, ll[:, 0]),
                                       _segment_d2(apo - ab, self.bc[io], ll[:, 1])),
                            _segment_d2(apo, self.ac[io], ll[:, 2]))
            out[o] = np.sqrt(d2)
        return out


def _segment_d2(ap: Array, ab: Array, ll: Array) -> Array:
    """Squared distance from points (given relative to a) to the segments a -> a + ab of
    squared length ll."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip(np.where(ll > 0.0, np.einsum("ij,ij->i", ap, ab) / ll, 0.0), 0.0, 1.0)
    r = ap - t[:, None] * ab
    return np.einsum("ij,ij->i", r, r)


def _proxy_points(tris: Array) -> tuple[Array, Array]:
    """Points spread over the proxy triangles and the triangle each lies on: the centroids of
    an n x n split of each triangle (n larger on big triangles). None lies on an edge or a
    corner, where it would belong to several triangles."""
    area = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]),
                                axis=1)
    # n x n points on a triangle: about PROXY_POINTS in all, spread by area
    n = np.clip(np.ceil(np.sqrt(area * (PROXY_POINTS / max(area.sum(), 1e-30)))), 1, 12)
    n = n.astype(np.int64)
    points, labels = [], []
    for k in np.unique(n):
        sel = np.flatnonzero(n == k)
        i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
        up = (i + j) <= k - 1  # sub-triangles pointing up, centroid (i + 1/3, j + 1/3) / k
        down = (i + j) <= k - 2  # and down, centroid (i + 2/3, j + 2/3) / k
        w1 = np.concatenate([(i[up] + 1 / 3), (i[down] + 2 / 3)]) / k
        w2 = np.concatenate([(j[up] + 1 / 3), (j[down] + 2 / 3)]) / k
        w0 = 1.0 - w1 - w2
        t = tris[sel]
        pts = (t[:, None, 0] * w0[None, :, None] + t[:, None, 1] * w1[None, :, None]
               + t[:, None, 2] * w2[None, :, None])
        points.append(pts.reshape(-1, 3))
        labels.append(np.repeat(sel, len(w0)))
    return np.vstack(points), np.concatenate(labels)


def _convex_inside(points: Array, part: trimesh.Trimesh, tol: float) -> Array:
    """Which points lie inside a convex part (its distinct face planes), within `tol`."""
    eq = np.column_stack([part.face_normals,
                          -np.einsum("ij,ij->i", part.face_normals, part.triangles[:, 0])])
    eq = np.unique(np.round(eq, 12), axis=0)
    lo, hi = part.bounds
    inside = np.all((points >= lo - tol) & (points <= hi + tol), axis=1)
    idx = np.flatnonzero(inside)
    step = max(1, 20_000_000 // max(1, len(eq)))
    for k in range(0, len(idx), step):
        sel = idx[k:k + step]
        inside[sel] = np.all(points[sel] @ eq[:, :3].T + eq[:, 3] <= tol, axis=1)
    return inside


class _Finder:
    """Candidate proxy sets for points of the part: the proxy triangles whose spread points
    are nearest (exact distances to them), and for a convex proxy the pieces instead, with
    distance 0 to a piece holding the point."""

    def __init__(self, parts: tuple[trimesh.Trimesh, ...], convex: bool, tol: float):
        self.parts, self.convex, self.tol = parts, convex, tol
        tris = np.vstack([np.asarray(p.triangles, dtype=np.float64) for p in parts])
        self.table = _Triangles(tris)
        self.piece = np.concatenate([np.full(len(p.faces), i) for i, p in enumerate(parts)])
        pts, self.lab = _proxy_points(tris)
        self.k = min(CANDIDATES, len(pts))
        self.tree = cKDTree(pts)

    def __call__(self, points: Array) -> tuple[Array, Array, Array]:
        """(labels (n, c), distances (n, c), candidate proxy triangles (n, k)) of each point:
        labels are the candidate triangles, or for a convex proxy their pieces and the piece
        holding the point (distance 0)."""
        workers = 2 if len(points) > 200_000 else 1  # threads cost more than small queries
        _, near = self.tree.query(points, k=self.k, workers=workers)
        cand = self.lab[near.reshape(len(points), self.k)].astype(np.int64)
        dist = self.table.distance(np.repeat(points, self.k, axis=0),
                                   cand.ravel()).reshape(len(points), self.k)
        if not self.convex:
            return cand, dist, cand
        inside_of = np.full(len(points), -1, dtype=np.int64)
        for i, p in enumerate(self.parts):
            free = np.flatnonzero(inside_of == -1)
            inside_of[free[_convex_inside(points[free], p, self.tol)]] = i
        labels = np.column_stack([self.piece[cand], np.where(inside_of >= 0, inside_of, -2)])
        dist = np.column_stack([dist, np.where(inside_of >= 0, 0.0, np.inf)])
        return labels, dist, cand


def outside_bound(vertices: Array, faces: Array, parts: tuple[trimesh.Trimesh, ...], *,
                  convex: bool, progress: Progress | None = None) -> OutsideBound:
    """Upper bound (m) of how far any point of the surface (vertices, faces) lies from the
    proxy `parts`; `convex` when each part is a convex solid (then points inside a part are
    at distance 0), else the proxy is its surface."""
    progress = progress or Progress()
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if len(f) == 0:
        return OutsideBound(0.0, 0.0, 0, 0)
    progress.update(0.05, "measuring the proxy against the part")
    find = _Finder(parts, convex, 1e-9 * float(np.ptp(v, axis=0).max()))
    used = np.zeros(len(v), dtype=bool)
    used[f.ravel()] = True
    used = np.flatnonzero(used)
    lab_u, dist_u, cand_u = find(v[used])
    labels = np.zeros((len(v), lab_u.shape[1]), dtype=np.int64)
    dist = np.full((len(v), lab_u.shape[1]), np.inf)
    cand = np.zeros((len(v), cand_u.shape[1]), dtype=np.int64)  # candidate proxy triangles
    labels[used], dist[used], cand[used] = lab_u, dist_u, cand_u
    best = np.zeros(len(v), dtype=np.int64)  # each vertex's nearest candidate triangle
    best[used] = _nearest_candidate(cand_u, dist_u)
    del lab_u, dist_u, cand_u
    at_vertices = float(dist[used].min(axis=1).max())
    progress.update(0.6, "bounding every triangle")

    bound, common = _bound(labels, dist, f, v)
    del labels, dist
    # A triangle whose corners share their nearest candidate is bounded about as tightly as
    # the distance is. The others are measured against every candidate of their corners,
    # and where still above the largest of those, split in four, again and again.
    floor = float(bound[common].max()) if common.any() else 0.0
    todo = np.flatnonzero(bound > floor)
    if len(todo):
        bound[todo] = np.minimum(bound[todo], _cross_bound(v, f[todo], best, find.table))
        todo = todo[bound[todo] > floor]
    del best
    todo = todo[np.argsort(bound[todo])[::-1]]
    refined = 0
    # Largest bounds first, a batch at a time: the result is at least the largest bound a
    # split gives, so once the rest are below that they need no split.
    while len(todo) and refined < REFINE_MAX:
        progress.update(0.7 + 0.29 * refined / REFINE_MAX, "bounding every triangle")
        batch, todo = todo[:REFINE_BATCH], todo[REFINE_BATCH:]
        fb = f[batch]
        tcand = np.concatenate([cand[fb[:, 0]], cand[fb[:, 1]], cand[fb[:, 2]]], axis=1)
        bound[batch] = _refine(v[fb], tcand, bound[batch], floor, find.table)
        refined += len(batch)
        floor = max(floor, float(bound[batch].max()))
        todo = todo[bound[todo] > floor]
    progress.update(1.0, "proxy measured")
    result = float(bound.max())
    # the corners' figure is itself an upper estimate (nearest candidate, not nearest
    # triangle): never report it above the bound
    return OutsideBound(result, min(at_vertices, result), len(f), refined)


def _nearest_candidate(cand: Array, dist: Array) -> Array:
    """Each point's candidate proxy triangle at the least distance."""
    k = cand.shape[1]
    return cand[np.arange(len(cand)), np.argmin(dist[:, :k], axis=1)]


def _bound(labels: Array, dist: Array, f: Array, v: Array) -> tuple[Array, Array]:
    """Per triangle (corners f into v, candidates per corner): the best of the shared
    candidate bound (convexity) and the corners' distances plus the triangle's size
    (distance is 1-Lipschitz); and whether its corners share their nearest candidate."""
    near = dist.min(axis=1)
    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    first = labels[np.arange(len(labels)), np.argmin(dist, axis=1)]
    # Most triangles have one nearest candidate at all three corners.
    common = (first[a] == first[b]) & (first[a] == first[c])
    bound = np.where(common, np.maximum(near[a], np.maximum(near[b], near[c])), np.inf)
    rest = np.flatnonzero(~common)
    if len(rest):
        fr = f[rest]
        shared = np.full(len(rest), np.inf)
        lb, lc, db_, dc_ = labels[fr[:, 1]], labels[fr[:, 2]], dist[fr[:, 1]], dist[fr[:, 2]]
        for i in range(labels.shape[1]):
            s = labels[fr[:, 0], i][:, None]
            db = np.where(lb == s, db_, np.inf).min(axis=1)
            dc = np.where(lc == s, dc_, np.inf).min(axis=1)
            np.minimum(shared, np.maximum(dist[fr[:, 0], i], np.maximum(db, dc)), out=shared)
        pa, pb, pc = v[fr[:, 0]], v[fr[:, 1]], v[fr[:, 2]]
        l_ab = np.linalg.norm(pa - pb, axis=1)
        l_bc = np.linalg.norm(pb - pc, axis=1)
        l_ca = np.linalg.norm(pc - pa, axis=1)
        lip = np.minimum(np.minimum(near[fr[:, 0]] + np.maximum(l_ab, l_ca),
                                    near[fr[:, 1]] + np.maximum(l_ab, l_bc)),
                         near[fr[:, 2]] + np.maximum(l_bc, l_ca))
        bound[rest] = np.minimum(shared, lip)
    return bound, common


def _cross_bound(v: Array, f: Array, best: Array, table: _Triangles) -> Array:
    """Per triangle: the smallest, over its corners' nearest proxy triangles (`best`, per
    vertex), of the largest distance of its three corners to that proxy triangle (a
    triangle straddling two proxy triangles often lies close to one of them everywhere)."""
    corners = [v[f[:, i]] for i in range(3)]
    out = np.full(len(f), np.inf)
    for i in range(3):
        t = best[f[:, i]]
        worst = table.distance(corners[0], t)
        np.maximum(worst, table.distance(corners[1], t), out=worst)
        np.maximum(worst, table.distance(corners[2], t), out=worst)
        np.minimum(out, worst, out=out)
    return out


def _refine(tri: Array, tcand: Array, bound: Array, floor: float, table: _Triangles,
            depth: int = 0) -> Array:
    """Bounds of the triangles `tri` (n, 3, 3) no larger than `bound`: each is split in four
    at its edge midpoints, and a piece is bounded by the best of its triangle's candidate
    proxy triangles `tcand` (n, m) (largest distance of the piece's corners to it); pieces
    still above `floor` are split again, to `REFINE_DEPTH`. A piece straddling two proxy
    triangles lies closer to one of them everywhere the smaller it is."""
    n = len(tri)
    if depth >= REFINE_DEPTH or n == 0:
        return bound
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    pts = np.stack([a, b, c, (a + b) / 2, (b + c) / 2, (c + a) / 2], axis=1)  # (n, 6, 3)
    m = tcand.shape[1]
    # distance of each of the 6 points of each triangle to each of its m candidates
    d = table.distance(np.repeat(pts, m, axis=0).reshape(-1, 3),
                       np.repeat(tcand, 6, axis=0).ravel()).reshape(n, 6, m)
    pieces = np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]])
    kid = d[:, pieces, :].max(axis=2).min(axis=2)  # (n, 4): best candidate per piece
    more = np.argwhere(kid > floor)  # (parent, piece) pairs to split further
    if len(more) and depth + 1 < REFINE_DEPTH:
        sub = pts[more[:, 0]][np.arange(len(more))[:, None], pieces[more[:, 1]]]
        kid[more[:, 0], more[:, 1]] = _refine(sub, tcand[more[:, 0]], kid[more[:, 0],
                                                                          more[:, 1]],
                                              floor, table, depth + 1)
    return np.minimum(bound, kid.max(axis=1))


def nearest_distances(points: Array, mesh: trimesh.Trimesh) -> Array:
    """Distance from each point to the surface of `mesh`, as an upper bound: exact to the
    nearest of the candidate triangles found through points spread over the mesh."""
    _, dist, _ = _Finder((mesh,), False, 0.0)(np.asarray(points, dtype=np.float64))
    return dist.min(axis=1)
