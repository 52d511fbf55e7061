"""Close self pairs of the fast model decided in joint space: a lower bound of their distance
from a table over the two joints their relative pose depends on.

Why: links two joints apart sit side by side in every posture (a UR5's shoulder housing
0-3 cm above its base, its wrists 1-3 cm apart, a Panda's hand 1-3 cm from its forearm).
Capsules around their short, flat-ended housings overlap there in most postures, and FCL on
the meshes for each such posture cost most of a planning query. The relative pose of link
la + 2 in link la depends on q[la] and q[la + 1] only, so the pair's distance is a function
of two angles: a table of it on a grid, with how far the pair can approach between grid
nodes, proves most postures free in a few array operations.

The bound: at a node the table holds, for each capsule c that covers the second shape, the
larger of the real distance (FCL, exact) and the distance from c to the first shape's
capsules (both bound the distance of the part of the shape inside c). Between nodes no point
of c moves more than rho_u |du| + rho_v |dv| relative to the first link (rho: the capsule's
reach from each joint axis), so

    distance(q) >= min over c of (table(node, c) - rho_u,c |du| - rho_v,c |dv|),

a capsule near the joints (small rho) keeping the bound tight where the shapes are close.
Nodes are measured when first asked (process-wide per robot description: the tables do not
depend on the cell) on a grid of `NODES` per joint (per turn where a joint turns further).
"""

from __future__ import annotations

import hashlib
import os
import threading
from pathlib import Path

import fcl
import numpy as np

from assistant.collision.broad_phase import _segment_segment_distance
from assistant.collision.fcl_shapes import fcl_geometry, fcl_transform

Array = np.ndarray

#: Grid nodes per joint (over one turn, or over the joint's range if it is shorter).
NODES = 256
#: Nodes measured since the table was last kept on disk before it is kept again.
SAVE_EVERY = 2000
#: Bump when what a node holds changes: tables kept by the old code are not reused.
TABLE_VERSION = 1
_TABLES: dict[tuple, PairTable] = {}
_LOCK = threading.Lock()


def _rz(a: float) -> Array:
    c, s = np.cos(a), np.sin(a)
    T = np.eye(4)
    T[0, 0], T[0, 1], T[1, 0], T[1, 1] = c, -s, s, c
    return T


def axis_capsules(caps: list) -> list[tuple[Array, Array, float]]:
    """Capsules on a link's own joint axis (z) that contain what the given capsules sweep
    when the link turns about it: a capsule's axial span, its farthest reach from the
    axis as radius (a point within r of the segment lies within r + its end's reach of the
    axis segment, the reach along a segment being largest at an end)."""
    out = []
    for c in caps:
        a, b, r = np.asarray(c[0]), np.asarray(c[1]), float(c[2])
        R = max(np.hypot(a[0], a[1]), np.hypot(b[0], b[1])) + r
        z0, z1 = sorted((float(a[2]), float(b[2])))
        out.append((np.array([0.0, 0.0, z0]), np.array([0.0, 0.0, z1]), float(R)))
    return out


