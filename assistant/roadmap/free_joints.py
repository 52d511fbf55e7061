"""The roadmap path's free joints (those that move no geometry, e.g. J6 with a straight
tool) ramped from start to goal along the path.

Every found path gets this (`RoadmapPlanner._interpolate_free_joints`): a dozen numpy calls,
~0.04 ms a query.
"""

from __future__ import annotations

import numpy as np

Array = np.ndarray


def ramp_free_joints(P: Array, free: Array, weights: Array) -> None:
    """Set P's free joints (in place) to their start-to-goal ramp along the path P (M, dof),
    M >= 2, parametrised by the weighted arc length of the other joints (even fractions for
    a path that does not move them)."""
    m = len(P)
    W = P[:, ~free] * weights[~free]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(W, axis=0), axis=1))])
    f = s / s[-1] if s[-1] > 0 else np.linspace(0.0, 1.0, m)
    P[:, free] = P[0, free] + f[:, None] * (P[m - 1, free] - P[0, free])
