"""Capsules that contain a robot shape: the pieces of the fast collision model.

Why: a URDF arm's links are meshes (a UR5's: 230-600 vertices each, a Panda's 100-150) and
an exact mesh test through FCL costs tens of microseconds a pair, plus the Python around it;
a planner asks thousands. A capsule against a box is a closed-form distance the compiled
broad phase already computes (`segment_box`), so a link covered by a few capsules is
checked in the same pass that poses it (`fast_model`).

Conservative by construction: a capsule is convex, so one that contains a triangle's three
vertices contains the triangle; every face of a mesh (and every vertex) is assigned to one
capsule that contains all its vertices, so the union of the capsules contains the mesh. A
box is covered by the capsule around its 8 corners, a cylinder by the capsule of its radius
and length, a capsule or a sphere is itself. The radii are padded by `PAD` (m), so a
configuration the fast model calls free has every real shape more than `PAD` from every
obstacle box - well above FCL's own tolerance (the exact check's answers stay FCL's).

How many capsules: a mesh starts as one capsule around all its vertices; the cluster whose
split (along its principal axis, at the cut among a few quantiles of the face centres that
gives the smallest total volume) saves the most volume is split, while that saves at least
`gain` of the cluster's volume and the mesh has fewer than `max_capsules`. A UR5's upper arm
(a tube with a bulge at each joint) becomes three capsules; a wrist stays one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.collision.bounding_capsule import capsule_around
from assistant.robots.model import CollisionShape, ShapeKind

Array = np.ndarray

#: Longest triangle edge (m) of a mesh before it is covered: a capsule holds whole
#: triangles, and a CAD fan of triangles from the centre of a disc to its rim would
#: otherwise force every capsule to span the disc (subdividing keeps the surface).
MAX_EDGE = 0.03
#: Radius padding (m) of every capsule of the fast model: its "free" means more than this
#: away from every obstacle box (FCL's own tolerances are far below it).
PAD = 1e-5


@dataclass(frozen=True)
class Capsule:
    """Axis segment a-b (owner frame) and radius."""

    a: Array
    b: Array
    r: float

    @property
    def volume(self) -> float:
        L = float(np.linalg.norm(self.b - self.a))
        return float(np.pi * self.r ** 2 * L + 4.0 / 3.0 * np.pi * self.r ** 3)

    def shape(self) -> CollisionShape:
        """As a collision shape (a sphere where the segment is a point)."""
        if float(np.linalg.norm(self.b - self.a)) <= 1e-12:
            T = np.eye(4)
            T[:3, 3] = self.a
            return CollisionShape(ShapeKind.SPHERE, (self.r,), T)
        return CollisionShape.capsule_between(self.a, self.b, self.r)


def cover_shape(shape: CollisionShape, *, max_capsules: int = 4, gain: float = 0.2,
                axes: Array | None = None, lines: list[tuple[Array, Array]] | None = None,
                ) -> list[Capsule]:
    """Capsules (in the shape's owner frame) whose union contains the shape (module
    docstring); radii padded by `PAD`."""
    T = np.asarray(shape.T_link_shape, dtype=float)
    k = shape.kind
    if k in (ShapeKind.CAPSULE, ShapeKind.CYLINDER):
        r, length = float(shape.size[0]), float(shape.size[1])
        a, b = T[:3, 3] - 0.5 * length * T[:3, 2], T[:3, 3] + 0.5 * length * T[:3, 2]
        return [Capsule(a, b, r + PAD)]  # a cylinder lies inside the capsule of its size
    if k == ShapeKind.SPHERE:
        return [Capsule(T[:3, 3].copy(), T[:3, 3].copy(), float(shape.size[0]) + PAD)]
    if k == ShapeKind.BOX:
        s = np.asarray(shape.size, dtype=float) / 2.0
        corners = np.array([[x, y, z] for x in (-s[0], s[0]) for y in (-s[1], s[1])
                            for z in (-s[2], s[2])])
        a, b, r = capsule_around(corners @ T[:3, :3].T + T[:3, 3])
        return [Capsule(a, b, r + PAD)]
    if shape.mesh is None:
        raise ValueError("a mesh collision shape without a mesh")
    V = np.asarray(shape.mesh.vertices, dtype=float) @ T[:3, :3].T + T[:3, 3]
    faces = np.asarray(shape.mesh.faces, dtype=np.int64).reshape(-1, 3)
    V, faces = subdivided(V, faces, MAX_EDGE)
    return [Capsule(a, b, r + PAD) for a, b, r in
            mesh_capsules(V, faces, max_capsules=max_capsules, gain=gain, axes=axes,
                          lines=lines)]


def subdivided(V: Array, faces: Array, max_edge: float) -> tuple[Array, Array]:
    """The same surface with no triangle edge longer than `max_edge` (trimesh's
    subdivision: new vertices on the old edges)."""
    import trimesh

    if len(faces) == 0:
        return V, faces
    V2, F2 = trimesh.remesh.subdivide_to_size(V, faces, max_edge=max_edge, max_iter=12)
    return np.asarray(V2, dtype=float), np.asarray(F2, dtype=np.int64)


def mesh_capsules(V: Array, faces: Array, *, max_capsules: int = 4, gain: float = 0.2,
                  axes: Array | None = None, lines: list[tuple[Array, Array]] | None = None,
                  ) -> list[tuple[Array, Array, float]]:
    """(a, b, r) per capsule: every face's vertices inside one capsule, every vertex in one
    (vertices no face uses count as faces of their own).

    Candidates: one capsule around everything; a capsule per line of `lines` (a link's
    joint axes and the segment between them, `line_capsules`); and 2 to `max_capsules`
    slabs of equal face counts across each principal direction of the face centres, each
    slab's capsule along whichever of its own principal axes and `axes` fits it smallest
    (`capsule_best`: strips across a disc, sections of a tube). Of these, the fewest
    capsules whose total volume is within `gain` of the smallest."""
    used = np.zeros(len(V), dtype=bool)
    used[faces.reshape(-1)] = True
    G = np.array([f for f in faces] + [np.array([i, i, i]) for i in np.flatnonzero(~used)],
                 dtype=np.int64)
    if not len(G):
        return []
    cands = [[capsule_around(V)]]
    if lines:
        cands.append(line_capsules(V, faces, lines))
    centres = V[G].mean(axis=1)
    X = centres - centres.mean(axis=0)
    if len(X) > 2:
        for d in np.linalg.svd(X, full_matrices=False)[2]:
            order = np.argsort(X @ d, kind="stable")
            for k in range(2, max_capsules + 1):
                runs = np.array_split(order, k)
                cands.append(_shrink(V, G, [r for r in runs if len(r)], axes))
    vols = union_volumes(cands)
    smallest = min(vols)
    ok = [i for i, v in enumerate(vols) if v <= (1.0 + gain) * smallest]
    return cands[min(ok, key=lambda i: (len(cands[i]), vols[i]))]


def _shrink(V: Array, G: Array, runs: list[Array], axes: Array | None, rounds: int = 6,
            ) -> list[tuple[Array, Array, float]]:
    """Fit a capsule to each run of faces, then hand every face to the smallest capsule
    that already contains it and fit again, while that shrinks the total volume: slabs
    cut a housing from the tube it meets, but a face at the seam fits inside either."""
    caps = [capsule_best(V[np.unique(G[run])], axes) for run in runs]
    labels = np.empty(len(G), dtype=np.int64)
    for c, run in enumerate(runs):
        labels[run] = c
    vol = sum(_volume(c) for c in caps)
    for _ in range(rounds):
        order = np.argsort([r for _, _, r in caps])  # smallest radius first
        new = labels.copy()
        taken = np.zeros(len(G), dtype=bool)
        for c in order.tolist():
            a, b, r = caps[c]
            inside = _segment_distance(V, a, b)[G].max(axis=1) <= r
            new[inside & ~taken] = c
            taken |= inside
        if np.array_equal(new, labels):
            break
        fitted = [capsule_best(V[np.unique(G[new == c])], axes) if (new == c).any() else None
                  for c in range(len(caps))]
        fitted = [f for f in fitted if f is not None]
        v = sum(_volume(c) for c in fitted)
        if v >= vol:
            break
        kept = [c for c in range(len(caps)) if (new == c).any()]
        labels = np.searchsorted(np.array(kept), new)
        caps, vol = fitted, v
    return caps


def line_capsules(V: Array, faces: Array, lines: list[tuple[Array, Array]],
                  ) -> list[tuple[Array, Array, float]]:
    """(a, b, r) per capsule: every face to the line (point, unit direction) nearest its
    vertices, a capsule around each line's faces along that direction, then `_shrink`.
    Lines are a link's joint axes and the segment between them: a housing about each
    axis, a tube between."""
    used = np.zeros(len(V), dtype=bool)
    used[faces.reshape(-1)] = True
    G = np.array([f for f in faces] + [np.array([i, i, i]) for i in np.flatnonzero(~used)],
                 dtype=np.int64)
    if not len(G):
        return []
    dist = []
    for p, d in lines:
        X = V - p
        t = X @ d
        dist.append(np.sqrt(np.maximum((X * X).sum(axis=1) - t * t, 0.0))[G].max(axis=1))
    label = np.argmin(np.stack(dist, axis=1), axis=1)
    runs = [np.flatnonzero(label == i) for i in range(len(lines))]
    dirs = np.array([d for _, d in lines])
    return _shrink(V, G, [r for r in runs if len(r)], dirs)


def capsule_best(P: Array, axes: Array | None = None) -> tuple[Array, Array, float]:
    """The smallest of the capsules around the points P along their principal axes and
    the given `axes` (unit rows; a link's joint axes: a joint housing is a short cylinder
    about its axis, and only a capsule along that axis fits it)."""
    if len(P) < 2:
        return capsule_around(P)
    X = P - P.mean(axis=0)
    dirs = list(np.linalg.svd(X, full_matrices=False)[2])
    if axes is not None:
        dirs += [np.asarray(a, dtype=float) / np.linalg.norm(a) for a in axes]
    best = capsule_around(P)
    for d in dirs:
        cap = capsule_along(P, d)
        if _volume(cap) < _volume(best):
            best = cap
    return best


def capsule_along(P: Array, axis: Array, iterations: int = 20,
                  ) -> tuple[Array, Array, float]:
    """A capsule around the points P whose segment is parallel to `axis`: its line
    through the (approximate, Badoiu-Clarkson) centre of the smallest circle around the
    points projected across the axis, its radius their largest distance from that line
    (exact for the line chosen), the ends pulled in as `capsule_around` does."""
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    t = P @ axis
    Y = P - np.outer(t, axis)  # projections onto the plane through 0 across the axis
    c = 0.5 * (Y.min(axis=0) + Y.max(axis=0))
    c -= (c @ axis) * axis  # in the plane (a box's middle need not be): the line's point
    for i in range(2, iterations + 2):
        far = Y[int(np.argmax(((Y - c) ** 2).sum(axis=1)))]
        c = c + (far - c) / (i + 1)
    c -= (c @ axis) * axis  # rounding: the ends below are measured from the plane
    d2 = ((Y - c) ** 2).sum(axis=1)
    r = float(np.sqrt(d2.max()))
    slack = np.sqrt(np.maximum(r * r - d2, 0.0))
    lo, hi = float((t + slack).min()), float((t - slack).max())
    if lo > hi:
        m = 0.5 * (lo + hi)
        p = c + m * axis
        return p, p.copy(), _pad_up(float(np.sqrt(((P - p) ** 2).sum(axis=1).max())))
    return c + lo * axis, c + hi * axis, _pad_up(r)


def _pad_up(r: float) -> float:
    """A hair larger: the distances were rounded once more than the checks' will be."""
    return r * (1.0 + 1e-9) + 1e-12


