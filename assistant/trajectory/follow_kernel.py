"""The nearest-branch walk of `cartesian_follow.follow_poses` as one compiled loop (numba).

Why: every LINEAR or CIRCULAR move of a planned trajectory walks its poses (20-60) picking,
for each, the IK branch nearest the previous joints and checking the step. With all branches
of all poses already computed in one batch (`rv2aj_pose_batch`), what is left per pose is a
handful of small numpy calls - about 10 us each, ~1 ms per planning query. The loop does
the same arithmetic (Euclidean norm summed in joint order, first minimum, first largest
jump) and stops where the Python side must take over: a pose the batch cannot answer, or a
jump.
"""

from __future__ import annotations

import numpy as np
from numba import njit

Array = np.ndarray


@njit(cache=True)
def walk_nearest(joints: Array, valid: Array, usable: Array, q_prev: Array,
                 max_joint_step: float, first: int, out: Array) -> tuple[int, int]:
    """Walk poses first.. writing each one's nearest valid branch to `out` (M, dof).

    joints (M, K, dof) candidates, valid (M, K) which are solutions, usable (M,) poses the
    batch answers. Returns (stop, joint): stop = M when every pose was walked; else the pose
    it stopped at, with joint = the joint that would jump more than `max_joint_step` there
    (its row in `out` then holds that nearest branch), or -1 if the batch cannot answer it.
    """
    m, k_max, dof = joints.shape
    q = q_prev.copy()
    for i in range(first, m):
        if not usable[i]:
            return i, -1
        best, best_d = -1, np.inf
        for k in range(k_max):
            if not valid[i, k]:
                continue
            s = 0.0
            for j in range(dof):
                d = joints[i, k, j] - q[j]
                s += d * d
            d = np.sqrt(s)
            if d < best_d:
                best, best_d = k, d
        worst_j, worst = 0, -1.0
        for j in range(dof):
            out[i, j] = joints[i, best, j]
            jump = abs(out[i, j] - q[j])
            if jump > worst:
                worst_j, worst = j, jump
        if worst > max_joint_step:
            return i, worst_j
        for j in range(dof):
            q[j] = out[i, j]
    return m, -1
