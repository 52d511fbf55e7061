"""The roadmap path's free joints (those that move no geometry, e.g. J6 with a straight
tool) ramped from start to goal along the path, compiled (numba).

Why: every found path gets this (`RoadmapPlanner._interpolate_free_joints`); as numpy it
is a dozen calls (~0.04 ms a query). The steps are the numpy form's, number for number:
segment lengths of the weighted other joints (differences of the weighted values, squares
summed in order), their running sum, fractions of the whole (or even fractions for a path
that does not move them), and start + s (goal - start) per free joint.

Serves (the user-felt figure): the found path's free-joint ramp: under 0.1 s in Python; a
candidate to drop.
"""

from __future__ import annotations

import math

import numpy as np

from assistant.kernels.lazy import kernel

Array = np.ndarray


@kernel(cache=True)
def ramp_free_joints(P: Array, free: Array, weights: Array) -> None:
    """Set P's free joints (in place) to their start-to-goal ramp along the path P (M, dof),
    M >= 2, parametrised by the weighted arc length of the other joints."""
    m, dof = P.shape
    s = np.zeros(m)
    for i in range(1, m):
        acc = 0.0
        first = True
        for j in range(dof):
            if free[j]:
                continue
            d = P[i, j] * weights[j] - P[i - 1, j] * weights[j]  # np.diff of weighted
            acc = d * d if first else acc + d * d
            first = False
        s[i] = s[i - 1] + math.sqrt(acc)
    total = s[m - 1]
    for i in range(m):
        if total > 0:
            f = s[i] / total
        else:  # np.linspace(0, 1, m): i * (1 / (m - 1)), the last exactly 1
            f = 1.0 if i == m - 1 else i * (1.0 / (m - 1)) + 0.0
        for j in range(dof):
            if free[j]:
                P[i, j] = P[0, j] + f * (P[m - 1, j] - P[0, j])
