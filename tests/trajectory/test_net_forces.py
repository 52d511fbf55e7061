"""The compiled sweep of the elastic net against the numpy formulation it replaced.

The reference below is the net's former numpy code (kept here only as the reference): forces
per colour class on the tentative positions, the line/curve switch of rule (65), the cap at
`max_move`. On noisy lines, circles and random nets, both must propose the same moves.
"""

from __future__ import annotations

import numpy as np
import pytest

from assistant.trajectory.elastic_net import ElasticNetParams, turn_angles
from assistant.trajectory.net_forces import propose_moves
from assistant.trajectory.particles import row_norms


def _polygon_turn(side, radius):
    if radius <= 0.0:
        return np.pi
    return 2.0 * np.arcsin(np.minimum(1.0, np.asarray(side) / (2.0 * radius)))


def _rotation(P, idx, t, side):
    n = len(P)
    gam = turn_angles(P)
    S = P[:-2] + P[2:] - 2.0 * P[1:-1]
    a = P[2:] - P[:-2]
    a /= np.maximum(row_norms(a), 1e-15)[:, None]
    S -= np.einsum("ij,ij->i", S, a)[:, None] * a
    sn = row_norms(S)
    normal = np.where(sn[:, None] > 1e-12, S / np.maximum(sn, 1e-300)[:, None], 0.0)
    K, G = np.zeros((n, 3)), np.zeros(n)
    K[1:-1], G[1:-1] = gam[:, None] * normal, gam
    kb = K[idx]
    cnt = ((idx - 1) >= 1).astype(float) + ((idx + 1) <= n - 2)
    kmean = (K[idx - 1] + K[idx + 1]) / np.maximum(cnt, 1.0)[:, None]
    kmean[cnt == 0.0] = kb[cnt == 0.0]
    kmean -= np.einsum("ij,ij->i", kmean, t)[:, None] * t
    target = kmean / np.maximum(np.cos(G[idx]), 0.5)[:, None]
    return 0.25 * side[:, None] * (kb - target) / 3.0, np.stack(
        [G[idx - 1], G[idx], G[idx + 1]], axis=1)


def _displacements(P, idx, stage, lam, p: ElasticNetParams):
    A, B, C = P[idx - 1], P[idx], P[idx + 1]
    lab, lbc = row_norms(B - A), row_norms(C - B)
    t = (C - A) / np.maximum(row_norms(C - A), 1e-15)[:, None]
    F_eq = (lbc - lab)[:, None] * t
    S = (A - B) + (C - B)
    F_sh = S - np.einsum("ij,ij->i", S, t)[:, None] * t
    if stage == 1:
        return p.c_equidistance * F_eq + p.stage1_shrink * F_sh
    side = 0.5 * (lab + lbc)
    F_rot, g3 = _rotation(P, idx, t, side)
    g_min = _polygon_turn(side, p.r_max)
    g_max = _polygon_turn(side, p.r_min) if p.r_min > 0.0 else np.full(len(idx), np.inf)
    line = np.all(g3 < g_min[:, None], axis=1) | (g3[:, 1] > g_max)
    curve = (p.c_equidistance * F_eq + (1.0 - lam) * p.c_rotation * F_rot
             + lam * p.c_shrink * F_sh)
    return np.where(line[:, None], p.c_equidistance * F_eq + p.c_line_shrink * F_sh, curve)


def _reference(P0, stage, lam, p):
    interior = np.arange(1, len(P0) - 1)
    trial = P0.copy()
    out_i, out_d = [], []
    for c in range(3):
        idx = interior[interior % 3 == c]
        if not len(idx):
            continue
        D = _displacements(trial, idx, stage, lam, p)
        D /= np.maximum(1.0, row_norms(D) / p.max_move)[:, None]
        trial[idx] += D
        out_i.append(idx)
        out_d.append(D)
    return np.concatenate(out_i), np.concatenate(out_d), trial


def _nets(seed: int):
    rng = np.random.default_rng(seed)
    for k in range(120):
        n = int(rng.integers(3, 40))
        s = np.linspace(0.0, 1.0, n)
        shape = k % 3
        if shape == 0:  # noisy line
            P = np.outer(s, rng.normal(size=3) * 0.3)
        elif shape == 1:  # circle arc of random radius
            r = rng.uniform(0.02, 0.8)
            a = s * rng.uniform(0.2, 3.0)
            P = np.stack([r * np.cos(a), r * np.sin(a), np.zeros(n)], axis=1)
        else:  # random walk
            P = np.cumsum(rng.normal(scale=0.02, size=(n, 3)), axis=0)
        yield P + rng.normal(scale=rng.choice([0.0, 1e-4, 3e-3]), size=P.shape), rng


@pytest.mark.parametrize("stage", [1, 2])
@pytest.mark.parametrize("seed", [1, 2])
def test_sweep_equals_numpy_reference(seed: int, stage: int) -> None:
    lines = curves = 0
    for P, rng in _nets(seed):
        p = ElasticNetParams(r_max=float(rng.choice([0.1, 0.4])),
                             r_min=float(rng.choice([0.0, 0.02])),
                             max_move=float(rng.choice([0.005, 1.0])),
                             stage1_shrink=float(rng.choice([0.05, 0.7])))
        lam = float(rng.uniform(0.0, 1.0))
        idx, D, trial = propose_moves(P, stage, lam, p.c_equidistance, p.c_rotation,
                                      p.c_shrink, p.c_line_shrink, p.stage1_shrink, p.r_max,
                                      p.r_min, p.max_move)
        ri, rD, rtrial = _reference(P.copy(), stage, lam, p)
        assert np.array_equal(idx, ri)
        assert np.allclose(D, rD, atol=1e-13, rtol=0.0)
        assert np.allclose(trial, rtrial, atol=1e-13, rtol=0.0)
        if stage == 2:  # both branches of the line/curve switch are exercised
            straight = np.allclose(D, _reference_line_only(P, lam, p), atol=1e-13)
            lines += straight
            curves += not straight
    if stage == 2:
        assert lines > 10 and curves > 10


def _reference_line_only(P, lam, p):
    """What the sweep would propose if every particle counted as on a line."""
    return _reference(P.copy(), 2, lam, ElasticNetParams(
        r_max=1e-9, r_min=0.0, max_move=p.max_move, stage1_shrink=p.stage1_shrink))[1]
