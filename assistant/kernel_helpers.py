"""Small compiled helpers the numba kernels share: 3x3 products, Rodrigues, a limit test.

numba's `@` goes through BLAS, slow at 3 x 3 and warning on slices, so the kernels write
their small products out; these are the ones more than one kernel needs
(`rv2aj_pose_batch`, `trajectory.follow_kernel`, `trajectory.net_kernel`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

Array = np.ndarray


@njit(cache=True)
def mm3(A: Array, B: Array) -> Array:
    """A (3, 3) @ B (3, k) as plain loops."""
    out = np.zeros((3, B.shape[1]))
    for r in range(3):
        for c in range(B.shape[1]):
            out[r, c] = A[r, 0] * B[0, c] + A[r, 1] * B[1, c] + A[r, 2] * B[2, c]
    return out


@njit(cache=True, inline="always")
def mm3_into(A: Array, B: Array, out: Array) -> None:
    """`mm3` into out (3, k): the same products and sums, no new array."""
    for r in range(3):
        for c in range(B.shape[1]):
            out[r, c] = A[r, 0] * B[0, c] + A[r, 1] * B[1, c] + A[r, 2] * B[2, c]


@njit(cache=True)
def axis_angle3(axis: Array, norm: float, angle: float) -> Array:
    """`transforms.axis_angle_batch` of one axis (not necessarily unit) given its norm:
    I + sin(angle) K + (1 - cos(angle)) K^2; the identity for a zero axis."""
    if norm < 1e-15:
        return np.eye(3)
    k = axis / norm
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * mm3(K, K)


@njit(cache=True, inline="always")
def within_limits(q: Array, lower: Array, upper: Array) -> bool:
    """`JointLimits.contains_batch` of one row (tolerance 1e-9)."""
    for j in range(q.shape[0]):  # noqa: SIM110 - a loop numba compiles, not a generator
        if not (q[j] >= lower[j] - 1e-9 and q[j] <= upper[j] + 1e-9):
            return False
    return True
