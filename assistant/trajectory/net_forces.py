"""The elastic net's proposed moves for one sweep, compiled (numba).

`elastic_net._Net.iterate` evaluates the forces one colour class at a time on the tentative
positions (Gauss-Seidel) and caps each move at `max_move`. As numpy calls on a few dozen
particles this is ~40 small array operations per colour class, ~0.1 ms per sweep and a
quarter of the net's time; one compiled loop does the same sweep in a few microseconds.
The formulas (equidistance, shrink, rotation, the line/curve switch) are documented in
`elastic_net`; the test compares this kernel with that numpy formulation sweep for sweep.

Serves (the user-felt figure): the elastic net of every plan and re-plan: 0.6 s in Python in
the thesis run.
"""

from __future__ import annotations

import math

import numpy as np

from assistant.kernels.lazy import kernel

Array = np.ndarray

_JIT = {"cache": True, "error_model": "numpy"}


@kernel(**_JIT)
def _turn(P: Array, j: int) -> tuple[float, float, float, float]:
    """Turn angle at interior particle j and its unit curvature direction (the component of
    P[j-1] + P[j+1] - 2 P[j] across the chord, 0 if none); 0 at the ends."""
    n = len(P)
    if j < 1 or j > n - 2:
        return 0.0, 0.0, 0.0, 0.0
    a0, a1, a2 = P[j, 0] - P[j - 1, 0], P[j, 1] - P[j - 1, 1], P[j, 2] - P[j - 1, 2]
    b0, b1, b2 = P[j + 1, 0] - P[j, 0], P[j + 1, 1] - P[j, 1], P[j + 1, 2] - P[j, 2]
    na = max(math.sqrt(a0 * a0 + a1 * a1 + a2 * a2), 1e-15)
    nb = max(math.sqrt(b0 * b0 + b1 * b1 + b2 * b2), 1e-15)
    a0, a1, a2 = a0 / na, a1 / na, a2 / na
    b0, b1, b2 = b0 / nb, b1 / nb, b2 / nb
    c = a0 * b0 + a1 * b1 + a2 * b2
    x0, x1, x2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
    gam = math.atan2(math.sqrt(x0 * x0 + x1 * x1 + x2 * x2), c)  # well conditioned near 0
    s0 = (P[j - 1, 0] + P[j + 1, 0]) - 2.0 * P[j, 0]
    s1 = (P[j - 1, 1] + P[j + 1, 1]) - 2.0 * P[j, 1]
    s2 = (P[j - 1, 2] + P[j + 1, 2]) - 2.0 * P[j, 2]
    h0, h1, h2 = P[j + 1, 0] - P[j - 1, 0], P[j + 1, 1] - P[j - 1, 1], P[j + 1, 2] - P[j - 1, 2]
    nc = max(math.sqrt(h0 * h0 + h1 * h1 + h2 * h2), 1e-15)
    h0, h1, h2 = h0 / nc, h1 / nc, h2 / nc
    dot = s0 * h0 + s1 * h1 + s2 * h2
    s0, s1, s2 = s0 - dot * h0, s1 - dot * h1, s2 - dot * h2
    sn = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
    if sn > 1e-12:
        return gam, s0 / sn, s1 / sn, s2 / sn
    return gam, 0.0, 0.0, 0.0


@kernel(**_JIT)
def _polygon_turn(side: float, radius: float) -> float:
    """Turn angle of a regular polygon with this side inscribed in a circle of this radius."""
    if radius <= 0.0:
        return math.pi
    return 2.0 * math.asin(min(1.0, side / (2.0 * radius)))


