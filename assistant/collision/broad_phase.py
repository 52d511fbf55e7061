"""The collision broad phase as one compiled loop (numba): covering spheres vs boxes and pairs.

`CollisionChecker` runs this on every batch of configurations before FCL sees anything, and
the planners call it with small batches (an elastic-net sweep checks ~10 postures, an edge of
the roadmap ~20): a batch of 10 postures costs ~8 us as one compiled loop, where numpy
array expressions spend their time in the per-call overhead of a dozen temporaries; the loop
gives the same numbers.
Compiled on first use and cached on disk (`cache=True`), so only the first run after an
install pays the compile (`jit_warmup`); `NUMBA_DISABLE_JIT=1` runs the same code as plain
Python.

Serves (the user-felt figure): every collision check of the world build, plan and execution:
in the thesis run its numpy fallback costs 5.5 s, compiled well under 0.1 s.
"""

from __future__ import annotations

import numpy as np

from assistant.collision.prune_numpy import prune_round_pairs_numpy
from assistant.collision.segment_box import segment_box_distance_one
from assistant.kernels.lazy import kernel
from assistant.robots.dh import chain_frames_numpy, chain_row

Array = np.ndarray


def _centres_numpy(frames: Array, sph_link: Array, sph_local: Array) -> Array:
    """Sphere centres (N, S, 3) of every configuration, base frame."""
    F = frames[:, sph_link, :3]  # (N, S, 3, 4)
    # column by column, as `_sphere_centre` sums them (2-3x faster than an einsum)
    return (F[..., 0] * sph_local[:, 0, None] + F[..., 1] * sph_local[:, 1, None]
            + F[..., 2] * sph_local[:, 2, None] + F[..., 3])


def _broad_rows_numpy(frames: Array, sph_link: Array, sph_local: Array, sph_r: Array,
                      sph_shape: Array, env_lo: Array, env_hi: Array, sp_a: Array,
                      sp_b: Array, sp_pair: Array, env_c: Array, self_c: Array,
                      env_from: int = 1) -> tuple[Array, Array]:
    """The broad phase of every row of frames as array expressions: flags into env_c and
    self_c (rows aligned with frames), returns the gaps and the centres."""
    n = frames.shape[0]
    centre = _centres_numpy(frames, sph_link, sph_local)
    gap = np.full(n, np.inf)
    moving = np.flatnonzero(sph_link >= env_from)
    if moving.size and env_lo.shape[0]:
        c = centre[:, moving, None, :]  # (N, M, 1, 3)
        d = c - np.minimum(np.maximum(c, env_lo), env_hi)
        d2 = np.einsum("nmei,nmei->nme", d, d)
        r = sph_r[moving][None, :, None]
        k, m, e = np.nonzero(d2 <= r * r)
        env_c[k, sph_shape[moving][m], e] = True
        gap = np.minimum(gap, (np.sqrt(d2) - r).min(axis=(1, 2)))
    if sp_a.shape[0]:
        d = centre[:, sp_a] - centre[:, sp_b]
        d2 = np.einsum("npi,npi->np", d, d)
        rr = (sph_r[sp_a] + sph_r[sp_b])[None, :]
        k, j = np.nonzero(d2 <= rr * rr)
        self_c[k, sp_pair[j]] = True
        gap = np.minimum(gap, (np.sqrt(d2) - rr).min(axis=1))
    return gap, centre


