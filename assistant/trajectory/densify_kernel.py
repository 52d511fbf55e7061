"""`particles.densify_joint_path` and `resample_joint_path` for the RV-2AJ as compiled
loops (numba).

Every transfer's elastic net starts by subdividing the searched joint path until no TCP
chord exceeds an eighth of the particle spacing: a few passes, each a dozen numpy calls
and a batch FK of every row - ~0.1 ms a query (2-3 %), nearly all of it per-call cost.
The steps are the numpy form's, operation for operation (the chord norms summed in order,
the fractions k / parts as float divisions, a + f (b - a) per joint, the same closed-form
FK), so the rows come out the same to the bit (tested against it). The resampling that
follows (`resample_rows`: arc lengths, even targets, interpolation, FK) is another dozen
numpy calls, ~60 us a query; it too follows the numpy form step for step.

Serves (the user-felt figure): the net's particle resampling: under 0.1 s in Python in the
thesis run; a candidate to drop.
"""

from __future__ import annotations

import math

import numpy as np

from assistant.kernels.lazy import kernel
from assistant.robots.rv2aj_fk_batch import tcp_row

Array = np.ndarray


@kernel(cache=True)
def _positions(Q: Array, arm: Array, BP: Array, BM: Array, BK: Array, v: Array,
               tool_offset: bool) -> Array:
    """`tcp_poses`' positions alone: its (N, 3, 3) rotations, unused here, would cost the
    replayed nets ~2 %."""
    n = Q.shape[0]
    P = np.empty((n, 3))
    rot = np.empty((3, 3))
    for k in range(n):
        tcp_row(Q[k], arm, BP, BM, BK, v, tool_offset, P[k], rot)
    return P


@kernel(cache=True)
def densify_rows(Q: Array, max_tcp_step: float, passes: int, arm: Array, BP: Array,
                 BM: Array, BK: Array, v: Array, tool_offset: bool) -> tuple[Array, Array]:
    """(joints, TCP points) of the path Q (M, dof) subdivided linearly, up to `passes`
    times, until no TCP chord exceeds max_tcp_step (`densify_joint_path`)."""
    P = _positions(Q, arm, BP, BM, BK, v, tool_offset)
    dof = Q.shape[1]
    for _ in range(passes):
        m = Q.shape[0] - 1
        parts = np.empty(m, dtype=np.int64)
        longest = 0.0
        total = 0
        for i in range(m):
            dx, dy, dz = P[i + 1, 0] - P[i, 0], P[i + 1, 1] - P[i, 1], P[i + 1, 2] - P[i, 2]
            chord = math.sqrt(dx * dx + dy * dy + dz * dz)
            longest = max(longest, chord)
            parts[i] = max(1, int(math.ceil(chord / max_tcp_step)))
            total += parts[i]
        if longest <= max_tcp_step:
            break
        out = np.empty((total + 1, dof))
        out[0] = Q[0]
        r = 1
        for i in range(m):
            for k in range(1, parts[i] + 1):
                f = k / parts[i]
                for j in range(dof):
                    out[r, j] = Q[i, j] + f * (Q[i + 1, j] - Q[i, j])
                r += 1
        Q = out
        P = _positions(Q, arm, BP, BM, BK, v, tool_offset)
    return Q, P


@kernel(cache=True)
def resample_rows(Q: Array, P: Array, spacing: float, arm: Array, BP: Array, BM: Array,
                  BK: Array, v: Array, tool_offset: bool) -> tuple[Array, Array]:
    """(joints, TCP points) of particles about `spacing` apart along the densified path
    (Q, P) (`particles.resample_joint_path`): the count round(length / spacing) rounded
    half to even as Python's round, targets as `np.linspace` makes them, each target's
    segment as `np.searchsorted(..., side="right") - 1` clipped to the path."""
    m = Q.shape[0] - 1
    seg = np.empty(m)
    s = np.empty(m + 1)
    s[0] = 0.0
    for i in range(m):
        dx, dy, dz = P[i + 1, 0] - P[i, 0], P[i + 1, 1] - P[i, 1], P[i + 1, 2] - P[i, 2]
        seg[i] = math.sqrt(dx * dx + dy * dy + dz * dz)
        s[i + 1] = s[i] + seg[i]
    total = s[m]
    x = total / spacing
    n_seg = math.floor(x)
    if x - n_seg > 0.5 or (x - n_seg == 0.5 and n_seg % 2 == 1):
        n_seg += 1
    n_seg = max(1, int(n_seg))
    step = total / n_seg
    dof = Q.shape[1]
    joints = np.empty((n_seg + 1, dof))
    j = 0  # s[:j + 1] <= t: the segment searchsorted finds (targets ascend)
    for i in range(n_seg + 1):
        t = total if i == n_seg else (i * step if step != 0.0 else i / n_seg * total) + 0.0
        while j + 1 <= m and s[j + 1] <= t:
            j += 1
        k = min(max(j, 0), m - 1)
        f = (t - s[k]) / seg[k] if seg[k] > 0.0 else 0.0
        f = min(max(f, 0.0), 1.0)
        for c in range(dof):
            joints[i, c] = Q[k, c] + f * (Q[k + 1, c] - Q[k, c])
    joints[0] = Q[0]
    joints[n_seg] = Q[m]
    return joints, _positions(joints, arm, BP, BM, BK, v, tool_offset)
