"""The fast model's whole check as one compiled pass over capsules (numba).

The exact checker's broad phase covers shapes with spheres and prunes with capsule bounds
before FCL; its margins are sphere gaps, which on a capsule model are looser than the
capsules themselves (a 33 cm capsule of 69 mm radius split into five spheres of 102 mm):
near a table every posture's margin was under 5 mm and certified nothing. Here every
question is the capsules' own: per configuration the smallest distance from a capsule to an
obstacle box and between the capsules of each self pair - exact for the capsule model, the
segment-to-box distance (`segment_box`) and the segment-to-segment one - each pair first
bounded by the spheres around its capsules and measured only if that bound is below the
smallest distance found so far. That distance is the row's margin: a posture within that
much arm travel is free as well (`CollisionChecker.is_valid_batch_margin`), so along a
motion in the open most samples are certified by a neighbour.

Serves (the user-felt figure): a UR or Panda planning query, its edge and joint-move checks
(seconds before the fast model; target <= 50 ms a query), and the world build (<= 10 s).
"""

from __future__ import annotations

import numpy as np

from assistant.collision.broad_phase import _pose, _segment_segment_distance
from assistant.collision.segment_box import segment_box_distance_one
from assistant.kernels.lazy import kernel

Array = np.ndarray

#: `capsule_samples` status per row (the values of `broad_phase`'s: FREE, OUTSIDE_LIMITS,
#: a contact, CERTIFIED by a neighbour's margin)
FREE, OUTSIDE_LIMITS, HIT, CERTIFIED = 0, 1, 2, 3


@kernel(cache=True, inline="always")
def _capsule_row(frames: Array, k: int, cap_link: Array, cap_a: Array, cap_b: Array,
                 cap_r: Array, env_from: int, box_R: Array, box_c: Array, box_h: Array,
                 pair_a: Array, pair_b: Array, A: Array, B: Array, la: Array,
                 lb: Array) -> float:
    """The smallest capsule-to-box and self-pair capsule distance of row k (<= 0: a
    contact). A, B (capsules, 3) are scratch for the posed segment ends; la, lb (3,)."""
    n = cap_r.shape[0]
    for c in range(n):
        F = frames[k, cap_link[c]]
        for i in range(3):
            A[c, i] = (F[i, 0] * cap_a[c, 0] + F[i, 1] * cap_a[c, 1]
                       + F[i, 2] * cap_a[c, 2] + F[i, 3])
            B[c, i] = (F[i, 0] * cap_b[c, 0] + F[i, 1] * cap_b[c, 1]
                       + F[i, 2] * cap_b[c, 2] + F[i, 3])
    best = np.inf
    for c in range(n):
        if cap_link[c] < env_from:
            continue
        mx, my, mz = 0.5 * (A[c, 0] + B[c, 0]), 0.5 * (A[c, 1] + B[c, 1]), \
            0.5 * (A[c, 2] + B[c, 2])
        hx, hy, hz = B[c, 0] - mx, B[c, 1] - my, B[c, 2] - mz
        rho = np.sqrt(hx * hx + hy * hy + hz * hz) + cap_r[c]
        for e in range(box_c.shape[0]):
            s2 = 0.0  # the capsule's bounding sphere to the box, in the box's frame
            for i in range(3):
                x = (box_R[e, 0, i] * (mx - box_c[e, 0]) + box_R[e, 1, i] * (my - box_c[e, 1])
                     + box_R[e, 2, i] * (mz - box_c[e, 2]))
                d = abs(x) - box_h[e, i]
                if d > 0.0:
                    s2 += d * d
            if np.sqrt(s2) - rho >= best:
                continue
            for i in range(3):
                la[i] = (box_R[e, 0, i] * (A[c, 0] - box_c[e, 0])
                         + box_R[e, 1, i] * (A[c, 1] - box_c[e, 1])
                         + box_R[e, 2, i] * (A[c, 2] - box_c[e, 2]))
                lb[i] = (box_R[e, 0, i] * (B[c, 0] - box_c[e, 0])
                         + box_R[e, 1, i] * (B[c, 1] - box_c[e, 1])
                         + box_R[e, 2, i] * (B[c, 2] - box_c[e, 2]))
            best = min(best, segment_box_distance_one(la, lb, box_h[e]) - cap_r[c])
    for p in range(pair_a.shape[0]):
        a, b = pair_a[p], pair_b[p]
        d2 = 0.0
        ra = 0.0
        rb = 0.0
        for i in range(3):
            d = 0.5 * (A[a, i] + B[a, i] - A[b, i] - B[b, i])
            d2 += d * d
            ha = 0.5 * (B[a, i] - A[a, i])
            hb = 0.5 * (B[b, i] - A[b, i])
            ra += ha * ha
            rb += hb * hb
        bound = np.sqrt(d2) - np.sqrt(ra) - np.sqrt(rb) - cap_r[a] - cap_r[b]
        if bound >= best:
            continue
        best = min(best, _segment_segment_distance(A[a], B[a], A[b], B[b])
                   - cap_r[a] - cap_r[b])
    return best