def _sphere_broad_phase_numpy(frames: Array, sph_link: Array, sph_local: Array, sph_r: Array,
                              sph_shape: Array, env_lo: Array, env_hi: Array, sp_a: Array,
                              sp_b: Array, sp_pair: Array, n_shapes: int, n_pairs: int,
                              env_from: int = 1) -> tuple[Array, Array, Array]:
    """`sphere_broad_phase` as array expressions over all configurations (its fallback until
    compiled), in chunks that keep the (rows, spheres, boxes) temporaries small."""
    n = frames.shape[0]
    env_c = np.zeros((n, n_shapes, env_lo.shape[0]), dtype=np.bool_)
    self_c = np.zeros((n, n_pairs), dtype=np.bool_)
    gap = np.full(n, np.inf)
    chunk = max(1, 2_000_000 // max(1, sph_r.shape[0] * max(1, env_lo.shape[0])))
    for a in range(0, n, chunk):
        b = min(n, a + chunk)
        gap[a:b] = _broad_rows_numpy(frames[a:b], sph_link, sph_local, sph_r, sph_shape,
                                     env_lo, env_hi, sp_a, sp_b, sp_pair, env_c[a:b],
                                     self_c[a:b], env_from)[0]
    return env_c, self_c, gap


def _broad_row_numpy(frames: Array, k: int, sph_link: Array, sph_local: Array, sph_r: Array,
                     sph_shape: Array, env_lo: Array, env_hi: Array, sp_a: Array, sp_b: Array,
                     sp_pair: Array, centre: Array, env_c: Array, self_c: Array,
                     env_from: int = 1) -> float:
    """`_broad_row` as array expressions (its fallback until compiled)."""
    gap, c = _broad_rows_numpy(frames[k:k + 1], sph_link, sph_local, sph_r, sph_shape, env_lo,
                               env_hi, sp_a, sp_b, sp_pair, env_c[k:k + 1], self_c[k:k + 1],
                               env_from)
    centre[:] = c[0]
    return float(gap[0])


@kernel(cache=True, fallback=_sphere_broad_phase_numpy)
def sphere_broad_phase(frames: Array, sph_link: Array, sph_local: Array, sph_r: Array,
                       sph_shape: Array, env_lo: Array, env_hi: Array, sp_a: Array,
                       sp_b: Array, sp_pair: Array, n_shapes: int, n_pairs: int,
                       env_from: int = 1) -> tuple[Array, Array, Array]:
    """Which (robot shape, obstacle) and self pairs may touch, per configuration.

    frames (N, L, 4, 4) link frames; spheres s (centre `sph_local[s]` in link `sph_link[s]`,
    radius `sph_r[s]`, covering robot shape `sph_shape[s]`); obstacle boxes `env_lo`/`env_hi`
    (E, 3); self sphere pairs (`sp_a`, `sp_b`) of self pair `sp_pair`.
    Returns env_c (N, n_shapes, E) and self_c (N, n_pairs) bool: a sphere reaches the box or
    the other sphere; and gap (N,): how far every moving sphere stays outside every box and
    every self sphere pair apart (m, inf if there is nothing to measure). Spheres of the
    fixed base (link 0) never meet obstacles (the cell reports that overlap), only self pairs;
    nor do those of links below `env_from` (the fast model's, when it has proved that link
    clear of every obstacle in every posture: `fast_model`).
    """
    n = frames.shape[0]
    env_c = np.zeros((n, n_shapes, env_lo.shape[0]), dtype=np.bool_)
    self_c = np.zeros((n, n_pairs), dtype=np.bool_)
    gap = np.full(n, np.inf)
    centre = np.empty((sph_r.shape[0], 3))
    for k in range(n):
        gap[k] = _broad_row(frames, k, sph_link, sph_local, sph_r, sph_shape, env_lo, env_hi,
                            sp_a, sp_b, sp_pair, centre, env_c, self_c, env_from)
    return env_c, self_c, gap


@kernel(cache=True, inline="always", fallback=_broad_row_numpy)
def _broad_row(frames: Array, k: int, sph_link: Array, sph_local: Array, sph_r: Array,
               sph_shape: Array, env_lo: Array, env_hi: Array, sp_a: Array, sp_b: Array,
               sp_pair: Array, centre: Array, env_c: Array, self_c: Array,
               env_from: int = 1) -> float:
    """`sphere_broad_phase` of row k: flags into env_c[k] and self_c[k], returns its gap
    (`centre` is scratch space, (S, 3))."""
    n_sph = sph_r.shape[0]
    for s in range(n_sph):
        _sphere_centre(frames, k, sph_link[s], sph_local[s], centre[s])
    g = np.inf
    for s in range(n_sph):
        if sph_link[s] < env_from:
            continue
        r = sph_r[s]
        for e in range(env_lo.shape[0]):
            d2 = _box_dist2(centre[s], env_lo[e], env_hi[e])
            if d2 <= r * r:
                env_c[k, sph_shape[s], e] = True
            g = min(g, np.sqrt(d2) - r)
    for j in range(sp_a.shape[0]):
        sa, sb = sp_a[j], sp_b[j]
        d2 = 0.0
        for a in range(3):
            d = centre[sa, a] - centre[sb, a]
            d2 += d * d
        rr = sph_r[sa] + sph_r[sb]
        if d2 <= rr * rr:
            self_c[k, sp_pair[j]] = True
        g = min(g, np.sqrt(d2) - rr)
    return g


@kernel(cache=True, inline="always")
def _sphere_centre(frames: Array, k: int, link: int, local: Array, out: Array) -> None:
    """Centre (base frame) of a sphere at `local` in link `link`, configuration k."""
    for a in range(3):
        out[a] = (frames[k, link, a, 0] * local[0] + frames[k, link, a, 1] * local[1]
                  + frames[k, link, a, 2] * local[2] + frames[k, link, a, 3])


@kernel(cache=True, inline="always")
def _box_dist2(c: Array, lo: Array, hi: Array) -> float:
    """Squared distance of point c to the axis-aligned box lo..hi (0 inside)."""
    d2 = 0.0
    for a in range(3):
        d = c[a] - min(max(c[a], lo[a]), hi[a])
        d2 += d * d
    return d2


@kernel(cache=True)
def _segment_segment_distance(p1: Array, q1: Array, p2: Array, q2: Array) -> float:
    """Distance between the segments p1->q1 and p2->q2 (closest points by clamped
    parameters; exact for parallel and degenerate segments too)."""
    # scalars, not 3-vector temporaries: the pruning asks this for most self pairs
    d10, d11, d12 = q1[0] - p1[0], q1[1] - p1[1], q1[2] - p1[2]
    d20, d21, d22 = q2[0] - p2[0], q2[1] - p2[1], q2[2] - p2[2]
    r0, r1, r2 = p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]
    a = d10 * d10 + d11 * d11 + d12 * d12
    e = d20 * d20 + d21 * d21 + d22 * d22
    f = d20 * r0 + d21 * r1 + d22 * r2
    s = t = 0.0
    if a <= 1e-18 and e <= 1e-18:
        pass
    elif a <= 1e-18:
        t = min(max(f / e, 0.0), 1.0)
    else:
        c = d10 * r0 + d11 * r1 + d12 * r2
        if e <= 1e-18:
            s = min(max(-c / a, 0.0), 1.0)
        else:
            b = d10 * d20 + d11 * d21 + d12 * d22
            den = a * e - b * b
            s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 0.0 else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = min(max(-c / a, 0.0), 1.0)
            elif t > 1.0:
                t = 1.0
                s = min(max((b - c) / a, 0.0), 1.0)
    g0 = (p1[0] + s * d10) - (p2[0] + t * d20)
    g1 = (p1[1] + s * d11) - (p2[1] + t * d21)
    g2 = (p1[2] + s * d12) - (p2[2] + t * d22)
    return np.sqrt(g0 * g0 + g1 * g1 + g2 * g2)


