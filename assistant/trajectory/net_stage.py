"""Runs of elastic-net sweeps in one compiled call (numba), between progress reports.

Why: a query's net makes ~40 sweeps, and run one by one each sweep is five compiled calls
from Python (`net_sweep.sweep_moves`, `net_kernel.check_moves` once or twice,
`halve_retries`, `repin`) plus the stop tests: numba's dispatch of the move test alone (two
dozen arguments, among them tuples of arrays) and the Python in between cost ~0.6 ms a
query. Here the sweeps between two progress reports (`elastic_net.SWEEPS_PER_REPORT`) run
in one call.

The steps are `elastic_net._Net.iterate`'s and `run_stage`'s, in the same order on the same
arrays: the mean movement E and the taut test's lengths are summed as numpy sums them
(`_np_sum`, its pairwise order), so the particles come out the same to the bit (the net
tests compare with the sweep-by-sweep form). The one step that cannot run here is FCL, for
the moves the broad phase cannot clear: a sweep that needs it is rolled back (its state was
copied first) and handed to Python, which runs it sweep by sweep and then calls in again.

Serves (the user-felt figure): the elastic net's sweeps between progress reports: 0.15 s in
Python in the thesis run; a candidate to drop (its compile costs far more than it saves a
first-time user).
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.lazy import kernel
from assistant.trajectory.net_kernel import ACCEPTED, ASK_FCL, check_moves
from assistant.trajectory.net_sweep import halve_retries, repin, sweep_moves

Array = np.ndarray

#: `run_sweeps` outcomes besides the stop reasons (codes 0-4, `STOPS`' order)
RAN, NEEDS_FCL = 5, 6
#: code -> `StopReason` value
STOPS = ("converged", "settled", "taut", "blocked", "iteration_cap")


@kernel(cache=True)
def _block_sum(a: Array, lo: int, n: int) -> float:
    """numpy's sum of up to 128 float64s: eight running sums, then the rest in order."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r = a[lo:lo + 8].copy()
    i = 8
    while i < n - (n % 8):
        for j in range(8):
            r[j] += a[lo + i + j]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@kernel(cache=True)
def _np_sum(a: Array, lo: int, n: int) -> float:
    """a[lo:lo + n].sum() as numpy adds a float64 array: blocks of up to 128 (`_block_sum`),
    longer runs split in two halves (rounded to eights) added left + right. numpy recurses;
    here an explicit stack does (numba cannot load a cached self-recursive function)."""
    lo_s = np.empty(64, dtype=np.int64)
    n_s = np.empty(64, dtype=np.int64)
    phase = np.zeros(64, dtype=np.int64)
    left = np.empty(64)
    top = 0
    lo_s[0], n_s[0] = lo, n
    ret = 0.0
    while True:
        m = n_s[top]
        if m <= 128:
            ret = _block_sum(a, lo_s[top], m)
            top -= 1
        else:
            half = m // 2
            half -= half % 8
            if phase[top] == 0:  # the left half first
                phase[top] = 1
                top += 1
                lo_s[top], n_s[top], phase[top] = lo_s[top - 1], half, 0
                continue
            if phase[top] == 1:  # left done: the right half
                left[top] = ret
                phase[top] = 2
                top += 1
                lo_s[top], n_s[top], phase[top] = lo_s[top - 1] + half, m - half, 0
                continue
            ret = left[top] + ret
            top -= 1
        if top < 0:
            return ret


@kernel(cache=True)
def _norm_sum(X: Array, rows: Array) -> float:
    """`row_norms(X[rows]).sum()` (`particles.row_norms`: squares summed in order)."""
    norms = np.empty(rows.shape[0])
    for r in range(rows.shape[0]):
        i = rows[r]
        norms[r] = np.sqrt(X[i, 0] * X[i, 0] + X[i, 1] * X[i, 1] + X[i, 2] * X[i, 2])
    return _np_sum(norms, 0, norms.shape[0])


@kernel(cache=True)
def polyline_length(P: Array) -> float:
    """`particles.polyline_length`, to the bit."""
    D = P[1:] - P[:-1]
    return _norm_sum(D, np.arange(D.shape[0]))


