"""The samples of a batch of roadmap edges and each edge's first invalid one, compiled
(numba).

Why: the lazy search checks its path's edges in one batched call (`planner._EdgeCheck`);
laying out every edge's samples and finding each edge's first invalid sample take a dozen
numpy calls around it (~0.03 ms a call, two or three calls a query). The samples are the
numpy form's, number for number: a + (k / n) (b - a), k = 0..n.

Serves (the user-felt figure): the roadmap's batched edge checks: 0.1 s in Python in the
thesis run; a candidate to drop.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.lazy import kernel

Array = np.ndarray


@kernel(cache=True)
def edge_samples(Q0: Array, Q1: Array, ns: Array) -> tuple[Array, Array, Array]:
    """(samples, edge of each, its fraction k / n) of the edges Q0[i] -> Q1[i], edge i in
    ns[i] steps (ns[i] + 1 samples, both ends included), edge after edge."""
    m = 0
    for i in range(ns.shape[0]):
        m += ns[i] + 1
    dof = Q0.shape[1]
    Q = np.empty((m, dof))
    edge = np.empty(m, dtype=np.int64)
    F = np.empty(m)
    r = 0
    for i in range(ns.shape[0]):
        for k in range(ns[i] + 1):
            f = k / ns[i]
            edge[r], F[r] = i, f
            for j in range(dof):
                Q[r, j] = Q0[i, j] + f * (Q1[i, j] - Q0[i, j])
            r += 1
    return Q, edge, F


@kernel(cache=True)
def first_invalid(ok: Array, edge: Array, F: Array, n_edges: int) -> Array:
    """Per edge the fraction of its first sample with ok False, NaN if all are valid."""
    out = np.full(n_edges, np.nan)
    for r in range(ok.shape[0]):
        if not ok[r] and np.isnan(out[edge[r]]):
            out[edge[r]] = F[r]
    return out