@kernel(cache=True, fallback=prune_round_pairs_numpy)
def prune_round_pairs(frames: Array, rows: Array, env_c: Array, self_c: Array,
                      shape_link: Array, seg_a: Array, seg_b: Array, seg_r: Array,
                      box_R: Array, box_c: Array, box_h: Array, pair_a: Array, pair_b: Array,
                      apart: float) -> None:
    """Clear the broad phase's candidates (in place) that are certainly apart.

    A capsule, cylinder or sphere lies within `seg_r` of its axis segment (NaN for other
    shapes: never pruned), and an obstacle inside its oriented box, so segment-to-box (and
    segment-to-segment for self pairs) distance minus the radii bounds the shapes' distance
    from below. The covering spheres are looser (25 mm on the RV-2AJ's upper arm), and most
    pairs they pass are more than `apart` away by this bound: FCL is asked only for the rest.
    """
    n_shapes = seg_r.shape[0]
    A = np.empty((n_shapes, 3))
    B = np.empty((n_shapes, 3))
    la = np.empty(3)
    lb = np.empty(3)
    for k in rows:
        _prune_row(frames, k, env_c, self_c, shape_link, seg_a, seg_b, seg_r, box_R, box_c,
                   box_h, pair_a, pair_b, apart, A, B, la, lb)


