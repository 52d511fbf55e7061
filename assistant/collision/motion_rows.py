"""The bookkeeping around `CollisionChecker.is_valid_samples`, compiled (numba).

A roadmap edge or a verification chunk is a few dozen samples; as numpy calls, marking the
motions' ends, the link frames, the limit test and picking each motion's rows before its
first invalid one cost more than the compiled certification itself. The answers are the
numpy forms', bit for bit (the link frames are `dh.chain_row`'s, the limit test
`JointLimits.contains_batch`'s).

Serves (the user-felt figure): the motion checks' samples: 0.2 s in Python in the thesis
run.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.helpers import within_limits
from assistant.kernels.lazy import kernel

Array = np.ndarray


@kernel(cache=True)
def motion_marks(groups: Array) -> tuple[Array, Array, Array]:
    """(first, last, motion) of rows labelled by `groups` (rows of a motion consecutive):
    whether a row starts or ends its motion, and the motion's number 0, 1, ..."""
    n = groups.shape[0]
    first = np.zeros(n, dtype=np.bool_)
    last = np.zeros(n, dtype=np.bool_)
    motion = np.zeros(n, dtype=np.int64)
    m = 0
    for k in range(n):
        if k > 0 and groups[k] != groups[k - 1]:
            m += 1
        first[k] = k == 0 or groups[k] != groups[k - 1]
        last[k] = k == n - 1 or groups[k] != groups[k + 1]
        motion[k] = m
    return first, last, motion


@kernel(cache=True)
def rows_inside(Q: Array, lower: Array, upper: Array) -> Array:
    """The joint-limit test of each row of Q (`JointLimits.contains_batch`)."""
    inside = np.empty(Q.shape[0], dtype=np.bool_)
    for k in range(Q.shape[0]):
        inside[k] = within_limits(Q[k], lower, upper)
    return inside


@kernel(cache=True)
def rows_before_first_bad(ask: Array, bad: Array, motion: Array) -> tuple[Array, Array]:
    """Rows flagged `ask` that lie before their motion's first `bad` row, and each
    motion's first bad row (n where none)."""
    n = ask.shape[0]
    n_motions = motion[n - 1] + 1 if n else 0
    first_bad = np.full(n_motions, n, dtype=np.int64)
    for k in range(n):
        if bad[k] and first_bad[motion[k]] == n:
            first_bad[motion[k]] = k
    rows = np.empty(n, dtype=np.int64)
    m = 0
    for k in range(n):
        if ask[k] and not bad[k] and k < first_bad[motion[k]]:
            rows[m] = k
            m += 1
    return rows[:m], first_bad


@kernel(cache=True)
def valid_before_first_bad(ok: Array, rows: Array, hit: Array, motion: Array,
                           first_bad: Array) -> None:
    """Set ok (in place) from FCL's answers `hit` on `rows`: a hit row is invalid and so is
    every row of its motion after its first invalid row."""
    for i in range(rows.shape[0]):
        k = rows[i]
        ok[k] = not hit[i]
        if hit[i] and k < first_bad[motion[k]]:
            first_bad[motion[k]] = k
    for k in range(ok.shape[0]):
        if k > first_bad[motion[k]]:
            ok[k] = False


@kernel(cache=True)
def path_samples(A: Array, counts: Array, trusted: Array) -> tuple[Array, Array, Array]:
    """(segment, fraction, joints) of the samples `CollisionChecker.check_path` asks on
    the path A (M, dof), segment i in counts[i] steps: each segment's samples but its end,
    the last segment's end too, the segments flagged in `trusted` left out (an empty
    `trusted` flags none). The joints A[i] + (k / n) (A[i + 1] - A[i]), the same numbers
    as a numpy form (two numpy passes and a dozen calls, ~15 us a check of a path)."""
    m = counts.shape[0]
    total = 0
    for i in range(m):
        if trusted.shape[0] == 0 or not trusted[i]:
            total += counts[i] + (1 if i == m - 1 else 0)
    dof = A.shape[1]
    S = np.empty(total, dtype=np.int64)
    F = np.empty(total)
    Q = np.empty((total, dof))
    r = 0
    for i in range(m):
        if trusted.shape[0] and trusted[i]:
            continue
        for k in range(counts[i] + (1 if i == m - 1 else 0)):
            f = k / counts[i]
            S[r], F[r] = i, f
            for j in range(dof):
                Q[r, j] = A[i, j] + f * (A[i + 1, j] - A[i, j])
            r += 1
    return S, F, Q
