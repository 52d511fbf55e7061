"""The samples of a batch of roadmap edges and each edge's first invalid one.

The lazy search checks its path's edges in one batched call (`edge_check.EdgeCheck`); these
lay out every edge's samples a + (k / n) (b - a), k = 0..n, and find each edge's first
invalid sample (a few numpy calls, ~0.03 ms a call).
"""

from __future__ import annotations

import numpy as np

Array = np.ndarray


def edge_samples(Q0: Array, Q1: Array, ns: Array) -> tuple[Array, Array, Array]:
    """(samples, edge of each, its fraction k / n) of the edges Q0[i] -> Q1[i], edge i in
    ns[i] steps (ns[i] + 1 samples, both ends included), edge after edge."""
    ns = np.asarray(ns, dtype=np.int64)
    edge = np.repeat(np.arange(len(ns)), ns + 1)
    k = np.arange(len(edge)) - np.repeat(np.cumsum(ns + 1) - (ns + 1), ns + 1)
    F = k / ns[edge]
    Q = Q0[edge] + F[:, None] * (Q1[edge] - Q0[edge])
    return Q, edge, F


def first_invalid(ok: Array, edge: Array, F: Array, n_edges: int) -> Array:
    """Per edge the fraction of its first sample with ok False, NaN if all are valid."""
    out = np.full(n_edges, np.nan)
    bad = np.flatnonzero(~np.asarray(ok, dtype=bool))
    # samples are laid out edge after edge: an edge's first bad sample is its first in `bad`
    e, first = np.unique(edge[bad], return_index=True)
    out[e] = F[bad[first]]
    return out
