"""Standard Denavit-Hartenberg chains: A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i).

Used by the built-in robots. `DHChain` keeps the table immutable; the per-configuration
algorithms are free functions over it so they can be vectorised over many configurations.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

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


def rz_batch(q: Array) -> Array:
    """Rz(q) as (N, 4, 4)."""
    n = q.shape[0]
    out = np.zeros((n, 4, 4))
    c, s = np.cos(q), np.sin(q)
    out[:, 0, 0] = c
    out[:, 0, 1] = -s
    out[:, 1, 0] = s
    out[:, 1, 1] = c
    out[:, 2, 2] = 1.0
    out[:, 3, 3] = 1.0
    return out


def chain_frames(chain: DHChain, q: Array) -> Array:
    """Link frames for one configuration, shape (n+1, 4, 4).

    Entry 0 is the base; entry i (1..n) is the frame of link i, i.e. the base-side frame of
    joint i rotated by q_i (before the fixed part F_i). The flange is `flange_frame`.
    """
    n = len(chain.rows)
    out = np.empty((n + 1, 4, 4))
    out[0] = np.eye(4)
    F = chain.fixed_parts
    cs, sn = np.cos(q), np.sin(q)
    T = out[0]
    for i in range(n):
        # T @ Rz(q_i) touches only the first two columns.
        Ti = T.copy()
        Ti[:, 0] = cs[i] * T[:, 0] + sn[i] * T[:, 1]
        Ti[:, 1] = -sn[i] * T[:, 0] + cs[i] * T[:, 1]
        out[i + 1] = Ti
        T = Ti @ F[i]
    return out


def flange_frame(chain: DHChain, q: Array) -> Array:
    frames = chain_frames(chain, q)
    return frames[-1] @ chain.fixed_parts[-1]


def batch_chain_frames(chain: DHChain, Q: Array) -> tuple[Array, Array]:
    """Link frames and flanges for N configurations: ((N, n+1, 4, 4), (N, 4, 4)).

    Plain batched matrix products (~0.5 M configurations/s here); the robots that need more
    (the reachability table) write their closed form out per element instead.
    """
    N, n = Q.shape
    frames = np.empty((N, n + 1, 4, 4))
    T = np.broadcast_to(np.eye(4), (N, 4, 4)).copy()
    frames[:, 0] = T
    for i in range(n):
        T = T @ rz_batch(Q[:, i])
        frames[:, i + 1] = T
        T = T @ chain.fixed_parts[i]
    return frames, T
