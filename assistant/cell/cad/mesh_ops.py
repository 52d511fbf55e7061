"""Mesh repair steps on plain arrays, linear or n log n in the size, for millions of triangles.

trimesh does each of these, but by way of its cached properties and Python loops: on a
2 000 000-triangle part its merge took 8 s, its hole fill 14 s and its winding fix 3 s, its
repair as a whole 45 s. Here every step is a few numpy passes over one sorted edge table
(`EdgeTable`), so the repair of that part takes a few seconds. Vertices (n, 3) float64 and
faces (m, 3) int64 in, new arrays out; nothing is cached on a mesh object.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components

Array = np.ndarray

_MIX = (np.uint64(0x9E3779B97F4A7C15), np.uint64(0xBF58476D1CE4E5B9),
        np.uint64(0x94D049BB133111EB))


def _row_hash(q: Array) -> Array:
    """A 64-bit mix of each row of an (n, 3) int64 array (splitmix-style steps)."""
    u = q.view(np.uint64)
    h = u[:, 0] * _MIX[0]
    h ^= h >> np.uint64(31)
    h = (h + u[:, 1]) * _MIX[1]
    h ^= h >> np.uint64(27)
    h = (h + u[:, 2]) * _MIX[2]
    h ^= h >> np.uint64(31)
    return h


def unique_rows(q: Array) -> tuple[Array, Array]:
    """(index of the first of each distinct row, inverse) of an (n, 3) int64 array, distinct
    rows numbered in order of first appearance. Rows are grouped by a 64-bit hash and the
    grouping is checked exactly (a collision, never seen, falls back to an exact sort)."""
    q = np.ascontiguousarray(q, dtype=np.int64)
    if len(q) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    h = _row_hash(q)
    order = np.argsort(h)
    first, inverse = _groups(h[order], order)
    del h
    if not np.array_equal(q[first[inverse]], q):  # a hash collision: do it exactly
        order = np.lexsort(q.T[::-1])
        qs = q[order]
        same = np.concatenate([[False], np.all(qs[1:] == qs[:-1], axis=1)])
        first, inverse = _groups(np.cumsum(~same), order)
    return first, inverse


def _groups(sorted_keys: Array, order: Array) -> tuple[Array, Array]:
    """First index and inverse of each run of equal sorted keys, runs numbered by their
    first index (the original order kept)."""
    start = np.empty(len(sorted_keys), dtype=bool)
    start[0] = True
    np.not_equal(sorted_keys[1:], sorted_keys[:-1], out=start[1:])
    begins = np.flatnonzero(start)
    first = np.minimum.reduceat(order, begins)
    rank = np.argsort(first)
    new_id = np.empty(len(first), dtype=np.int64)
    new_id[rank] = np.arange(len(first))
    inverse = np.empty(len(order), dtype=np.int64)
    inverse[order] = new_id[np.cumsum(start) - 1]
    return first[rank], inverse


def merge_vertices(vertices: Array, faces: Array, digits: int = 8) -> tuple[Array, Array]:
    """Vertices equal after rounding to `digits` decimals merged into one (trimesh's rule,
    `tol.merge`), faces renumbered; unreferenced vertices dropped."""
    used = np.zeros(len(vertices), dtype=bool)
    used[faces.ravel()] = True
    keep = np.flatnonzero(used)
    q = np.round(vertices[keep] * 10.0**digits).astype(np.int64)
    first, inverse = unique_rows(q)
    del q
    remap = np.full(len(vertices), -1, dtype=np.int64)
    remap[keep] = inverse
    return vertices[keep[first]], remap[faces]


def triangle_areas(vertices: Array, faces: Array, chunk: int = 1_000_000) -> Array:
    out = np.empty(len(faces))
    for k in range(0, len(faces), chunk):
        f = faces[k:k + chunk]
        a = vertices[f[:, 0]]
        c = np.cross(vertices[f[:, 1]] - a, vertices[f[:, 2]] - a)
        out[k:k + chunk] = 0.5 * np.sqrt(np.einsum("ij,ij->i", c, c))
    return out


def degenerate_faces(vertices: Array, faces: Array, min_area: float) -> Array:
    """Mask of faces with a repeated corner or less area than `min_area`."""
    f = faces
    bad = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    return bad | (triangle_areas(vertices, faces) <= min_area)


def duplicate_faces(faces: Array) -> Array:
    """Mask of faces that repeat an earlier face's corners (in any order or winding)."""
    first, inverse = unique_rows(np.sort(faces, axis=1))
    keep = np.zeros(len(faces), dtype=bool)
    keep[first] = True
    return ~keep


