"""Fewer joint targets for links that stop at every command (the KUKA REST bridge).

Each REST command is one exact-stop PTP, so sending every point of a planned joint path
would stop the arm hundreds of times. A synchronous PTP between two configurations moves
along the straight joint-space segment between them, so we keep only the vertices that a
straight segment cannot replace within a tolerance (Ramer-Douglas-Peucker in joint space).

The distance is measured where it matters, on the arm: a joint deviation dq moves no point
of the arm by more than sum_i r_i |dq_i| (`Robot.arm_radii`). The executed path therefore
stays within `tol_m` of the checked one everywhere on the arm (the distance from a straight
segment to the chord is convex along it, so checking vertices suffices). The planner's
clearance must exceed `tol_m`; the default (2 mm) is well below the planner's margins.
"""

from __future__ import annotations

import numpy as np

Array = np.ndarray


def arm_deviation(points: Array, a: Array, b: Array, radii: Array) -> Array:
    """Weighted distance of each point to the joint segment a-b (arm-motion bound, metres)."""
    d = b - a
    w = radii
    denom = float(np.sum((w * d) ** 2))
    rel = points - a[None]
    if denom <= 1e-18:
        s = np.zeros(len(points))
    else:
        s = np.clip((rel * w[None] ** 2) @ d / denom, 0.0, 1.0)
    off = rel - s[:, None] * d[None]
    return np.abs(off) @ w


def decimate_joint_path(path: Array, radii: Array, tol_m: float) -> Array:
    """Indices of the vertices to keep (always the first and the last), ascending."""
    P = np.asarray(path, dtype=float)
    n = len(P)
    if n <= 2:
        return np.arange(n)
    keep = np.zeros(n, dtype=bool)
    keep[0] = keep[-1] = True
    stack = [(0, n - 1)]
    r = np.asarray(radii, dtype=float)
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        dev = arm_deviation(P[i + 1:j], P[i], P[j], r)
        k = int(np.argmax(dev))
        if dev[k] > tol_m:
            m = i + 1 + k
            keep[m] = True
            stack += [(i, m), (m, j)]
    return np.nonzero(keep)[0]