@kernel(cache=True, inline="always")
def _prune_row(frames: Array, k: int, env_c: Array, self_c: Array, shape_link: Array,
               seg_a: Array, seg_b: Array, seg_r: Array, box_R: Array, box_c: Array,
               box_h: Array, pair_a: Array, pair_b: Array, apart: float, A: Array, B: Array,
               la: Array, lb: Array) -> None:
    """`prune_round_pairs` of row k (A, B, la, lb are scratch space)."""
    n_shapes = seg_r.shape[0]
    for s in range(n_shapes):
        if np.isnan(seg_r[s]):
            continue
        F = frames[k, shape_link[s]]
        for i in range(3):
            A[s, i] = (F[i, 0] * seg_a[s, 0] + F[i, 1] * seg_a[s, 1]
                       + F[i, 2] * seg_a[s, 2] + F[i, 3])
            B[s, i] = (F[i, 0] * seg_b[s, 0] + F[i, 1] * seg_b[s, 1]
                       + F[i, 2] * seg_b[s, 2] + F[i, 3])
    for s in range(n_shapes):
        if np.isnan(seg_r[s]):
            continue
        for e in range(env_c.shape[2]):
            if not env_c[k, s, e]:
                continue
            for i in range(3):  # R^T (x - centre): the box's frame
                la[i] = (box_R[e, 0, i] * (A[s, 0] - box_c[e, 0])
                         + box_R[e, 1, i] * (A[s, 1] - box_c[e, 1])
                         + box_R[e, 2, i] * (A[s, 2] - box_c[e, 2]))
                lb[i] = (box_R[e, 0, i] * (B[s, 0] - box_c[e, 0])
                         + box_R[e, 1, i] * (B[s, 1] - box_c[e, 1])
                         + box_R[e, 2, i] * (B[s, 2] - box_c[e, 2]))
            if segment_box_distance_one(la, lb, box_h[e]) - seg_r[s] > apart:
                env_c[k, s, e] = False
    for p in range(self_c.shape[1]):
        a, b = pair_a[p], pair_b[p]
        if not self_c[k, p] or np.isnan(seg_r[a]) or np.isnan(seg_r[b]):
            continue
        if _segment_segment_distance(A[a], B[a], A[b], B[b]) - seg_r[a] - seg_r[b] > apart:
            self_c[k, p] = False


#: `certify_samples` status per row: free by the broad phase, outside the joint limits, for
#: FCL to decide, free by a checked neighbour's margin
FREE, OUTSIDE_LIMITS, ASK_FCL, CERTIFIED = 0, 1, 2, 3


@kernel(cache=True, inline="always")
def _pose(frames: Array, ready: Array, Q: Array, F: Array, k: int, T: Array) -> None:
    """Row k's link frames from the DH chain's fixed parts F (`dh.chain_row`), unless
    they are there already."""
    if not ready[k]:
        chain_row(Q[k], F, frames[k], T)
        ready[k] = True


