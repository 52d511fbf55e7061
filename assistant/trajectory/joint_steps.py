"""`assemble.joint_interpolation` as one compiled loop (numba).

Why: a straight joint move is sampled for every fallback joint move, every split the
assembly tries and every check of one (several a query); as numpy it is eight calls
(~6 us each time). The steps are the numpy form's, number for number: the arm travel
summed joint by joint in order (np.sum's order for a handful of joints), the count,
np.linspace's fractions, q0 + f (q1 - q0).

Serves (the user-felt figure): the joint moves' samples: under 0.1 s in Python; a candidate
to drop.
"""

from __future__ import annotations

import math

import numpy as np

from assistant.kernels.lazy import kernel

Array = np.ndarray


@kernel(cache=True)
def joint_steps(q0: Array, q1: Array, radii: Array, step: float) -> Array:
    """The move q0 -> q1 sampled so no arm point (radii: `Robot.arm_radii`) moves more than
    `step` between samples: (n + 1, dof), both ends included."""
    dof = q0.shape[0]
    travel = 0.0
    for j in range(dof):
        travel += radii[j] * abs(q1[j] - q0[j])
    n = max(1, int(math.ceil(travel / step)))
    out = np.empty((n + 1, dof))
    inc = 1.0 / n
    for i in range(n + 1):
        f = 1.0 if i == n else i * inc + 0.0
        for j in range(dof):
            out[i, j] = q0[j] + f * (q1[j] - q0[j])
    return out
