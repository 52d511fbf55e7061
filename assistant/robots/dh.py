"""Standard Denavit-Hartenberg chains: A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i).

Used by the built-in robots. `DHChain` keeps the table immutable; the per-configuration
algorithms are free functions over it so they can be vectorised over many configurations.

Serves (the user-felt figure): the link frames of every check: in the thesis run the numpy
fallback costs 4 s, compiled under 0.1 s.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from assistant.kernels.lazy import kernel

Array = np.ndarray


@dataclass(frozen=True)
class DHRow:
    """One joint of a DH table, lengths in metres, angles in radians."""

    d: float
    theta_offset: float
    a: float
    alpha: float


@dataclass(frozen=True)
class DHChain:
    rows: tuple[DHRow, ...]

    @functools.cached_property
    def fixed_parts(self) -> tuple[Array, ...]:
        """All F_i, computed once (hot in single-configuration FK)."""
        return tuple(self.fixed_part(i) for i in range(len(self.rows)))

    @functools.cached_property
    def fixed_stack(self) -> Array:
        """The F_i as one contiguous (n, 4, 4) array (for the compiled batch)."""
        return np.ascontiguousarray(np.array(self.fixed_parts, dtype=float))

    def fixed_part(self, i: int) -> Array:
        """F_i = Rz(offset) Tz(d) Tx(a) Rx(alpha): the joint-independent part of A_i."""
        r = self.rows[i]
        co, so = np.cos(r.theta_offset), np.sin(r.theta_offset)
        ca, sa = np.cos(r.alpha), np.sin(r.alpha)
        return np.array(
            [
                [co, -so * ca, so * sa, r.a * co],
                [so, co * ca, -co * sa, r.a * so],
                [0.0, sa, ca, r.d],
                [0.0, 0.0, 0.0, 1.0],
            ]
        )


def chain_frames(chain: DHChain, q: Array) -> Array:
    """Link frames for one configuration, shape (n+1, 4, 4).

    Entry 0 is the base; entry i (1..n) is the frame of link i, i.e. the base-side frame of
    joint i rotated by q_i (before the fixed part F_i). The flange is `flange_frame`.
    The compiled loop of `batch_chain_frames` (~1 us, where numpy's per-call overhead
    dominates, and a planning query asks for ~20 single poses), with the same bits as the
    numpy form (`chain_frames_numpy`).
    """
    Q = np.ascontiguousarray(q, dtype=float).reshape(1, -1)
    return _chain_frames_kernel(Q, chain.fixed_stack)[0]


def flange_frame(chain: DHChain, q: Array) -> Array:
    frames = chain_frames(chain, q)
    return frames[-1] @ chain.fixed_parts[-1]


def batch_chain_frames(chain: DHChain, Q: Array) -> tuple[Array, Array]:
    """Link frames and flanges for N configurations: ((N, n+1, 4, 4), (N, 4, 4)).

    One compiled loop (`_chain_frames_kernel`): the planners ask for a few to a few dozen
    configurations at a time, where numpy's batched 4x4 products spend their time in call
    overhead (10 configurations cost ~4 us compiled); the robots that need millions (the
    reachability table) write their closed form out per element instead.
    """
    Q = np.ascontiguousarray(Q, dtype=float)
    F = chain.fixed_stack
    frames = _chain_frames_kernel(Q, F)
    return frames, frames[:, -1] @ F[-1]


def chain_frames_numpy(Q: Array, F: Array) -> Array:
    """`_chain_frames_kernel` as batched numpy, for the configurations all at once (its
    fallback until the kernel is compiled: the world build poses ~400 000 configurations)."""
    N, n = Q.shape
    out = np.zeros((N, n + 1, 4, 4))
    T = np.broadcast_to(np.eye(4), (N, 4, 4))
    out[:, 0] = T
    c, s = np.cos(Q), np.sin(Q)
    for i in range(n):
        Ti = out[:, i + 1]
        Ti[:, :, 0] = c[:, i, None] * T[:, :, 0] + s[:, i, None] * T[:, :, 1]
        Ti[:, :, 1] = c[:, i, None] * T[:, :, 1] - s[:, i, None] * T[:, :, 0]
        Ti[:, :, 2:] = T[:, :, 2:]
        T = Ti @ F[i]
    return out


def _chain_row_numpy(q: Array, F: Array, out: Array, T: Array) -> None:
    """`chain_row` with numpy columns (its fallback until compiled; one configuration)."""
    M = np.eye(4)
    out[0] = M
    for i in range(q.shape[0]):
        c, s = math.cos(q[i]), math.sin(q[i])
        Ti = out[i + 1]
        Ti[:, 0] = c * M[:, 0] + s * M[:, 1]
        Ti[:, 1] = c * M[:, 1] - s * M[:, 0]
        Ti[:, 2:] = M[:, 2:]
        M = Ti @ F[i]
    T[:] = M


@kernel(cache=True, fallback=chain_frames_numpy)
def _chain_frames_kernel(Q: Array, F: Array) -> Array:
    """frames[k, i + 1] = frames[k, i] F[i - 1] Rz(Q[k, i]) (F[-1] only after), base = I."""
    N, n = Q.shape
    out = np.zeros((N, n + 1, 4, 4))
    T = np.empty((4, 4))
    for k in range(N):
        chain_row(Q[k], F, out[k], T)
    return out


@kernel(cache=True, inline="always", fallback=_chain_row_numpy)
def chain_row(q: Array, F: Array, out: Array, T: Array) -> None:
    """`_chain_frames_kernel` of one configuration q into out (n+1, 4, 4); T is scratch.
    Also called per row by compiled planners (`trajectory.net_kernel`)."""
    n = q.shape[0]
    T[:] = 0.0
    for r in range(4):
        T[r, r] = 1.0
    out[0] = T
    for i in range(n):
        c, s = np.cos(q[i]), np.sin(q[i])
        Ti = out[i + 1]
        for r in range(4):  # T @ Rz(q_i) changes only the first two columns
            Ti[r, 0] = c * T[r, 0] + s * T[r, 1]
            Ti[r, 1] = c * T[r, 1] - s * T[r, 0]
            Ti[r, 2] = T[r, 2]
            Ti[r, 3] = T[r, 3]
        for r in range(4):
            for col in range(4):
                T[r, col] = (Ti[r, 0] * F[i, 0, col] + Ti[r, 1] * F[i, 1, col]
                             + Ti[r, 2] * F[i, 2, col] + Ti[r, 3] * F[i, 3, col])