@kernel(cache=True)
def capsule_rows(frames: Array, ready: Array, F: Array, Q: Array, cap_link: Array,
                 cap_a: Array, cap_b: Array, cap_r: Array, env_from: int, box_R: Array,
                 box_c: Array, box_h: Array, pair_a: Array, pair_b: Array) -> Array:
    """Every row's smallest capsule distance (`_capsule_row`; <= 0: a contact), rows posed
    from the chain's fixed parts F unless `ready`."""
    n = Q.shape[0]
    gap = np.empty(n)
    m = cap_r.shape[0]
    A, B = np.empty((m, 3)), np.empty((m, 3))
    la, lb = np.empty(3), np.empty(3)
    T = np.empty((4, 4))
    for k in range(n):
        _pose(frames, ready, Q, F, k, T)
    for k in range(n):
        gap[k] = _capsule_row(frames, k, cap_link, cap_a, cap_b, cap_r, env_from, box_R,
                              box_c, box_h, pair_a, pair_b, A, B, la, lb)
    return gap


@kernel(cache=True)
def capsule_samples(frames: Array, ready: Array, F: Array, Q: Array, inside: Array,
                    first: Array, last: Array, stride: int, radii: Array, cap_link: Array,
                    cap_a: Array, cap_b: Array, cap_r: Array, env_from: int, box_R: Array,
                    box_c: Array, box_h: Array, pair_a: Array, pair_b: Array,
                    first_only: bool = False) -> tuple[Array, Array]:
    """The samples of one or more motions (rows of a motion consecutive, `first`/`last` its
    ends), as `broad_phase.certify_samples` does them: every `stride`-th row of a motion and
    its last get `_capsule_row` and its distance as margin; a row whose arm travel from the
    checked row before or after it stays below that row's margin is CERTIFIED; the others
    are checked themselves. Returns (status, gap): FREE / OUTSIDE_LIMITS / HIT / CERTIFIED
    per row, and the distance where a row was checked (NaN elsewhere). With `first_only`
    only each motion's first invalid row matters: the rows after a motion's first checked
    contact are HIT unchecked (a motion into an obstacle costs its rows up to it)."""
    n, dof = Q.shape
    status = np.zeros(n, dtype=np.int8)
    gap = np.full(n, np.nan)
    m = cap_r.shape[0]
    A, B = np.empty((m, 3)), np.empty((m, 3))
    la, lb = np.empty(3), np.empty(3)
    T = np.empty((4, 4))
    coarse = np.zeros(n, dtype=np.bool_)
    start = 0
    for k in range(n):
        if first[k]:
            start = k
        coarse[k] = (k - start) % stride == 0 or last[k]
    margin = np.full(n, -np.inf)
    stop = n  # with first_only: the current motion's first coarse contact
    for k in range(n):
        if first[k]:
            stop = n
        if not inside[k]:
            status[k] = OUTSIDE_LIMITS
            if first_only and stop == n:
                stop = k
        elif coarse[k]:
            if first_only and k > stop:
                status[k] = HIT
                continue
            _pose(frames, ready, Q, F, k, T)
            g = _capsule_row(frames, k, cap_link, cap_a, cap_b, cap_r, env_from, box_R,
                             box_c, box_h, pair_a, pair_b, A, B, la, lb)
            gap[k] = g
            margin[k] = g
            status[k] = FREE if g > 0.0 else HIT
            if first_only and g <= 0.0 and stop == n:
                stop = k
    prev = -1
    nxt = np.empty(n, dtype=np.int64)
    for k in range(n - 1, -1, -1):
        nxt[k] = k if coarse[k] else prev
        if coarse[k]:
            prev = k
    prev = -1
    todo = np.zeros(n, dtype=np.bool_)
    seen_hit = False  # first_only: past a coarse contact of its motion
    for k in range(n):
        if first[k]:
            seen_hit = False
        if coarse[k]:
            prev = k
            if status[k] != FREE:
                seen_hit = True
            continue
        if not inside[k]:
            continue
        if first_only and seen_hit:
            status[k] = HIT
            continue
        free = False
        for c in (prev, nxt[k]):
            if c < 0:
                continue
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
        if todo[k]:
            g = _capsule_row(frames, k, cap_link, cap_a, cap_b, cap_r, env_from, box_R,
                             box_c, box_h, pair_a, pair_b, A, B, la, lb)
            gap[k] = g
            status[k] = FREE if g > 0.0 else HIT
    return status, gap
