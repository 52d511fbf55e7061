"""Whether a shape's vertices all lie beyond one face plane of a box, row by row (numba).

The certificate's cheap exact test (`certify_path._outside_box`): a mesh is its triangles,
each the convex hull of three of its vertices, so a mesh whose every vertex lies beyond a
face plane of a box lies wholly beyond it. Each row tries first the face that cleared the
row before (a path moves little from sample to sample), then the others; a face stops at
the first vertex short of it, so a cleared row costs about one pass over the vertices (a
UR5 link's 230-600). As numpy products over every vertex this cost ~19 ns a vertex and
row on the shared machine, about as much as the FCL tests it saves.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.lazy import kernel

Array = np.ndarray


def vertices_beyond_numpy(T: Array, Rb: Array, cb: Array, h: Array, V: Array, slack: float,
                          out: Array) -> None:
    """`vertices_beyond` with numpy products (its fallback until compiled)."""
    for lo in range(0, len(T), 256):
        sl = slice(lo, lo + 256)
        Rt = np.swapaxes(Rb[sl], 1, 2)
        M = Rt @ T[sl, :3, :3]
        u = np.einsum("nij,nj->ni", Rt, T[sl, :3, 3] - cb[sl])
        Y = np.einsum("nij,kj->nik", M, V) + u[:, :, None]
        gap = np.concatenate([Y.min(axis=2) - h, -Y.max(axis=2) - h], axis=1)
        out[sl] = gap.max(axis=1) > slack


@kernel(cache=True, fallback=vertices_beyond_numpy)
def vertices_beyond(T: Array, Rb: Array, cb: Array, h: Array, V: Array, slack: float,
                    out: Array) -> None:
    """out[r] = every point V[k] (a shape's frame) posed by T[r] (4 x 4) lies more than
    `slack` beyond one face plane of the box of rotation Rb[r], centre cb[r] and half
    extents h along Rb[r]'s columns."""
    nv = V.shape[0]
    last = 0
    for r in range(T.shape[0]):
        out[r] = False
        for t in range(6):
            f = (last + t) % 6
            a = f % 3
            s = 1.0 if f < 3 else -1.0
            # the face's outward normal in the shape's frame, and the shape's origin on it
            m0 = s * (Rb[r, 0, a] * T[r, 0, 0] + Rb[r, 1, a] * T[r, 1, 0]
                      + Rb[r, 2, a] * T[r, 2, 0])
            m1 = s * (Rb[r, 0, a] * T[r, 0, 1] + Rb[r, 1, a] * T[r, 1, 1]
                      + Rb[r, 2, a] * T[r, 2, 1])
            m2 = s * (Rb[r, 0, a] * T[r, 0, 2] + Rb[r, 1, a] * T[r, 1, 2]
                      + Rb[r, 2, a] * T[r, 2, 2])
            o = s * (Rb[r, 0, a] * (T[r, 0, 3] - cb[r, 0]) + Rb[r, 1, a] * (T[r, 1, 3] - cb[r, 1])
                     + Rb[r, 2, a] * (T[r, 2, 3] - cb[r, 2]))
            need = h[a] + slack - o  # every m . v must exceed this
            ok = True
            for k in range(nv):
                if m0 * V[k, 0] + m1 * V[k, 1] + m2 * V[k, 2] <= need:
                    ok = False
                    break
            if ok:
                out[r] = True
                last = f
                break
