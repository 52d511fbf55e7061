"""The round-shape pruning of the broad phase as whole-array numpy: the fallback of
`broad_phase.prune_round_pairs` while that kernel is not compiled yet (`kernels.lazy`).

Why: row by row in Python the pruning cost ~5 s of a first run's world build; as arrays
over every candidate at once it costs a few hundredths. The arithmetic is the kernel's:
segment-to-box distance by the convex pieces between face crossings
(`segment_box.segment_box_distance_one`), segment-to-segment by clamped parameters
(`broad_phase._segment_segment_distance`); a pair is cleared when the bound exceeds
`apart`, so a difference in the last bit can only flip a pair lying within rounding of
`apart` - which FCL then decides exactly, as it does for every pair kept.
"""

from __future__ import annotations

import numpy as np

Array = np.ndarray


def segment_box_distances(a: Array, b: Array, half: Array) -> Array:
    """Distances (...) from segments a->b (..., 3) to boxes [-half, half] (..., 3), each in
    its box's frame; 0 where they meet."""
    d = b - a
    with np.errstate(invalid="ignore", divide="ignore"):
        cross = np.concatenate([(half - a) / d, (-half - a) / d], axis=-1)
    cross = np.where(np.isfinite(cross), np.clip(cross, 0.0, 1.0), 0.0)
    zeros = np.zeros(cross.shape[:-1] + (1,))
    t = np.sort(np.concatenate([zeros, cross, zeros + 1.0], axis=-1), axis=-1)
    lo, hi = t[..., :-1], t[..., 1:]
    x = a[..., None, :] + (0.5 * (lo + hi))[..., None] * d[..., None, :]
    h = half[..., None, :]
    face = np.where(x > h, h, np.where(x < -h, -h, np.nan))
    outside = ~np.isnan(face)
    e = np.where(outside, a[..., None, :] - np.nan_to_num(face), 0.0)
    dd = np.where(outside, d[..., None, :], 0.0)
    den = (dd * dd).sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        ts = np.clip(np.where(den > 0.0, -(dd * e).sum(axis=-1) / den, lo), lo, hi)
    r = e + ts[..., None] * dd
    return np.sqrt((r * r).sum(axis=-1).min(axis=-1))


def segment_segment_distances(p1: Array, q1: Array, p2: Array, q2: Array) -> Array:
    """Distances (N,) between segments p1->q1 and p2->q2 (N, 3): closest points by clamped
    parameters, exact for parallel and degenerate segments too."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = (d1 * d1).sum(axis=1)
    e = (d2 * d2).sum(axis=1)
    f = (d2 * r).sum(axis=1)
    c = (d1 * r).sum(axis=1)
    b = (d1 * d2).sum(axis=1)
    tiny_a, tiny_e = a <= 1e-18, e <= 1e-18
    safe_a, safe_e = np.where(tiny_a, 1.0, a), np.where(tiny_e, 1.0, e)
    den = a * e - b * b
    s = np.where(den > 0.0, np.clip((b * f - c * e) / np.where(den > 0.0, den, 1.0), 0, 1), 0.0)
    t = (b * s + f) / safe_e
    low, high = t < 0.0, t > 1.0
    s = np.where(low, np.clip(-c / safe_a, 0, 1),
                 np.where(high, np.clip((b - c) / safe_a, 0, 1), s))
    t = np.clip(t, 0.0, 1.0)
    # the degenerate cases: a point and a segment, or two points
    s = np.where(tiny_e & ~tiny_a, np.clip(-c / safe_a, 0, 1), s)
    t = np.where(tiny_e, 0.0, t)
    t = np.where(tiny_a & ~tiny_e, np.clip(f / safe_e, 0, 1), t)
    s = np.where(tiny_a, 0.0, s)
    g = (p1 + s[:, None] * d1) - (p2 + t[:, None] * d2)
    return np.sqrt((g * g).sum(axis=1))


def prune_round_pairs_numpy(frames: Array, rows: Array, env_c: Array, self_c: Array,
                            shape_link: Array, seg_a: Array, seg_b: Array, seg_r: Array,
                            box_R: Array, box_c: Array, box_h: Array, pair_a: Array,
                            pair_b: Array, apart: float) -> None:
    """`broad_phase.prune_round_pairs` over all rows at once (same arguments, in place)."""
    rows = np.asarray(rows, dtype=np.int64)
    round_ = ~np.isnan(seg_r)
    if len(rows) == 0 or not round_.any():
        return
    F = frames[rows][:, shape_link]  # (R, S, 4, 4)
    A = np.einsum("rsij,sj->rsi", F[:, :, :3, :3], np.nan_to_num(seg_a)) + F[:, :, :3, 3]
    B = np.einsum("rsij,sj->rsi", F[:, :, :3, :3], np.nan_to_num(seg_b)) + F[:, :, :3, 3]
    sub = env_c[rows] & round_[None, :, None]
    r_i, s_i, e_i = np.nonzero(sub)
    if len(r_i):
        # R^T (x - centre): each segment in its box's frame
        la = np.einsum("nji,nj->ni", box_R[e_i], A[r_i, s_i] - box_c[e_i])
        lb = np.einsum("nji,nj->ni", box_R[e_i], B[r_i, s_i] - box_c[e_i])
        gap = segment_box_distances(la, lb, box_h[e_i]) - seg_r[s_i]
        clear = gap > apart
        env_c[rows[r_i[clear]], s_i[clear], e_i[clear]] = False
    if self_c.shape[1] == 0:
        return
    both = round_[pair_a] & round_[pair_b]
    r_j, p_j = np.nonzero(self_c[rows] & both[None, :])
    if len(r_j):
        a, b = pair_a[p_j], pair_b[p_j]
        gap = (segment_segment_distances(A[r_j, a], B[r_j, a], A[r_j, b], B[r_j, b])
               - seg_r[a] - seg_r[b])
        clear = gap > apart
        self_c[rows[r_j[clear]], p_j[clear]] = False