def _pose_and_broad_numpy(frames: Array, ready: Array, F: Array, Q: Array, rows: Array,
                         sph_link: Array, sph_local: Array, sph_r: Array, sph_shape: Array,
                         env_lo: Array, env_hi: Array, sp_a: Array, sp_b: Array,
                         sp_pair: Array, env_c: Array, self_c: Array, shape_link: Array,
                         seg_a: Array, seg_b: Array, seg_r: Array, box_R: Array, box_c: Array,
                         box_h: Array, pair_a: Array, pair_b: Array, apart: float,
                         status: Array, env_from: int = 1) -> Array:
    """Pose `rows` (unless ready), give them the broad phase as array expressions and prune
    the rows it flags; status FREE or ASK_FCL per row into `status`; returns their gaps."""
    todo = rows[~ready[rows]]
    if todo.size:
        frames[todo] = chain_frames_numpy(Q[todo], F)
        ready[todo] = True
    env_r = np.zeros((rows.size,) + env_c.shape[1:], dtype=np.bool_)
    self_r = np.zeros((rows.size,) + self_c.shape[1:], dtype=np.bool_)
    gap = _broad_rows_numpy(frames[rows], sph_link, sph_local, sph_r, sph_shape, env_lo,
                            env_hi, sp_a, sp_b, sp_pair, env_r, self_r, env_from)[0]
    env_c[rows], self_c[rows] = env_r, self_r
    flagged = rows[env_r.reshape(rows.size, -1).any(axis=1) | self_r.any(axis=1)]
    status[rows] = FREE
    if flagged.size:  # the flagged rows pruned in one pass (`_prune_and_flag` per row)
        prune_round_pairs_numpy(frames, flagged, env_c, self_c, shape_link, seg_a, seg_b,
                                seg_r, box_R, box_c, box_h, pair_a, pair_b, apart)
        left = (env_c[flagged].reshape(flagged.size, -1).any(axis=1)
                | self_c[flagged].any(axis=1))
        status[flagged[left]] = ASK_FCL
    return gap


def _certify_samples_numpy(frames: Array, ready: Array, F: Array, Q: Array, inside: Array,
                           first: Array, last: Array, stride: int, radii: Array,
                           sph_link: Array, sph_local: Array, sph_r: Array, sph_shape: Array,
                           env_lo: Array, env_hi: Array, sp_a: Array, sp_b: Array,
                           sp_pair: Array, n_shapes: int, n_pairs: int, shape_link: Array,
                           seg_a: Array, seg_b: Array, seg_r: Array, box_R: Array,
                           box_c: Array, box_h: Array, pair_a: Array, pair_b: Array,
                           apart: float, env_from: int = 1) -> tuple[Array, Array, Array]:
    """`certify_samples` as array expressions (its fallback until compiled): every row within
    the limits gets the broad phase itself - none is certified by a neighbour's margin, so
    the answers are the same (FREE where the kernel says CERTIFIED) for more arithmetic."""
    n = Q.shape[0]
    env_c = np.zeros((n, n_shapes, env_lo.shape[0]), dtype=np.bool_)
    self_c = np.zeros((n, n_pairs), dtype=np.bool_)
    status = np.full(n, OUTSIDE_LIMITS, dtype=np.int8)
    rows = np.flatnonzero(inside)
    if rows.size:
        _pose_and_broad_numpy(frames, ready, F, Q, rows, sph_link, sph_local, sph_r, sph_shape,
                              env_lo, env_hi, sp_a, sp_b, sp_pair, env_c, self_c, shape_link,
                              seg_a, seg_b, seg_r, box_R, box_c, box_h, pair_a, pair_b, apart,
                              status, env_from)
    return status, env_c, self_c


def _margin_rows_numpy(frames: Array, ready: Array, F: Array, Q: Array, sph_link: Array,
                       sph_local: Array, sph_r: Array, sph_shape: Array, env_lo: Array,
                       env_hi: Array, sp_a: Array, sp_b: Array, sp_pair: Array, n_shapes: int,
                       n_pairs: int, shape_link: Array, seg_a: Array, seg_b: Array,
                       seg_r: Array, box_R: Array, box_c: Array, box_h: Array, pair_a: Array,
                       pair_b: Array, apart: float, env_from: int = 1,
                       ) -> tuple[Array, Array, Array, Array]:
    """`margin_rows` as array expressions (its fallback until compiled)."""
    n = Q.shape[0]
    env_c = np.zeros((n, n_shapes, env_lo.shape[0]), dtype=np.bool_)
    self_c = np.zeros((n, n_pairs), dtype=np.bool_)
    status = np.zeros(n, dtype=np.int8)
    gap = np.full(n, np.inf)
    if n:
        gap = _pose_and_broad_numpy(frames, ready, F, Q, np.arange(n), sph_link, sph_local,
                                    sph_r, sph_shape, env_lo, env_hi, sp_a, sp_b, sp_pair,
                                    env_c, self_c, shape_link, seg_a, seg_b, seg_r, box_R,
                                    box_c, box_h, pair_a, pair_b, apart, status, env_from)
    return status, gap, env_c, self_c


