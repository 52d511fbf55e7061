"""The elastic net's proposed moves for one sweep, compiled (numba).

`elastic_net._Net.iterate` evaluates the forces one colour class at a time on the tentative
positions (Gauss-Seidel) and caps each move at `max_move`. As numpy calls on a few dozen
particles this was ~40 small array operations per colour class, ~0.1 ms per sweep and a
quarter of the net's time; one compiled loop does the same sweep in a few microseconds.
The formulas (equidistance, shrink, rotation, the line/curve switch) are documented in
`elastic_net`; the test compares this kernel with that numpy formulation sweep for sweep.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

Array = np.ndarray

_JIT = {"cache": True, "error_model": "numpy"}


@njit(**_JIT)
def _turn(P: Array, j: int, out: Array) -> float:
    """Turn angle at interior particle j, and its unit curvature direction (the component of
    P[j-1] + P[j+1] - 2 P[j] across the chord, 0 if none) into `out`; 0 at the ends."""
    n = len(P)
    out[:] = 0.0
    if j < 1 or j > n - 2:
        return 0.0
    a = P[j] - P[j - 1]
    b = P[j + 1] - P[j]
    na = max(math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]), 1e-15)
    nb = max(math.sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]), 1e-15)
    a, b = a / na, b / nb
    c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    gam = math.acos(min(max(c, -1.0), 1.0))
    S = P[j - 1] + P[j + 1] - 2.0 * P[j]
    ch = P[j + 1] - P[j - 1]
    nc = max(math.sqrt(ch[0] * ch[0] + ch[1] * ch[1] + ch[2] * ch[2]), 1e-15)
    ch = ch / nc
    S = S - (S[0] * ch[0] + S[1] * ch[1] + S[2] * ch[2]) * ch
    sn = math.sqrt(S[0] * S[0] + S[1] * S[1] + S[2] * S[2])
    if sn > 1e-12:
        out[:] = S / sn
    return gam


@njit(**_JIT)
def _polygon_turn(side: float, radius: float) -> float:
    """Turn angle of a regular polygon with this side inscribed in a circle of this radius."""
    if radius <= 0.0:
        return math.pi
    return 2.0 * math.asin(min(1.0, side / (2.0 * radius)))


@njit(**_JIT)
def propose_moves(P: Array, stage: int, lam: float, c_eq: float, c_rot: float, c_sh: float,
                  c_line: float, stage1_shrink: float, r_max: float, r_min: float,
                  max_move: float) -> tuple[Array, Array, Array]:
    """One Gauss-Seidel sweep of proposals: (particle indices in colour order, their moves
    (k, 3), the tentative positions with every move applied).

    Interior particles are taken by colour class i mod 3 (0, 1, 2); each class reads the
    tentative positions the earlier classes left. A move longer than `max_move` is scaled
    down to it.
    """
    n = len(P)
    trial = P.copy()
    m = max(0, n - 2)
    idx = np.empty(m, dtype=np.int64)
    D = np.empty((m, 3))
    k = 0
    kb, kp, kn = np.empty(3), np.empty(3), np.empty(3)
    for colour in range(3):
        first = k
        for i in range(1, n - 1):
            if i % 3 != colour:
                continue
            A, B, C = trial[i - 1], trial[i], trial[i + 1]
            AB, BC, AC = B - A, C - B, C - A
            lab = math.sqrt(AB[0] * AB[0] + AB[1] * AB[1] + AB[2] * AB[2])
            lbc = math.sqrt(BC[0] * BC[0] + BC[1] * BC[1] + BC[2] * BC[2])
            t = AC / max(math.sqrt(AC[0] * AC[0] + AC[1] * AC[1] + AC[2] * AC[2]), 1e-15)
            F_eq = (lbc - lab) * t
            S = (A - B) + (C - B)
            F_sh = S - (S[0] * t[0] + S[1] * t[1] + S[2] * t[2]) * t
            if stage == 1:
                d = c_eq * F_eq + stage1_shrink * F_sh
            else:
                side = 0.5 * (lab + lbc)
                g_b = _turn(trial, i, kb)
                g_p = _turn(trial, i - 1, kp)
                g_n = _turn(trial, i + 1, kn)
                kb *= g_b
                cnt = (1.0 if i - 1 >= 1 else 0.0) + (1.0 if i + 1 <= n - 2 else 0.0)
                if cnt == 0.0:  # three particles: no interior neighbour to compare with
                    kmean = kb.copy()
                else:
                    kmean = (g_p * kp + g_n * kn) / cnt
                kmean = kmean - (kmean[0] * t[0] + kmean[1] * t[1] + kmean[2] * t[2]) * t
                target = kmean / max(math.cos(g_b), 0.5)
                F_rot = 0.25 * side * (kb - target) / 3.0
                g_min = _polygon_turn(side, r_max)
                g_max = _polygon_turn(side, r_min) if r_min > 0.0 else np.inf
                if (g_p < g_min and g_b < g_min and g_n < g_min) or g_b > g_max:
                    d = c_eq * F_eq + c_line * F_sh
                else:
                    d = c_eq * F_eq + (1.0 - lam) * c_rot * F_rot + lam * c_sh * F_sh
            dn = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
            d = d / max(1.0, dn / max_move)
            idx[k] = i
            D[k] = d
            k += 1
        for j in range(first, k):  # the class moves together, after all of it is evaluated
            trial[idx[j]] += D[j]
    return idx[:k], D[:k], trial
