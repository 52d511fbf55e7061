"""Fewer joint targets for links that stop at every command (the KUKA REST bridge).

Each REST command is one exact-stop PTP, so sending every point of a planned joint path
would stop the arm hundreds of times. A synchronous PTP between two configurations moves
along the straight joint-space segment between them, so we keep only the vertices that a
straight segment cannot replace within a tolerance (Ramer-Douglas-Peucker in joint space,
comparing points at equal fractions of the path length, so out-and-back paths survive).

The distance is measured where it matters, on the arm: a joint deviation dq moves no point
of the arm by more than sum_i r_i |dq_i| (`Robot.arm_radii`). The executed path therefore
stays within `tol_m` of the checked one everywhere on the arm. The planner's
clearance must exceed `tol_m`; the default (2 mm) is well below the planner's margins.
"""

from __future__ import annotations

import numpy as np

Array = np.ndarray


def arm_deviation(points: Array, a: Array, b: Array, radii: Array) -> Array:
    """How far (bound on any arm point, metres) each vertex is from the chord a -> b.

    `points` is the sub-path from a to b, a and b included. Each vertex is compared with the
    chord point at the same fraction of the path's length (weighted by the arm radii), so a
    path that runs out and back along one line is not mistaken for a straight one. Within a
    segment both curves are linear in that fraction, so the deviation between vertices is
    never larger than at the vertices.
    """
    w = np.asarray(radii, dtype=float)
    P = np.asarray(points, dtype=float)
    steps = np.abs(np.diff(P, axis=0)) @ w
    length = np.concatenate([[0.0], np.cumsum(steps)])
    total = float(length[-1])
    s = length / total if total > 1e-15 else np.zeros(len(P))
    off = P - (a[None] + s[:, None] * (b - a)[None])
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
        dev = arm_deviation(P[i:j + 1], P[i], P[j], r)
        k = int(np.argmax(dev))
        if dev[k] > tol_m:
            m = i + k
            keep[m] = True
            stack += [(i, m), (m, j)]
    return np.nonzero(keep)[0]


def exact_stop_targets(path: Array, here: Array, radii: Array, tol_m: float,
                       ) -> tuple[Array, Array]:
    """The targets (K, dof) a link sends as exact stops for a validated joint path starting
    at or near the arm's posture `here`, decimated within `tol_m` of the path measured on
    the arm, and the path index of each (KUKA PTP, ABB MoveAbsJ, UR movej)."""
    lead = 0 if np.allclose(path[0], here, atol=1e-6) else 1
    full = path if lead == 0 else np.vstack([here[None], path])
    keep = decimate_joint_path(full, radii, tol_m)
    keep = keep[keep > 0] if len(keep) > 1 else keep
    return full[keep], np.maximum(keep - lead, 0)