@kernel(cache=True, fallback=_certify_samples_numpy)
def certify_samples(frames: Array, ready: Array, F: Array, Q: Array, inside: Array,
                    first: Array, last: Array,
                    stride: int, radii: Array, sph_link: Array, sph_local: Array,
                    sph_r: Array, sph_shape: Array, env_lo: Array, env_hi: Array, sp_a: Array,
                    sp_b: Array, sp_pair: Array, n_shapes: int, n_pairs: int,
                    shape_link: Array, seg_a: Array, seg_b: Array, seg_r: Array,
                    box_R: Array, box_c: Array, box_h: Array, pair_a: Array, pair_b: Array,
                    apart: float, env_from: int = 1) -> tuple[Array, Array, Array]:
    """Everything of `CollisionChecker.is_valid_samples` but FCL, for motions' samples.

    Rows of one motion are consecutive (`first`/`last` mark its ends); `inside` says which
    rows are within the joint limits. frames holds a row's link frames where `ready`; the
    others are computed here from the DH chain's fixed parts F when the row is checked (a
    row its neighbour's margin certifies is never posed: most rows of a motion in the
    open). Every `stride`-th row of a motion and its last get the broad phase and its gap;
    a row whose arm travel (sum of radii x |joint change|) from the checked row before or
    after it in its motion stays below that row's gap is free
    (no sphere can have come near anything); the others get the broad phase themselves.
    Pairs the broad phase passes are pruned (`prune_round_pairs`). Returns status (N,)
    (FREE, OUTSIDE_LIMITS, ASK_FCL or CERTIFIED) and for ASK_FCL rows the candidate pairs, env_c
    (N, n_shapes, E) and self_c (N, n_pairs), for FCL to decide.
    """
    n, dof = Q.shape
    env_c = np.zeros((n, n_shapes, env_lo.shape[0]), dtype=np.bool_)
    self_c = np.zeros((n, n_pairs), dtype=np.bool_)
    status = np.zeros(n, dtype=np.int8)
    centre = np.empty((sph_r.shape[0], 3))
    A = np.empty((n_shapes, 3))
    B = np.empty((n_shapes, 3))
    la = np.empty(3)
    lb = np.empty(3)
    coarse = np.zeros(n, dtype=np.bool_)
    # Of the coarse rows: what their gap certifies. A row the broad phase passes to FCL has
    # a gap <= 0 (a sphere reaches something): it certifies nothing, whatever FCL says.
    margin = np.full(n, -np.inf)
    T = np.empty((4, 4))
    start = 0
    for k in range(n):
        if first[k]:
            start = k
        coarse[k] = (k - start) % stride == 0 or last[k]
    # Rows are posed in passes of their own, before their broad phase: with the DH chain's
    # arithmetic in the same loop, numba's reference-count pruning leaves the 13 array
    # arguments of the inlined broad phase counted in and out per row, and those atomic
    # counts cost a large share of the pass.
    for k in range(n):
        if inside[k] and coarse[k]:
            _pose(frames, ready, Q, F, k, T)
    for k in range(n):
        if not inside[k]:
            status[k] = OUTSIDE_LIMITS
        elif coarse[k]:
            margin[k] = _broad_row(frames, k, sph_link, sph_local, sph_r, sph_shape, env_lo,
                                   env_hi, sp_a, sp_b, sp_pair, centre, env_c, self_c,
                                   env_from)
            status[k] = _prune_and_flag(frames, k, env_c, self_c, shape_link, seg_a, seg_b,
                                        seg_r, box_R, box_c, box_h, pair_a, pair_b, apart,
                                        A, B, la, lb)
    prev = -1
    nxt = np.empty(n, dtype=np.int64)  # the next coarse row at or after each row
    for k in range(n - 1, -1, -1):
        nxt[k] = k if coarse[k] else prev
        if coarse[k]:
            prev = k
    prev = -1
    todo = np.zeros(n, dtype=np.bool_)  # rows no checked neighbour's margin certifies
    for k in range(n):
        if coarse[k]:
            prev = k
            continue
        if not inside[k]:
            continue
        free = False
        for c in (prev, nxt[k]):
            travel = 0.0
            for j in range(dof):
                travel += abs(Q[k, j] - Q[c, j]) * radii[j]
            if margin[c] > travel + 1e-9:
                free = True
                break
        if free:
            status[k] = CERTIFIED
        else:
            todo[k] = True
    for k in range(n):
        if todo[k]:
            _pose(frames, ready, Q, F, k, T)
    for k in range(n):
        if not todo[k]:
            continue
        _broad_row(frames, k, sph_link, sph_local, sph_r, sph_shape, env_lo, env_hi, sp_a,
                   sp_b, sp_pair, centre, env_c, self_c, env_from)
        status[k] = _prune_and_flag(frames, k, env_c, self_c, shape_link, seg_a, seg_b, seg_r,
                                    box_R, box_c, box_h, pair_a, pair_b, apart, A, B, la, lb)
    return status, env_c, self_c


