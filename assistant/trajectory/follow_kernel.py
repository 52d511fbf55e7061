"""The nearest-branch walk of `cartesian_follow.follow_poses` as one compiled loop (numba).

Why: every LINEAR or CIRCULAR move of a planned trajectory walks its poses (20-60) picking,
for each, the IK branch nearest the previous joints and checking the step. With all branches
of all poses already computed in one batch (`rv2aj_pose_batch`), what is left per pose is a
handful of small numpy calls - about 10 us each, ~1 ms per planning query. The loop does
the same arithmetic (Euclidean norm summed in joint order, first minimum, first largest
jump) and stops where the Python side must take over: a pose the batch cannot answer, or a
jump.

Serves (the user-felt figure): the Cartesian moves' sample poses: under 0.1 s in Python in
the thesis run; a candidate to drop.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.helpers import axis_angle3_into, mm3
from assistant.kernels.lazy import kernel

Array = np.ndarray


@kernel(cache=True)
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


@kernel(cache=True)
def slerp_kernel(R0: Array, R1: Array, u: Array) -> Array:
    """Rotations (M, 3, 3) from R0 to R1 at fractions u in [0, 1] (`slerp_rotations`).

    The turn R0^T R1 as a unit quaternion (Shepperd's choice of the largest diagonal term,
    as scipy's `Rotation.from_matrix`), taken with w >= 0 (the shorter way), gives axis and
    angle = 2 atan2(|xyz|, w), stable near 0 and pi; each fraction is then one Rodrigues
    rotation. Through scipy and numpy this costs ~0.2 ms per LINEAR/CIRCULAR move.
    """
    out = np.empty((len(u), 3, 3))
    slerp_into(R0, R1, u, out)
    return out


@kernel(cache=True)
def slerp_into(R0: Array, R1: Array, u: Array, out: Array) -> None:
    """`slerp_kernel` into the first three rows and columns of out[n] (M, >= 3, >= 3)."""
    axis, s, angle = _turn(R0, R1)
    K, KK, R = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    for n in range(len(u)):
        axis_angle3_into(axis, s, min(max(u[n], 0.0), 1.0) * angle, K, KK, R)
        for r in range(3):  # `mm3(R0, R)`'s products and sums
            for c in range(3):
                out[n, r, c] = R0[r, 0] * R[0, c] + R0[r, 1] * R[1, c] + R0[r, 2] * R[2, c]


@kernel(cache=True)
def _turn(R0: Array, R1: Array) -> tuple[Array, float, float]:
    """The rotation R0^T R1 as (axis x, y, z of its unit quaternion with w >= 0, the axis'
    norm, angle) (`slerp_kernel`'s docstring)."""
    M = mm3(R0.T, R1)
    tr = M[0, 0] + M[1, 1] + M[2, 2]
    q = np.empty(4)  # x, y, z, w
    i = 0
    for k in range(1, 3):
        if M[k, k] > M[i, i]:
            i = k
    if tr > M[i, i]:
        q[0], q[1], q[2] = M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]
        q[3] = 1.0 + tr
    else:
        j, k = (i + 1) % 3, (i + 2) % 3
        q[i] = 1.0 - tr + 2.0 * M[i, i]
        q[j] = M[j, i] + M[i, j]
        q[k] = M[k, i] + M[i, k]
        q[3] = M[k, j] - M[j, k]
    if q[3] < 0.0:
        q = -q
    s = np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2])
    return q[:3].copy(), s, 2.0 * np.arctan2(s, q[3])


@kernel(cache=True)
def primitive_pose_rows(is_arc: bool, start: Array, end: Array, centre: Array,
                        normal: Array, sweep: float, n: int, R0: Array, R1: Array,
                        ) -> tuple[Array, Array]:
    """(u, T) of a LINEAR/CIRCULAR move's samples (`primitives.primitive_poses`): the n + 1
    fractions of `np.linspace(0, 1, n + 1)`, the points of `LinePrimitive.point_at` or
    `ArcPrimitive.point_at` (start/end resp. start/centre/normal/sweep) and the rotations of
    `slerp_rotations(R0, R1, u)`, stacked as `poses_from` stacks them - the same
    operations element for element."""
    u = np.empty(n + 1)
    step = 1.0 / n
    for k in range(n + 1):
        u[k] = k * step + 0.0  # linspace: arange * step, + start
    u[n] = 1.0
    T = np.zeros((n + 1, 4, 4))
    slerp_into(R0, R1, u, T)
    if is_arc:
        r0, r1, r2 = start[0] - centre[0], start[1] - centre[1], start[2] - centre[2]
        # `primitives._cross(normal, r0)`
        x0 = normal[1] * r2 - normal[2] * r1
        x1 = normal[2] * r0 - normal[0] * r2
        x2 = normal[0] * r1 - normal[1] * r0
        for k in range(n + 1):
            a = u[k] * sweep
            ca, sa = np.cos(a), np.sin(a)
            T[k, 0, 3] = centre[0] + ca * r0 + sa * x0
            T[k, 1, 3] = centre[1] + ca * r1 + sa * x1
            T[k, 2, 3] = centre[2] + ca * r2 + sa * x2
    else:
        for k in range(n + 1):
            for c in range(3):
                T[k, c, 3] = start[c] + u[k] * (end[c] - start[c])
    for k in range(n + 1):
        T[k, 3, 3] = 1.0
    return u, T
