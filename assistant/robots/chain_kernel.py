"""Link frames of a URDF chain for a few configurations at a time, compiled (numba).

Serves the re-plan after a Collision! indication (the operator waits, the arm halted): the
planners there ask `BatchChain` for one to a few hundred postures per call - the joint RRT's
hand test, the elastic net's position IK, the smoothing's IK steps - thousands of calls per
re-plan. The numpy form (`batch_chain`) is built for the reachability table's millions of
postures: ~500 numpy operations per call, each ~1 us of call overhead whatever the batch, so
a Panda re-plan spent about half its CPU there (4 s of 8 s profiled). Here one call costs
about a microsecond per posture.

The chain is packed once (`PackedChain`): per joint the constant transform from the previous
link frame to the joint frame at q = 0, the unit axis, and whether it is prismatic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from assistant.kernels.lazy import kernel

Array = np.ndarray


@dataclass(frozen=True)
class PackedChain:
    """A chain as arrays the kernel reads: M (n, 4, 4), axes (n, 3), prismatic (n,) bool."""

    M: Array
    axes: Array
    prismatic: Array


def chain_link_frames_numpy(Q: Array, M: Array, axes: Array, prismatic: Array,
                            out: Array) -> None:
    """`chain_link_frames` as batched numpy products (its fallback until compiled)."""
    N, n = Q.shape
    T = np.broadcast_to(np.eye(4), (N, 4, 4))
    out[:, 0] = T
    for i in range(n):
        J = np.broadcast_to(np.eye(4), (N, 4, 4)).copy()
        a = axes[i]
        if prismatic[i]:
            J[:, :3, 3] = Q[:, i, None] * a
        else:
            K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
            s, c = np.sin(Q[:, i]), np.cos(Q[:, i])
            J[:, :3, :3] = (np.eye(3) + s[:, None, None] * K
                            + (1.0 - c)[:, None, None] * (K @ K))
        T = T @ M[i] @ J
        out[:, i + 1] = T


@kernel(cache=True, fallback=chain_link_frames_numpy)
def chain_link_frames(Q: Array, M: Array, axes: Array, prismatic: Array,
                      out: Array) -> None:
    """out[k, 0] = I; out[k, i + 1] = out[k, i] M[i] Motion_i(Q[k, i]), where the motion
    rotates about (or, if prismatic, translates along) the unit axes[i] (Rodrigues' form)."""
    N, n = Q.shape
    for k in range(N):
        T = out[k, 0]
        for r in range(4):
            for col in range(4):
                T[r, col] = 1.0 if r == col else 0.0
        for i in range(n):
            P = out[k, i]
            Ti = out[k, i + 1]
            # A = P M[i] (affine: the last row stays 0 0 0 1)
            for r in range(3):
                for col in range(4):
                    Ti[r, col] = (P[r, 0] * M[i, 0, col] + P[r, 1] * M[i, 1, col]
                                  + P[r, 2] * M[i, 2, col])
                Ti[r, 3] += P[r, 3]
            Ti[3, 0] = 0.0
            Ti[3, 1] = 0.0
            Ti[3, 2] = 0.0
            Ti[3, 3] = 1.0
            ax, ay, az = axes[i, 0], axes[i, 1], axes[i, 2]
            q = Q[k, i]
            if prismatic[i]:
                for r in range(3):
                    Ti[r, 3] += q * (Ti[r, 0] * ax + Ti[r, 1] * ay + Ti[r, 2] * az)
                continue
            s, c = math.sin(q), math.cos(q)
            v = 1.0 - c
            # R = I + s K + v K K for the unit axis (K the cross-product matrix)
            r00 = c + v * ax * ax
            r01 = v * ax * ay - s * az
            r02 = v * ax * az + s * ay
            r10 = v * ax * ay + s * az
            r11 = c + v * ay * ay
            r12 = v * ay * az - s * ax
            r20 = v * ax * az - s * ay
            r21 = v * ay * az + s * ax
            r22 = c + v * az * az
            for r in range(3):
                x, y, z = Ti[r, 0], Ti[r, 1], Ti[r, 2]
                Ti[r, 0] = x * r00 + y * r10 + z * r20
                Ti[r, 1] = x * r01 + y * r11 + z * r21
                Ti[r, 2] = x * r02 + y * r12 + z * r22