@kernel(cache=True, fallback=_margin_rows_numpy)
def margin_rows(frames: Array, ready: Array, F: Array, Q: Array, sph_link: Array,
                sph_local: Array, sph_r: Array, sph_shape: Array, env_lo: Array,
                env_hi: Array, sp_a: Array, sp_b: Array, sp_pair: Array, n_shapes: int,
                n_pairs: int, shape_link: Array, seg_a: Array, seg_b: Array, seg_r: Array,
                box_R: Array, box_c: Array, box_h: Array, pair_a: Array, pair_b: Array,
                apart: float, env_from: int = 1) -> tuple[Array, Array, Array, Array]:
    """Every row's broad phase, its gap and its pruning, as one pass: (status FREE or
    ASK_FCL, gap, env_c, self_c) - `sphere_broad_phase` and `prune_round_pairs` of
    `CollisionChecker._collide_batch` (rows posed here from the DH chain's fixed parts F
    unless `ready`), for `CollisionChecker.is_valid_batch_margin`."""
    n = Q.shape[0]
    env_c = np.zeros((n, n_shapes, env_lo.shape[0]), dtype=np.bool_)
    self_c = np.zeros((n, n_pairs), dtype=np.bool_)
    status = np.zeros(n, dtype=np.int8)
    gap = np.empty(n)
    centre = np.empty((sph_r.shape[0], 3))
    A = np.empty((n_shapes, 3))
    B = np.empty((n_shapes, 3))
    la = np.empty(3)
    lb = np.empty(3)
    T = np.empty((4, 4))
    for k in range(n):  # posed in a pass of their own (see `certify_samples`)
        _pose(frames, ready, Q, F, k, T)
    for k in range(n):
        gap[k] = _broad_row(frames, k, sph_link, sph_local, sph_r, sph_shape, env_lo, env_hi,
                            sp_a, sp_b, sp_pair, centre, env_c, self_c, env_from)
        status[k] = _prune_and_flag(frames, k, env_c, self_c, shape_link, seg_a, seg_b, seg_r,
                                    box_R, box_c, box_h, pair_a, pair_b, apart, A, B, la, lb)
    return status, gap, env_c, self_c


@kernel(cache=True)
def _prune_and_flag(frames: Array, k: int, env_c: Array, self_c: Array, shape_link: Array,
                    seg_a: Array, seg_b: Array, seg_r: Array, box_R: Array, box_c: Array,
                    box_h: Array, pair_a: Array, pair_b: Array, apart: float, A: Array,
                    B: Array, la: Array, lb: Array) -> int:
    """Prune row k's candidate pairs; ASK_FCL if any is left, else FREE."""
    if env_c[k].any() or self_c[k].any():
        _prune_row(frames, k, env_c, self_c, shape_link, seg_a, seg_b, seg_r, box_R, box_c,
                   box_h, pair_a, pair_b, apart, A, B, la, lb)
        if env_c[k].any() or self_c[k].any():
            return ASK_FCL
    return FREE
