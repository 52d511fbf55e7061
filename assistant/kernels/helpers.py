"""Small compiled helpers the numba kernels share: 3x3 products, Rodrigues, a limit test.

numba's `@` goes through BLAS, slow at 3 x 3 and warning on slices, so the kernels write
their small products out; these are the ones more than one kernel needs
(`rv2aj_pose_batch`, `trajectory.net_kernel`).

Serves (the user-felt figure): the RV-2AJ's IK and the net's moves: 0.8 s in Python in the
thesis run.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.lazy import kernel

Array = np.ndarray


@kernel(cache=True, inline="always")
def mm3_into(A: Array, B: Array, out: Array) -> None:
    """A (3, 3) @ B (3, k) into out (3, k) as plain loops."""
    for r in range(3):
        for c in range(B.shape[1]):
            out[r, c] = A[r, 0] * B[0, c] + A[r, 1] * B[1, c] + A[r, 2] * B[2, c]


@kernel(cache=True, inline="always")
def axis_angle3_into(axis: Array, norm: float, angle: float, K: Array, KK: Array,
                     out: Array) -> None:
    """`transforms.axis_angle_batch` of one axis (not necessarily unit) given its norm,
    I + sin(angle) K + (1 - cos(angle)) K^2 (the identity for a zero axis), into out (3, 3),
    K and KK scratch (3, 3): the same operations element
    for element (I + sin K, then + (1 - cos) K K with `mm3_into`'s sums), no new arrays."""
    if norm < 1e-15:
        for r in range(3):
            for c in range(3):
                out[r, c] = 1.0 if r == c else 0.0
        return
    k0, k1, k2 = axis[0] / norm, axis[1] / norm, axis[2] / norm
    K[0, 0], K[0, 1], K[0, 2] = 0.0, -k2, k1
    K[1, 0], K[1, 1], K[1, 2] = k2, 0.0, -k0
    K[2, 0], K[2, 1], K[2, 2] = -k1, k0, 0.0
    mm3_into(K, K, KK)
    s, t = np.sin(angle), 1.0 - np.cos(angle)
    for r in range(3):
        for c in range(3):
            out[r, c] = ((1.0 if r == c else 0.0) + s * K[r, c]) + t * KK[r, c]


@kernel(cache=True, inline="always")
def within_limits(q: Array, lower: Array, upper: Array) -> bool:
    """`JointLimits.contains_batch` of one row (tolerance 1e-9)."""
    for j in range(q.shape[0]):  # noqa: SIM110 - a loop numba compiles, not a generator
        if not (q[j] >= lower[j] - 1e-9 and q[j] <= upper[j] + 1e-9):
            return False
    return True


@kernel(cache=True, inline="always")
def wrap_pi(a: float) -> float:
    """(a + pi) % (2 pi) - pi, Python's float modulo, to the bit: an angle into [-pi, pi).

    The modulo is a libm fmod (~5 ns) and the IK kernels wrap several joints per solution;
    for a + pi already in [0, 2 pi) it returns a + pi itself (fmod is exact there, and a
    zero comes out +0 either way), so only other values pay for it."""
    x = a + np.pi
    if x >= 0.0 and x < 2.0 * np.pi:
        return x - np.pi
    return x % (2.0 * np.pi) - np.pi
