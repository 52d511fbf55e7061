"""The bookkeeping of one elastic-net sweep around its move tests, compiled (numba).

`elastic_net._Net.iterate` proposes the sweep's moves, halves those of pinned particles,
tests them, retries the refused ones at half length and re-pins. As numpy calls that is
about a dozen array operations per sweep, more than the arithmetic; compiled, each of the
~40 sweeps of a query is ~6 us shorter. These three kernels do the same steps, element for
element (tests/planning/test_net_kernel.py runs the net with the numpy form as
reference and compares the particles to the bit).

Serves (the user-felt figure): the net's bookkeeping: under 0.1 s in Python in the thesis
run; a candidate to drop.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.lazy import kernel
from assistant.trajectory.net_forces import propose_moves

Array = np.ndarray


@kernel(cache=True)
def sweep_moves(P: Array, pinned: Array, stage: int, lam: float, c_eq: float, c_rot: float,
                c_sh: float, c_line: float, stage1_shrink: float, r_max: float, r_min: float,
                max_move: float) -> tuple[Array, Array, Array, Array]:
    """`propose_moves`, keeping the moves of non-zero length: (particles, moves, tentative
    positions, pinned flag per move); a pinned particle's move is halved straight away
    (and its tentative position with it)."""
    idx0, D0, trial = propose_moves(P, stage, lam, c_eq, c_rot, c_sh, c_line, stage1_shrink,
                                    r_max, r_min, max_move)
    m = 0
    live = np.zeros(idx0.shape[0], dtype=np.bool_)
    for i in range(idx0.shape[0]):
        # the norm's test: sqrt(sum of squares) > 0 (NaN and underflow included)
        s = D0[i, 0] * D0[i, 0] + D0[i, 1] * D0[i, 1] + D0[i, 2] * D0[i, 2]
        live[i] = s > 0.0
        m += live[i]
    idx = np.empty(m, dtype=np.int64)
    D = np.empty((m, 3))
    pin = np.zeros(m, dtype=np.bool_)
    r = 0
    for i in range(idx0.shape[0]):
        if not live[i]:
            continue
        k = idx0[i]
        idx[r] = k
        D[r] = D0[i]
        if pinned[k]:
            pin[r] = True
            for c in range(3):
                D[r, c] *= 0.5
                trial[k, c] = P[k, c] + D[r, c]
        r += 1
    return idx, D, trial, pin


@kernel(cache=True)
def halve_retries(ok: Array, pin: Array, idx: Array, D: Array, trial: Array, P: Array,
                  ) -> Array:
    """Rows refused at full length and not pinned: their moves (and tentative positions)
    halved for a second test; returns those rows."""
    rows = np.empty(ok.shape[0], dtype=np.int64)
    n = 0
    for i in range(ok.shape[0]):
        if ok[i] or pin[i]:
            continue
        k = idx[i]
        for c in range(3):
            D[i, c] *= 0.5
            trial[k, c] = P[k, c] + D[i, c]
        rows[n] = i
        n += 1
    return rows[:n]


@kernel(cache=True)
def repin(ok: Array, pin: Array, retry: Array, ok2: Array, idx: Array, pinned: Array,
          ) -> int:
    """Merge the retries' answers into ok and pin (in place) the particles refused at
    both lengths, or at half length when pinned; returns how many were refused."""
    refused = np.zeros(ok.shape[0], dtype=np.bool_)
    for i in range(ok.shape[0]):
        refused[i] = not ok[i] and pin[i]
    for r in range(retry.shape[0]):
        if ok2[r]:
            ok[retry[r]] = True
        else:
            refused[retry[r]] = True
    pinned[:] = False
    n = 0
    for i in range(ok.shape[0]):
        if refused[i]:
            pinned[idx[i]] = True
            n += 1
    return n
