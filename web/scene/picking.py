"""Where a click ray meets a part: viser reports the ray, the page needs the surface point and
its normal for CAD-click teaching. Pure geometry (the view's concern) on the part at full
resolution - a big part is drawn decimated, but the taught point lies on the part itself."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

Array = np.ndarray


@dataclass(frozen=True)
class Hit:
    point_world: Array
    normal_world: Array
    distance: float


#: Faces tested per block: bounds the temporary arrays on a part of millions of triangles
#: (~0.1 s per million faces) instead of caching every corner of the part.
_BLOCK = 250_000


def pick(mesh: trimesh.Trimesh, T_world_object: Array, ray_origin: Array,
         ray_direction: Array) -> Hit | None:
    """The first intersection of a world ray with the mesh placed at T (None: missed)."""
    T = np.asarray(T_world_object, float)
    R, t = T[:3, :3], T[:3, 3]
    o = R.T @ (np.asarray(ray_origin, float) - t)
    d = R.T @ np.asarray(ray_direction, float)
    n = np.linalg.norm(d)
    if n < 1e-12:
        return None
    d = d / n
    v = mesh.vertices.view(np.ndarray)
    f = mesh.faces.view(np.ndarray)
    best: Hit | None = None
    for k in range(0, len(f), _BLOCK):
        hit = _first_hit(v[f[k:k + _BLOCK]], o, d)
        if hit is not None and (best is None or hit[0] < best.distance):
            dist, nrm = hit
            best = Hit(R @ (o + dist * d) + t, R @ nrm, dist)
    return best


def _first_hit(tri: Array, o: Array, d: Array) -> tuple[float, Array] | None:
    """Moller-Trumbore over a block of triangles (F, 3, 3): (distance, normal facing the
    ray) of the nearest hit, or None."""
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = o - tri[:, 0]
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ d) * inv
    dist = np.einsum("ij,ij->i", e2, q) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (dist > 1e-9)
    if not np.any(hit):
        return None
    k = int(np.argmin(np.where(hit, dist, np.inf)))
    nrm = np.cross(e1[k], e2[k])
    nrm = nrm / np.linalg.norm(nrm)
    if nrm @ d > 0:  # face the camera
        nrm = -nrm
    return float(dist[k]), nrm