class PairTable:
    """The lazily filled table of one close pair (module docstring).

    The second shape sits in the first link's frame at A Rz(u) B Rz(v) C (C = I for links
    two joints apart). Three joints apart, its own joint turns it as well: the table then
    bounds its distance by that of what it sweeps about its axis (`axis_capsules`, the
    pieces `b_pieces` are those capsules), which depends on u and v alone."""

    def __init__(self, A: Array, B: Array, C: Array, ju: int, shape_a, T_a: Array,
                 b_pieces: list[tuple[object, Array]], caps_a: list, caps_b: list,
                 lower: Array, upper: Array):
        self.ju, self.jv = ju, ju + 1
        self.A, self.B, self.C = (np.asarray(M, dtype=float) for M in (A, B, C))
        self.caps_a = [(np.asarray(c[0]), np.asarray(c[1]), float(c[2])) for c in caps_a]
        self.caps_b = [(np.asarray(c[0]), np.asarray(c[1]), float(c[2])) for c in caps_b]
        self.obj_a = fcl.CollisionObject(fcl_geometry(shape_a), fcl_transform(T_a))
        self.pieces = [(fcl.CollisionObject(fcl_geometry(s)), np.asarray(T, dtype=float))
                       for s, T in b_pieces]
        self._req = fcl.DistanceRequest()
        # each capsule's reach from joint v's axis (z after Rz(v): the capsule sits at C p
        # there) and from joint u's (after Rz(u): at B Rz(v) C p, |Rz(v) C p| = |C p|)
        tB = float(np.hypot(self.B[0, 3], self.B[1, 3]))
        Rc, tc = self.C[:3, :3], self.C[:3, 3]
        self.rho_v = np.array([max(np.hypot(*(Rc @ a + tc)[:2]), np.hypot(*(Rc @ b + tc)[:2]))
                               + r for a, b, r in self.caps_b])
        self.rho_u = np.array([tB + max(np.linalg.norm(Rc @ a + tc), np.linalg.norm(Rc @ b + tc))
                               + r for a, b, r in self.caps_b])
        self.lo, self.step, self.n, self.periodic = [], [], [], []
        for j in (self.ju, self.jv):
            span = float(upper[j] - lower[j])
            periodic = span >= 2.0 * np.pi - 1e-9
            width = 2.0 * np.pi if periodic else max(span, 1e-9)
            n = NODES if periodic else max(2, int(np.ceil(NODES * width / (2.0 * np.pi))) + 1)
            self.lo.append(0.0 if periodic else float(lower[j]))
            self.step.append(width / (n if periodic else n - 1))
            self.n.append(n)
            self.periodic.append(periodic)
        self.S = np.full((self.n[0], self.n[1], len(self.caps_b)), np.nan)
        self.filled = 0
        self.path = None  # where the table is kept between runs (`pair_table`)
        self._saved = 0

    def bounds(self, Q: Array) -> Array:
        """Lower bound (m) of the pair's distance at each row of Q (N, dof)."""
        Q = np.atleast_2d(Q)
        idx, delta = [], []
        for a, j in enumerate((self.ju, self.jv)):
            x = (Q[:, j] - self.lo[a]) / self.step[a]
            i = np.rint(x)
            d = (x - i) * self.step[a]
            i = i.astype(np.int64)
            i = np.mod(i, self.n[a]) if self.periodic[a] else np.clip(i, 0, self.n[a] - 1)
            if not self.periodic[a]:  # a row beyond the range (never, within the limits)
                d = Q[:, j] - (self.lo[a] + i * self.step[a])
            idx.append(i)
            delta.append(np.abs(d))
        S = self.S[idx[0], idx[1]]  # (N, caps)
        todo = np.flatnonzero(np.isnan(S[:, 0]))
        if len(todo):
            for k in np.unique(idx[0][todo] * self.n[1] + idx[1][todo]).tolist():
                self._fill(k // self.n[1], k % self.n[1])
            S = self.S[idx[0], idx[1]]
            if self.filled - self._saved >= SAVE_EVERY:
                self.save()
        lb = S - delta[0][:, None] * self.rho_u[None] - delta[1][:, None] * self.rho_v[None]
        return lb.min(axis=1)

    def _fill(self, iu: int, iv: int) -> None:
        u = self.lo[0] + iu * self.step[0]
        v = self.lo[1] + iv * self.step[1]
        T_rel = self.A @ _rz(u) @ self.B @ _rz(v) @ self.C  # link lb's frame in link la's
        d = np.inf
        for obj, T in self.pieces:
            obj.setTransform(fcl_transform(T_rel @ T))
            d = min(d, float(fcl.distance(self.obj_a, obj, self._req, fcl.DistanceResult())))
        R, t = T_rel[:3, :3], T_rel[:3, 3]
        out = np.empty(len(self.caps_b))
        for c, (a, b, r) in enumerate(self.caps_b):
            a2, b2 = R @ a + t, R @ b + t
            dc = min(_segment_segment_distance(a1, b1, a2, b2) - r1 - r
                     for a1, b1, r1 in self.caps_a)
            out[c] = max(d, dc)
        self.S[iu, iv] = out
        self.filled += 1


    def save(self) -> None:
        """Keep the measured nodes on disk (the next run of the same robot starts with
        them); a cache that cannot be written only costs the measuring again."""
        self._saved = self.filled
        if self.path is None:
            return
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            tmp = self.path.with_suffix(f".{os.getpid()}.tmp.npy")
            np.save(tmp, self.S)
            os.replace(tmp, self.path)
        except OSError:
            pass

    def load(self, path) -> None:
        self.path = path
        try:
            S = np.load(path)
        except (OSError, ValueError):
            return
        if S.shape == self.S.shape:
            self.S = S
            self.filled = self._saved = int(np.count_nonzero(~np.isnan(S[..., 0])))


def pair_table(key: tuple, make) -> PairTable:
    """The process-wide table under `key` (robot description, pair), made once and kept
    in the cache folder between runs ($CELLTEACH_CACHE or ~/.cache/cellteach)."""
    with _LOCK:
        t = _TABLES.get(key)
    if t is None:
        t = make()
        env = os.environ.get("CELLTEACH_CACHE")
        root = Path(env) if env else Path.home() / ".cache" / "cellteach"
        name = hashlib.sha256(f"{key}:n{NODES}:v{TABLE_VERSION}".encode()).hexdigest()[:24]
        t.load(root / "pair_tables" / f"{name}.npy")
        with _LOCK:
            t = _TABLES.setdefault(key, t)
    return t