def compact(vertices: Array, faces: Array) -> tuple[Array, Array]:
    """Drop the vertices no face uses."""
    used = np.zeros(len(vertices), dtype=bool)
    used[faces.ravel()] = True
    if used.all():
        return vertices, faces
    remap = np.cumsum(used) - 1
    return vertices[used], remap[faces]


@dataclass
class EdgeTable:
    """The directed edges of every face (face k's edges are 3k, 3k+1, 3k+2: a->b, b->c,
    c->a), grouped by the undirected edge they lie on."""

    #: undirected edge key of each directed edge (min * n + max)
    key: Array
    #: directed edges sorted by key
    order: Array
    #: how many directed edges share each directed edge's undirected edge
    count: Array
    n_vertices: int

    @staticmethod
    def of(faces: Array, n_vertices: int) -> EdgeTable:
        a = faces.ravel()
        b = faces[:, [1, 2, 0]].ravel()
        key = np.minimum(a, b) * n_vertices + np.maximum(a, b)
        order = np.argsort(key)
        ks = key[order]
        start = np.empty(len(ks), dtype=bool)
        if len(ks):
            start[0] = True
            np.not_equal(ks[1:], ks[:-1], out=start[1:])
        group = np.cumsum(start) - 1
        sizes = np.bincount(group)
        count = np.empty(len(key), dtype=np.int64)
        count[order] = sizes[group]
        return EdgeTable(key, order, count, n_vertices)

    @property
    def watertight(self) -> bool:
        """Every edge shared by exactly two faces."""
        return bool(len(self.count)) and bool(np.all(self.count == 2))

    def manifold_pairs(self) -> tuple[Array, Array]:
        """Directed-edge pairs (i, j) lying on an edge exactly two faces share."""
        two = self.order[self.count[self.order] == 2]
        return two[0::2], two[1::2]


def face_adjacency(faces: Array, edges: EdgeTable) -> tuple[Array, Array, Array]:
    """Faces sharing a manifold edge: (face i, face j, wound alike) per shared edge; wound
    alike means both run the edge the same way, which consistent winding forbids."""
    i, j = edges.manifold_pairs()
    a = faces.ravel()
    same = a[i] == a[j]  # both directed edges start at the same vertex
    return i // 3, j // 3, same


def face_components(n_faces: int, fi: Array, fj: Array) -> tuple[int, Array]:
    """Connected pieces over shared manifold edges: their number and each face's piece."""
    graph = coo_matrix((np.ones(len(fi), dtype=np.int8), (fi, fj)), shape=(n_faces, n_faces))
    n, labels = connected_components(graph, directed=False)
    return int(n), labels


def consistent_flips(n_faces: int, fi: Array, fj: Array, same: Array,
                     labels: Array) -> Array:
    """Which faces to turn over so that faces sharing an edge run it in opposite ways.

    A spanning tree of each piece (breadth first from a virtual root tied to one face per
    piece) fixes every face relative to its piece's first face: a face is turned when the
    tree path to it crosses an odd number of edges wound alike. Pieces that cannot be
    oriented (a Moebius strip) keep the conflict on their non-tree edges."""
    n_labels = int(labels.max()) + 1 if len(labels) else 0
    root = n_faces
    firsts = np.full(n_labels, -1, dtype=np.int64)
    firsts[labels[::-1]] = np.arange(n_faces)[::-1]
    rows = np.concatenate([fi, fj, np.full(n_labels, root)])
    cols = np.concatenate([fj, fi, firsts])
    graph = coo_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)),
                       shape=(n_faces + 1, n_faces + 1)).tocsr()
    _, pred = breadth_first_order(graph, root, directed=True, return_predecessors=True)
    pred = pred[:n_faces].astype(np.int64)
    # the parity of each face's tree edge, looked up by the (smaller, larger) face pair
    pair = np.minimum(fi, fj) * (n_faces + 1) + np.maximum(fi, fj)
    order = np.argsort(pair, kind="stable")
    pair_s, same_s = pair[order], same[order]
    acc = np.zeros(n_faces + 1, dtype=bool)
    f = np.flatnonzero((pred >= 0) & (pred != root))
    if len(f):
        q = np.minimum(f, pred[f]) * (n_faces + 1) + np.maximum(f, pred[f])
        acc[f] = same_s[np.searchsorted(pair_s, q)]
    anc = np.append(np.where(pred >= 0, pred, root), root)
    # pointer jumping: after k rounds acc is the parity of the first 2^k tree edges
    while np.any(anc != root):
        acc = acc ^ np.where(anc != root, acc[anc], False)
        anc = anc[anc]
    return acc[:n_faces]