@kernel(cache=True)
def run_sweeps(P: Array, Q: Array, pinned: Array, ref_Q: Array, ref_margin: Array,
               gap_lb: Array, counts: Array, lengths: Array, n_len: int, E: float,
               first: int, last: int, taut: bool, stage: int, forces: Array, stops: Array,
               taut_window: int, grid_origin: Array, leaf: float, n_grid: int, free: Array,
               use_grid: bool, check_mid: bool, robot: tuple, checker: tuple,
               rec_q: Array, rec_half: Array, ik: Array, need: float,
               ) -> tuple[int, int, int, float]:
    """Sweeps first..last of a stage, in place on the net's arrays.

    forces = (c_error, c_equidistance, c_rotation, c_shrink, c_line_shrink, stage1_shrink,
    r_max, r_min, max_move); stops = (epsilon, settle, taut_length); ik = (nullspace_gain,
    max_joint_jump, 10 x IK tolerance); counts = (accepted, rejected, certified) moves,
    added to. lengths[:n_len] are the taut test's lengths so far.

    Returns (code, sweep, n_len, E): a stop (code < RAN) at that sweep; RAN: all done, the
    next sweep is `sweep`; NEEDS_FCL: sweep `sweep` was rolled back for Python to run.
    """
    n = P.shape[0]
    for it in range(first, last + 1):
        lam = forces[0] * E / (1.0 + forces[0] * E) if np.isfinite(E) else 1.0
        idx, D, trial, pin = sweep_moves(P, pinned, stage, lam, forces[1], forces[2],
                                         forces[3], forces[4], forces[5], forces[6],
                                         forces[7], forces[8])
        accepted = 0
        proposed = idx.shape[0]
        retry = np.zeros(0, dtype=np.int64)
        ok2 = np.zeros(0, dtype=np.bool_)
        if proposed:
            saved = (P.copy(), Q.copy(), pinned.copy(), ref_Q.copy(), ref_margin.copy(),
                     gap_lb.copy())
            status, _, _, _, _, _, _, _, cert = check_moves(
                P, Q, idx, D, trial, grid_origin, leaf, n_grid, free, use_grid, check_mid,
                robot, checker, rec_q, rec_half, ik[0], ik[1], ik[2], ref_Q, ref_margin,
                gap_lb, need)
            asked = (status == ASK_FCL).any()
            ok = status == ACCEPTED
            cert2 = 0
            if not asked:
                retry = halve_retries(ok, pin, idx, D, trial, P)
                if retry.shape[0]:
                    status2, _, _, _, _, _, _, _, cert2 = check_moves(
                        P, Q, idx[retry], D[retry], trial, grid_origin, leaf, n_grid, free,
                        use_grid, check_mid, robot, checker, rec_q, rec_half, ik[0], ik[1],
                        ik[2], ref_Q, ref_margin, gap_lb, need)
                    asked = (status2 == ASK_FCL).any()
                    ok2 = status2 == ACCEPTED
            if asked:  # FCL must decide a move: Python runs this sweep
                P[:], Q[:], pinned[:], ref_Q[:], ref_margin[:], gap_lb[:] = saved
                return NEEDS_FCL, it, n_len, E
            counts[1] += repin(ok, pin, retry, ok2, idx, pinned)
            counts[2] += cert + cert2
            accepted = int(ok.sum())
            counts[0] += accepted
            E = _norm_sum(D, np.flatnonzero(ok)) / max(1, n - 2)
        else:
            E = 0.0
        if proposed and not accepted:
            return 3, it, n_len, 0.0
        if E < stops[0]:
            return 0, it, n_len, E
        if E < stops[1]:
            return 1, it, n_len, E
        if taut:
            lengths[n_len] = polyline_length(P)
            n_len += 1
            w = taut_window
            if n_len > w and lengths[n_len - 1 - w] - lengths[n_len - 1] < stops[2]:
                return 2, it, n_len, E
    return RAN, last + 1, n_len, E