@kernel(**_JIT)
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
    for colour in range(3):
        first = k
        for i in range(1, n - 1):
            if i % 3 != colour:
                continue
            # scalars per particle, each the numpy formulation's operation in its order
            # (3-vector temporaries would be a dozen allocations per particle and sweep)
            ab0, ab1, ab2 = (trial[i, 0] - trial[i - 1, 0], trial[i, 1] - trial[i - 1, 1],
                             trial[i, 2] - trial[i - 1, 2])
            bc0, bc1, bc2 = (trial[i + 1, 0] - trial[i, 0], trial[i + 1, 1] - trial[i, 1],
                             trial[i + 1, 2] - trial[i, 2])
            ac0, ac1, ac2 = (trial[i + 1, 0] - trial[i - 1, 0],
                             trial[i + 1, 1] - trial[i - 1, 1],
                             trial[i + 1, 2] - trial[i - 1, 2])
            lab = math.sqrt(ab0 * ab0 + ab1 * ab1 + ab2 * ab2)
            lbc = math.sqrt(bc0 * bc0 + bc1 * bc1 + bc2 * bc2)
            lac = max(math.sqrt(ac0 * ac0 + ac1 * ac1 + ac2 * ac2), 1e-15)
            t0, t1, t2 = ac0 / lac, ac1 / lac, ac2 / lac
            e0, e1, e2 = (lbc - lab) * t0, (lbc - lab) * t1, (lbc - lab) * t2  # F_eq
            s0 = (trial[i - 1, 0] - trial[i, 0]) + (trial[i + 1, 0] - trial[i, 0])
            s1 = (trial[i - 1, 1] - trial[i, 1]) + (trial[i + 1, 1] - trial[i, 1])
            s2 = (trial[i - 1, 2] - trial[i, 2]) + (trial[i + 1, 2] - trial[i, 2])
            st = s0 * t0 + s1 * t1 + s2 * t2
            f0, f1, f2 = s0 - st * t0, s1 - st * t1, s2 - st * t2  # F_sh
            if stage == 1:
                d0 = c_eq * e0 + stage1_shrink * f0
                d1 = c_eq * e1 + stage1_shrink * f1
                d2 = c_eq * e2 + stage1_shrink * f2
            else:
                side = 0.5 * (lab + lbc)
                g_b, kb0, kb1, kb2 = _turn(trial, i)
                g_p, kp0, kp1, kp2 = _turn(trial, i - 1)
                g_n, kn0, kn1, kn2 = _turn(trial, i + 1)
                kb0, kb1, kb2 = kb0 * g_b, kb1 * g_b, kb2 * g_b
                cnt = (1.0 if i - 1 >= 1 else 0.0) + (1.0 if i + 1 <= n - 2 else 0.0)
                if cnt == 0.0:  # three particles: no interior neighbour to compare with
                    m0, m1, m2 = kb0, kb1, kb2
                else:
                    m0 = (g_p * kp0 + g_n * kn0) / cnt
                    m1 = (g_p * kp1 + g_n * kn1) / cnt
                    m2 = (g_p * kp2 + g_n * kn2) / cnt
                mt = m0 * t0 + m1 * t1 + m2 * t2
                m0, m1, m2 = m0 - mt * t0, m1 - mt * t1, m2 - mt * t2
                cb = max(math.cos(g_b), 0.5)
                q = 0.25 * side
                r0 = q * (kb0 - m0 / cb) / 3.0  # F_rot
                r1 = q * (kb1 - m1 / cb) / 3.0
                r2 = q * (kb2 - m2 / cb) / 3.0
                g_min = _polygon_turn(side, r_max)
                g_max = _polygon_turn(side, r_min) if r_min > 0.0 else np.inf
                if (g_p < g_min and g_b < g_min and g_n < g_min) or g_b > g_max:
                    d0, d1, d2 = c_eq * e0 + c_line * f0, c_eq * e1 + c_line * f1, \
                        c_eq * e2 + c_line * f2
                else:
                    w_rot, w_sh = (1.0 - lam) * c_rot, lam * c_sh
                    d0 = c_eq * e0 + w_rot * r0 + w_sh * f0
                    d1 = c_eq * e1 + w_rot * r1 + w_sh * f1
                    d2 = c_eq * e2 + w_rot * r2 + w_sh * f2
            dn = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            sc = max(1.0, dn / max_move)
            idx[k] = i
            D[k, 0], D[k, 1], D[k, 2] = d0 / sc, d1 / sc, d2 / sc
            k += 1
        for j in range(first, k):  # the class moves together, after all of it is evaluated
            trial[idx[j]] += D[j]
    return idx[:k], D[:k], trial