def _segment_distance(P: Array, a: Array, b: Array) -> Array:
    d = b - a
    L2 = float(d @ d)
    t = np.zeros(len(P)) if L2 <= 0.0 else np.clip((P - a) @ d / L2, 0.0, 1.0)
    return np.linalg.norm(P - (a + t[:, None] * d), axis=1)


def union_volumes(cands: list[list[tuple[Array, Array, float]]], n: int = 20000,
                  seed: int = 0) -> list[float]:
    """The volume of each candidate's union of capsules (m^3), by the same `n` random
    points in a box around them all (overlaps counted once, unlike a sum of volumes)."""
    ends = np.array([p for caps in cands for a, b, r in caps for p in (a - r, b + r, a + r,
                                                                          b - r)])
    lo, hi = ends.min(axis=0), ends.max(axis=0)
    P = np.random.default_rng(seed).uniform(lo, hi, size=(n, 3))
    box = float(np.prod(hi - lo))
    out = []
    for caps in cands:
        inside = np.zeros(n, dtype=bool)
        for a, b, r in caps:
            inside |= _segment_distance(P, a, b) <= r
        out.append(box * float(inside.mean()))
    return out


def _volume(cap: tuple[Array, Array, float]) -> float:
    a, b, r = cap
    return Capsule(a, b, r).volume
