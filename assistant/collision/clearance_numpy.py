"""The clearance scan as whole-array numpy: the fallback of `clearance_scan.pruned_clearance`
while that kernel is not compiled yet (`kernels.lazy`).

Why: its own Python, sample by sample, cost ~5 s of a first run's plan and execution; as
arrays over every (sample, shape, obstacle) at once it costs a few hundredths. The kernel
visits samples in the order of a lower bound and stops early; this form bounds every pair
instead (the same sphere-to-box and axis-segment-to-box bounds, `prune_numpy`) and returns
every pair FCL must measure whose bound is below the smallest exact distance. The kernel's
pairs are a subset of these, and the caller measures them in the order of their bounds
only while a bound is below the answer, so both give the same clearance.
"""

from __future__ import annotations

import numpy as np

from assistant.collision.prune_numpy import segment_box_distances
from assistant.robots.dh import chain_frames_numpy

Array = np.ndarray


def pruned_clearance_numpy(Q: Array, frames: Array, ready: Array, F: Array, travel: Array,
                           stride: int, movable: Array, n_shapes: int, sph_link: Array,
                           sph_local: Array, sph_r: Array, sph_shape: Array, env_lo: Array,
                           env_hi: Array, shape_link: Array, seg_a: Array, seg_b: Array,
                           seg_r: Array, seg_exact: Array, box_R: Array, box_c: Array,
                           box_h: Array, box_exact: Array) -> tuple[float, Array, Array]:
    """`clearance_scan.pruned_clearance` (same arguments and results, see its docstring);
    `travel` and `stride` only steer the kernel's visiting order and are not needed here."""
    n, n_mov, n_env = Q.shape[0], movable.shape[0], env_lo.shape[0]
    none = np.zeros(0, dtype=np.int64)
    if n == 0 or n_mov == 0 or n_env == 0:
        return np.inf, none, np.zeros(0)
    todo = np.flatnonzero(~ready)
    if todo.size:
        frames[todo] = chain_frames_numpy(Q[todo], F)
        ready[todo] = True
    mov_of = np.full(n_shapes, -1, dtype=np.int64)
    mov_of[movable] = np.arange(n_mov)
    # sphere-to-box bounds per (sample, movable shape, obstacle): -inf without spheres or
    # where a sphere reaches the box
    lbs = np.full((n, n_mov, n_env), np.inf)
    use = np.flatnonzero(mov_of[sph_shape] >= 0)
    if use.size:
        Fs = frames[:, sph_link[use]]  # (n, S, 4, 4)
        c = np.einsum("nsij,sj->nsi", Fs[..., :3, :3], sph_local[use]) + Fs[..., :3, 3]
        near = np.clip(c[:, :, None, :], env_lo[None, None], env_hi[None, None])
        g = np.sqrt(((c[:, :, None, :] - near) ** 2).sum(axis=-1)) - sph_r[use][None, :, None]
        np.minimum.at(lbs, (slice(None), mov_of[sph_shape[use]]), g)
    has = np.zeros(n_mov, dtype=bool)
    has[mov_of[sph_shape[use]]] = True
    lbs[:, ~has] = -np.inf
    lbs[lbs <= 0.0] = -np.inf
    # axis segment to oriented box, less the radius (NaN radius: no segment, -inf)
    link = shape_link[movable]
    Fm = frames[:, link]  # (n, M, 4, 4)
    A = np.einsum("nmij,mj->nmi", Fm[..., :3, :3], np.nan_to_num(seg_a[movable])) \
        + Fm[..., :3, 3]
    B = np.einsum("nmij,mj->nmi", Fm[..., :3, :3], np.nan_to_num(seg_b[movable])) \
        + Fm[..., :3, 3]
    la = np.einsum("eji,nmej->nmei", box_R, A[:, :, None, :] - box_c[None, None])
    lb = np.einsum("eji,nmej->nmei", box_R, B[:, :, None, :] - box_c[None, None])
    half = np.broadcast_to(box_h[None, None], la.shape)
    with np.errstate(invalid="ignore"):
        gap = segment_box_distances(la, lb, half) - seg_r[movable][None, :, None]
        tight = np.where(gap > 0.0, gap, -np.inf)
    exact = (seg_exact[movable][None, :, None] & box_exact[None, None, :]
             & np.isfinite(tight))
    best = float(tight[exact].min()) if exact.any() else np.inf
    bound = np.maximum(lbs, tight)
    measure = ~exact & (lbs < best) & (bound < best)
    rows = np.flatnonzero(measure.reshape(-1)).astype(np.int64)
    return best, rows, bound.reshape(-1)[rows].copy()
