"""The RV-2AJ's TCP poses for many configurations: the closed form as one compiled loop.

The planners ask for a few to a few dozen poses at a time (a sweep of the elastic net, a
fitted arc), where the numpy form - two dozen array expressions - costs ~60 us per call
whatever the batch; the loop costs ~2 us plus ~0.1 us per pose, and is no slower on the
reachability table's 131k-configuration chunks.

Serves (the user-felt figure): the RV-2AJ's TCP poses in the net and the reachability table:
0.6 s in Python in the thesis run.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.lazy import kernel

Array = np.ndarray


def tcp_poses_numpy(Q: Array, arm: Array, BP: Array, BM: Array, BK: Array, v: Array,
                    tool_offset: bool) -> tuple[Array, Array]:
    """`tcp_poses` as whole-array numpy, the same arithmetic per row: the pending kernel's
    fallback (row by row in Python the reachability table's 100k+ rows cost ~7 s of a cold
    first run; as arrays ~0.1 s)."""
    L1, L2, L3, L6 = arm[0], arm[1], arm[2], arm[3]
    q1, q2, q3, q5, q6 = Q[:, 0], Q[:, 1], Q[:, 2], Q[:, 3], Q[:, 4]
    c1, s1 = np.cos(q1), np.sin(q1)
    a23 = q2 + q3
    s = a23 + q5
    cs, ss = np.cos(s), np.sin(s)
    c6, s6 = np.cos(q6), np.sin(q6)
    r = L2 * np.sin(q2) + L3 * np.sin(a23) + L6 * ss
    z = L2 * np.cos(q2) + L3 * np.cos(a23) + L6 * cs + L1
    b = c6[:, None, None] * BP + s6[:, None, None] * BM + BK  # (N, 3, 3)
    c0 = cs[:, None] * b[:, 0] + ss[:, None] * b[:, 2]
    rot = np.empty((Q.shape[0], 3, 3))
    rot[:, 0] = c1[:, None] * c0 - s1[:, None] * b[:, 1]
    rot[:, 1] = s1[:, None] * c0 + c1[:, None] * b[:, 1]
    rot[:, 2] = cs[:, None] * b[:, 2] - ss[:, None] * b[:, 0]
    pos = np.stack([r * c1, r * s1, z], axis=1)
    if tool_offset:
        pos = (rot[:, :, 0] * v[0] + rot[:, :, 1] * v[1] + rot[:, :, 2] * v[2]) + pos
    return pos, rot


@kernel(cache=True, fallback=tcp_poses_numpy)
def tcp_poses(Q: Array, arm: Array, BP: Array, BM: Array, BK: Array, v: Array,
              tool_offset: bool) -> tuple[Array, Array]:
    """(positions (N, 3), rotations (N, 3, 3)) of the TCP for joints Q (N, 5).

    p_flange = (r cos q1, r sin q1, z) with r, z the planar arm sums; the rotation is
    Rz(q1) Ry(s) B with s = q2 + q3 + q5 and B = R0 Rz(q6) R_ft = c6 BP + s6 BM + BK; the TCP
    sits at p_flange + R v (v = R_ft^T p_ft) when the tool has an offset. `arm` holds
    (L1, L2, L3, L6).
    """
    n = Q.shape[0]
    pos = np.empty((n, 3))
    rot = np.empty((n, 3, 3))
    for k in range(n):
        tcp_row(Q[k], arm, BP, BM, BK, v, tool_offset, pos[k], rot[k])
    return pos, rot


@kernel(cache=True, inline="always")
def tcp_row(q: Array, arm: Array, BP: Array, BM: Array, BK: Array, v: Array,
            tool_offset: bool, pos: Array, rot: Array) -> None:
    """`tcp_poses` of one configuration q (5,) into pos (3,) and rot (3, 3); also called
    per row by compiled planners (`trajectory.net_kernel`)."""
    L1, L2, L3, L6 = arm[0], arm[1], arm[2], arm[3]
    q1, q2, q3, q5, q6 = q[0], q[1], q[2], q[3], q[4]
    c1, s1 = np.cos(q1), np.sin(q1)
    a23 = q2 + q3
    s = a23 + q5
    cs, ss = np.cos(s), np.sin(s)
    c6, s6 = np.cos(q6), np.sin(q6)
    r = L2 * np.sin(q2) + L3 * np.sin(a23) + L6 * ss
    z = L2 * np.cos(q2) + L3 * np.cos(a23) + L6 * cs + L1
    for j in range(3):
        b0 = c6 * BP[0, j] + s6 * BM[0, j] + BK[0, j]
        b1 = c6 * BP[1, j] + s6 * BM[1, j] + BK[1, j]
        b2 = c6 * BP[2, j] + s6 * BM[2, j] + BK[2, j]
        c0 = cs * b0 + ss * b2
        rot[0, j] = c1 * c0 - s1 * b1
        rot[1, j] = s1 * c0 + c1 * b1
        rot[2, j] = cs * b2 - ss * b0
    if tool_offset:
        for i in range(3):
            pos[i] = rot[i, 0] * v[0] + rot[i, 1] * v[1] + rot[i, 2] * v[2]
        pos[0] += r * c1
        pos[1] += r * s1
        pos[2] += z
    else:
        pos[0] = r * c1
        pos[1] = r * s1
        pos[2] = z