def small_hole_faces(faces: Array, edges: EdgeTable, fillable_vertex: Array) -> Array:
    """Faces closing every hole of 3 or 4 boundary edges whose corners are all `fillable`,
    wound like the faces around it (the holes trimesh's `fill_holes` closes)."""
    single = np.flatnonzero(edges.count == 1)
    if len(single) == 0:
        return np.zeros((0, 3), dtype=np.int64)
    a = faces.ravel()
    b = faces[:, [1, 2, 0]].ravel()
    u, v = a[single], b[single]
    n = edges.n_vertices
    out_count = np.bincount(u, minlength=n)
    out_edge = np.full(n, -1, dtype=np.int64)
    out_edge[u] = np.arange(len(single))
    ok = (out_count[v] == 1) & (out_count[u] == 1)
    nxt = np.where(ok, out_edge[v], -1)
    new: list[Array] = []
    idx = np.arange(len(single))
    n1 = nxt
    n2 = np.where(n1 >= 0, nxt[np.maximum(n1, 0)], -1)
    n3 = np.where(n2 >= 0, nxt[np.maximum(n2, 0)], -1)
    n4 = np.where(n3 >= 0, nxt[np.maximum(n3, 0)], -1)
    tri = (n3 == idx) & (n1 != idx) & (idx < n1) & (idx < n2)
    quad = (n4 == idx) & (n2 != idx) & (n1 != idx) & (idx < n1) & (idx < n2) & (idx < n3)
    if tri.any():
        e0, e1, e2 = idx[tri], n1[tri], n2[tri]
        t = np.column_stack([u[e0], u[e2], u[e1]])  # a, c, b: runs the rim backwards
        new.append(t[fillable_vertex[t].all(axis=1)])
    if quad.any():
        e0, e1, e2, e3 = idx[quad], n1[quad], n2[quad], n3[quad]
        p, q, r, s = u[e0], u[e1], u[e2], u[e3]
        keep = fillable_vertex[np.column_stack([p, q, r, s])].all(axis=1)
        new.append(np.column_stack([p, s, r])[keep])
        new.append(np.column_stack([p, r, q])[keep])
    return np.vstack(new) if new else np.zeros((0, 3), dtype=np.int64)


def flat_pieces(vertices: Array, vertex_label: Array, n: int) -> Array:
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
    return (count < 4) | (ev[:, 0] <= 1e-12 * np.maximum(ev[:, 2], 1e-60))


def closed_pieces(faces: Array, edges: EdgeTable, fi: Array, same: Array, labels: Array,
                  n: int) -> Array:
    """Per piece: True if every edge of it is shared by exactly two of its faces, which run
    it in opposite directions (closed and consistently wound)."""
    bad = np.zeros(n, dtype=bool)
    bad[np.repeat(labels, 3)[edges.count != 2]] = True
    bad[labels[fi[same]]] = True
    return ~bad


def piece_volumes(vertices: Array, faces: Array, labels: Array, n: int) -> Array:
    """Signed volume of each piece (about one of its own vertices: no cancellation far away)."""
    first = np.full(n, -1)
    first[labels[::-1]] = faces[::-1, 0]
    o = vertices[first[labels]]
    v0, v1, v2 = (vertices[faces[:, k]] - o for k in range(3))
    det = np.einsum("ij,ij->i", v0, np.cross(v1, v2))
    return np.bincount(labels, det, minlength=n) / 6.0
