"""The RV-2AJ's closed-form position IK next to seeds, one compiled loop (numba).

The elastic net asks this for every moved particle in every sweep (`RV2AJ.batch_position_ik`
explains the geometry: J1 faces the point, a tool pitch fixes the wrist, J2/J3 solve a
two-link triangle on the seed's elbow branch). A numpy form evaluates every candidate pitch
of every failed row before picking the first that works; the loop stops at the first, and
costs no per-call array set-up.

Serves (the user-felt figure): the net's IK next to its seeds: 0.4 s in Python in the thesis
run.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.helpers import wrap_pi
from assistant.kernels.lazy import kernel

Array = np.ndarray

_PI = np.pi


@kernel(cache=True, inline="always")
def _planar(tx: float, ty: float, tz: float, seed: tuple, pitch: float, q6: float,
            arm: tuple, tool_length: float, max_jump: float, lower: tuple, upper: tuple,
            out: Array) -> bool:
    """Joints for one TCP point and one tool pitch into `out`; True if reachable, inside
    the limits and within `max_jump` of the seed in every joint (angles nearest the seed's).

    Inlined (numba IR) into `solve_row`, which calls it up to 1 + 2 `n_steps` times per
    move of the elastic net: as a call, its five array arguments would be counted in and
    out of use (atomic reference counts) each time, a large share of the net's reference
    counting. Even inlined, numba counts arrays in and out per call, so the seed, arm
    lengths and limits come as tuples of floats (values, never counted).
    """
    L1, L2, L3, L6 = arm[0], arm[1], arm[2], arm[3]
    face = np.arctan2(ty, tx)
    a = seed[0] + wrap_pi(face - seed[0])
    b = seed[0] + wrap_pi(face + _PI - seed[0])
    q1 = a if abs(a - seed[0]) <= abs(b - seed[0]) else b  # the seed's side
    r = tx * np.cos(q1) + ty * np.sin(q1)
    le = L6 + tool_length
    wr = r - le * np.sin(pitch)
    wz = tz - L1 - le * np.cos(pitch)
    D = (wr * wr + wz * wz - L2 * L2 - L3 * L3) / (2.0 * L2 * L3)
    reach = abs(D) <= 1.0
    Dc = min(max(D, -1.0), 1.0)
    ac = np.arctan2(np.sqrt((1.0 - Dc) * (1.0 + Dc)), Dc)  # not arccos: exact near +-1
    q3 = ac if abs(ac - seed[2]) <= abs(-ac - seed[2]) else -ac
    q2 = np.arctan2(wr, wz) - np.arctan2(L3 * np.sin(q3), L2 + L3 * np.cos(q3))
    q2 = seed[1] + wrap_pi(q2 - seed[1])
    q5 = seed[3] + wrap_pi(pitch - q2 - q3 - seed[3])
    out[0], out[1], out[2], out[3], out[4] = q1, q2, q3, q5, q6
    ok = reach
    for j in range(5):
        v = out[j]
        if v < lower[j] - 1e-9 or v > upper[j] + 1e-9 or abs(v - seed[j]) > max_jump:
            ok = False
    return ok


@kernel(cache=True)
def planar_position_ik(targets: Array, seeds: Array, pitch: Array, q6: Array, arm: Array,
                       tool_length: float, max_jump: float, lower: Array, upper: Array,
                       n_steps: int, step: float) -> tuple[Array, Array]:
    """Per row: the pulled `pitch` first, then pitch +- 1, 2, ... `n_steps` steps of `step`
    (nearest first, + before -) until one works. Returns (joints (N, 5), ok (N,)); refused
    rows keep their seeds."""
    n = targets.shape[0]
    Q = seeds.copy()
    ok = np.zeros(n, dtype=np.bool_)
    q = np.empty(5)
    arm_t, lo, hi = as_tuples(arm, lower, upper)
    for i in range(n):
        seed = (seeds[i, 0], seeds[i, 1], seeds[i, 2], seeds[i, 3], seeds[i, 4])
        if solve_row(targets[i, 0], targets[i, 1], targets[i, 2], seed, pitch[i], q6[i],
                     arm_t, tool_length, max_jump, lo, hi, n_steps, step, q):
            Q[i] = q
            ok[i] = True
    return Q, ok


@kernel(cache=True)
def as_tuples(arm: Array, lower: Array, upper: Array) -> tuple:
    """The arm lengths (L1, L2, L3, L6) and the five joints' limits as tuples, the form
    `solve_row` takes them in."""
    return ((arm[0], arm[1], arm[2], arm[3]),
            (lower[0], lower[1], lower[2], lower[3], lower[4]),
            (upper[0], upper[1], upper[2], upper[3], upper[4]))


@kernel(cache=True, inline="always")
def solve_row(tx: float, ty: float, tz: float, seed: tuple, pitch: float, q6: float,
              arm: tuple, tool_length: float, max_jump: float, lower: tuple, upper: tuple,
              n_steps: int, step: float, q: Array) -> bool:
    """`planar_position_ik` of one row into q (seed, arm and limits as tuples, see
    `as_tuples`); True if a pitch worked. Also called per row by compiled planners
    (`trajectory.net_kernel`)."""
    found = _planar(tx, ty, tz, seed, pitch, q6, arm, tool_length, max_jump, lower, upper, q)
    m = 1
    while not found and m <= n_steps:
        off = m * step
        found = _planar(tx, ty, tz, seed, pitch + off, q6, arm, tool_length, max_jump,
                        lower, upper, q)
        if not found:
            found = _planar(tx, ty, tz, seed, pitch - off, q6, arm, tool_length, max_jump,
                            lower, upper, q)
        m += 1
    return found
