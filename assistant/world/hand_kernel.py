"""Whether each posture's hand fills a marked leaf, in one compiled pass (numba).

Serves the re-plan after a Collision! indication on a 6/7-axis arm (the operator waits, the
arm halted): the joint-space search there asks `HandCells.blocked` for every step it takes,
a few to a few dozen postures at a time, ~300 times a re-plan. In numpy each question posed
all of the hand's ~400-500 points per posture through a dozen array operations (points, a
distance to the TCP, leaf indices, a gather): a third of a Panda re-plan. Here a posture
stops at its first hand point in a marked leaf.

The arithmetic is `HandCells._points`' own: a point of link k at `local` is
frames[k] (local, 1); it belongs to the hand within `reach` of the TCP; its leaf is the
grid's (`leaf_lookup.leaf_flag`).
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.lazy import kernel
from assistant.world.leaf_lookup import leaf_flag

Array = np.ndarray


def hand_blocked_numpy(frames: Array, link: Array, local: Array, tcp: Array, reach2: float,
                       origin: Array, leaf: float, n: int, mask: Array, out: Array) -> None:
    """`hand_blocked` as whole-array numpy (its fallback until compiled)."""
    F = frames[:, link]  # (N, M, 4, 4)
    P = np.einsum("nmij,mj->nmi", F[..., :3, :3], local) + F[..., :3, 3]
    d = P - tcp[:, None, :]
    near = np.einsum("nmi,nmi->nm", d, d) <= reach2
    f = np.floor((P - origin) / leaf)
    inside = np.all((f >= 0) & (f < n), axis=2)
    fi = np.where(inside[..., None], f, 0).astype(np.int64)
    flat = (fi[..., 0] * n + fi[..., 1]) * n + fi[..., 2]
    hit = near & inside & mask[flat]
    t = np.floor((tcp - origin) / leaf)
    t_in = np.all((t >= 0) & (t < n), axis=1)
    ti = np.where(t_in[:, None], t, 0).astype(np.int64)
    out[:] = hit.any(axis=1) | (t_in & mask[(ti[:, 0] * n + ti[:, 1]) * n + ti[:, 2]])


@kernel(cache=True, fallback=hand_blocked_numpy)
def hand_blocked(frames: Array, link: Array, local: Array, tcp: Array, reach2: float,
                 origin: Array, leaf: float, n: int, mask: Array, out: Array) -> None:
    """out[r]: the TCP of row r, or a point local[m] of link link[m] posed by frames[r]
    (rows, links, 4, 4) within sqrt(reach2) of the TCP, lies in a leaf set in `mask`
    (flat over the grid's n^3 leaves, origin and leaf size as `OctreeGrid`)."""
    for r in range(frames.shape[0]):
        tx, ty, tz = tcp[r, 0], tcp[r, 1], tcp[r, 2]
        hit = leaf_flag(tx, ty, tz, origin, leaf, n, mask)
        m = 0
        while not hit and m < local.shape[0]:
            F = frames[r, link[m]]
            x = F[0, 0] * local[m, 0] + F[0, 1] * local[m, 1] + F[0, 2] * local[m, 2] + F[0, 3]
            y = F[1, 0] * local[m, 0] + F[1, 1] * local[m, 1] + F[1, 2] * local[m, 2] + F[1, 3]
            z = F[2, 0] * local[m, 0] + F[2, 1] * local[m, 1] + F[2, 2] * local[m, 2] + F[2, 3]
            if (x - tx) ** 2 + (y - ty) ** 2 + (z - tz) ** 2 <= reach2:
                hit = leaf_flag(x, y, z, origin, leaf, n, mask)
            m += 1
        out[r] = hit
