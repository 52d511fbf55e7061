"""World poses of the robot's collision shapes for FCL's exact phase, compiled (numba).

`CollisionChecker._first_contacts` poses the shapes of every row the broad phase passes to
FCL, ~80 rows for a motion that grazes an obstacle, although the check stops at the row
that first touches. Written out as a loop this costs ~10 us, a tenth of `np.einsum` over
all rows (row, shape, 4 x 4 products). The products are summed in einsum's order
(j = 0..3 in turn), so the poses, and FCL's answers, are the same to the bit.

Serves (the user-felt figure): posing the robot for FCL in the world build: 1.1 s in Python
in the thesis run.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.lazy import kernel

Array = np.ndarray


def shape_poses_numpy(frames: Array, shape_link: Array, shape_T: Array,
                      ) -> tuple[Array, Array]:
    """`shape_poses` as one einsum: its fallback until compiled (own Python, row by row,
    it cost ~3 s of a first run's world build)."""
    P = np.einsum("nsij,sjc->nsic", frames[:, shape_link], shape_T)
    return np.ascontiguousarray(P[:, :, :3, :3]), np.ascontiguousarray(P[:, :, :3, 3])


@kernel(cache=True, fallback=shape_poses_numpy)
def shape_poses(frames: Array, shape_link: Array, shape_T: Array) -> tuple[Array, Array]:
    """(R (n, r, 3, 3), t (n, r, 3)) of frames[:, shape_link[s]] @ shape_T[s] per row and
    shape s: the rotation and translation parts of each product."""
    n, r = frames.shape[0], shape_link.shape[0]
    R = np.empty((n, r, 3, 3))
    t = np.empty((n, r, 3))
    for k in range(n):
        for s in range(r):
            link = shape_link[s]
            for i in range(3):
                for c in range(4):
                    acc = 0.0
                    for j in range(4):
                        acc += frames[k, link, i, j] * shape_T[s, j, c]
                    if c < 3:
                        R[k, s, i, c] = acc
                    else:
                        t[k, s, i] = acc
    return R, t
