"""The RV-2AJ's closed-form IK for many tool poses at once (every branch, no choice made).

Why: a LINEAR or CIRCULAR move is turned into joints pose by pose, each solution taken
nearest the previous one (`cartesian_follow.follow_poses`). The choice is sequential, but
the candidates are not: computing every branch of every pose in one vectorised pass leaves
only a cheap nearest-neighbour pick per pose. The arithmetic is that of `RV2AJ.ik` and
`RV2AJ.nearest_reachable_orientation` (for a tool on the flange axis, where the projection
into the arm plane is one exact rotation); rows it cannot answer the same way (on the J1
axis, or a projection that does not settle in one step) are flagged for the scalar IK.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from assistant.robot_model import JointLimits
from assistant.transforms import axis_angle_batch, rot_y_batch, rot_z_batch

Array = np.ndarray


@dataclass(frozen=True)
class PoseCandidates:
    """Per pose (M) every analytic solution (K per pose) and what `ik` would say about it."""

    joints: Array  # (M, K, 5)
    #: Reachable and inside the joint limits: what `ik` would return as solutions.
    valid: Array  # (M, K)
    #: The orientation was turned into the arm plane first (`ik` fails with ORIENTATION).
    projected: Array  # (M,)
    #: Angle of that turn (rad), 0 where none.
    angle: Array  # (M,)
    #: False where the batch cannot stand in for `ik` (use the scalar IK for that pose).
    exact: Array  # (M,)

    def answers(self, i: int, project_orientation: bool = True) -> bool:
        """Whether pose i has a solution here that `ik` would give (turned into the arm
        plane first only if allowed); otherwise ask `ik`, also for its reason."""
        return bool(self.exact[i] and self.valid[i].any()
                    and (project_orientation or not self.projected[i]))

    def nearest(self, i: int, q: Array) -> Array:
        """The solution of pose i nearest q (as `IKResult.best`)."""
        C = self.joints[i][self.valid[i]]
        return C[int(np.argmin(np.linalg.norm(C - q, axis=1)))]


def pose_candidates(T_base_tool: Array, T_flange_tool: Array, T_tool_flange: Array,
                    limits: JointLimits, plane_tolerance: float,
                    lengths: tuple[float, float, float, float], R0: Array,
                    ) -> PoseCandidates | None:
    """All IK branches of the RV-2AJ for poses (M, 4, 4); None for a tool off the flange axis.

    Args:
        T_base_tool: requested tool poses in the base frame.
        T_flange_tool: the tool (its TCP must lie on the flange axis).
        T_tool_flange: its inverse, as the robot holds it (the same bits as `ik` uses).
        limits: joint limits (a solution outside them is not valid).
        plane_tolerance: largest distance of the approach vector from the arm plane that
            needs no projection (as `RV2AJConfig.plane_tolerance`).
        lengths: L1, L2, L3, L6 (m).
        R0: flange orientation at q = 0.
    """
    if abs(T_flange_tool[0, 3]) > 1e-12 or abs(T_flange_tool[1, 3]) > 1e-12:
        return None
    L1, L2, L3, L6 = lengths
    T = np.asarray(T_base_tool, dtype=float)
    m = len(T)
    p_tcp = T[:, :3, 3]
    rxy_tcp = np.hypot(p_tcp[:, 0], p_tcp[:, 1])
    exact = rxy_tcp >= 1e-9

    # Orientation into the vertical plane through J1 and the TCP (one minimal rotation).
    R_ft = T_flange_tool[:3, :3]
    Rf = T[:, :3, :3] @ T_tool_flange[:3, :3]
    with np.errstate(invalid="ignore", divide="ignore"):
        n = np.stack([-p_tcp[:, 1], p_tcp[:, 0], np.zeros(m)], axis=1) / rxy_tcp[:, None]
    a = Rf[:, :, 2]
    off = np.einsum("ij,ij->i", a, n)
    projected = exact & (np.abs(off) > plane_tolerance)
    angle = np.zeros(m)
    R_tool = T[:, :3, :3].copy()
    if projected.any():
        i = np.nonzero(projected)[0]
        a_i, n_i = a[i], n[i]
        a_proj = a_i - off[i, None] * n_i
        flat = np.linalg.norm(a_proj, axis=1) < 1e-9
        a_proj[flat] = (0.0, 0.0, -1.0)
        a_proj /= np.linalg.norm(a_proj, axis=1)[:, None]
        axis = np.cross(a_i, a_proj)
        s = np.linalg.norm(axis, axis=1)
        ang = np.arcsin(np.clip(s, -1.0, 1.0))
        R_fix = axis_angle_batch(axis, ang)
        R_tool[i] = (R_fix @ Rf[i]) @ R_ft[None]
        # The scalar version checks the plane again and would turn once more if needed.
        a_new = (R_tool[i] @ T_tool_flange[:3, :3])[:, :, 2]
        settled = np.abs(np.einsum("ij,ij->i", a_new, n_i)) <= plane_tolerance
        exact[i[~settled]] = False
        tr = np.einsum("kij,kij->k", R_tool[i], T[i, :3, :3])  # trace(R_new^T R)
        angle[i] = np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0))

    # Flange poses and the branches of `RV2AJ._ik_flange_all`.
    p = p_tcp + R_tool @ T_tool_flange[:3, 3]
    R = R_tool @ T_tool_flange[:3, :3]
    a = R[:, :, 2]
    exact &= np.hypot(p[:, 0], p[:, 1]) >= 1e-9
    base = np.arctan2(p[:, 1], p[:, 0])
    w = p - L6 * a
    branches, reach = [], []
    for q1 in (base, base + np.pi):
        c1, s1 = np.cos(q1), np.sin(q1)
        s_pitch = np.arctan2(a[:, 0] * c1 + a[:, 1] * s1, a[:, 2])
        rw = w[:, 0] * c1 + w[:, 1] * s1
        zw = w[:, 2] - L1
        D = (rw * rw + zw * zw - L2 * L2 - L3 * L3) / (2.0 * L2 * L3)
        ok = (D <= 1.0 + 1e-12) & (D >= -1.0 - 1e-12)
        D = np.clip(D, -1.0, 1.0)
        # q6 from A = Rz(q1) Ry(s) R0 and A^T R (columns 0 and 1 of A against R's column 0).
        A = rot_z_batch(q1) @ rot_y_batch(s_pitch) @ R0[None]
        q6 = np.arctan2(np.einsum("ij,ij->i", A[:, :, 1], R[:, :, 0]),
                        np.einsum("ij,ij->i", A[:, :, 0], R[:, :, 0]))
        for q3 in (np.arccos(D), -np.arccos(D)):
            q2 = np.arctan2(rw, zw) - np.arctan2(L3 * np.sin(q3), L2 + L3 * np.cos(q3))
            q5 = s_pitch - q2 - q3
            branches.append(np.stack([q1, q2, q3, q5, q6], axis=1))
            reach.append(ok)
    Q = (np.stack(branches, axis=1) + np.pi) % (2 * np.pi) - np.pi  # (M, 4, 5) wrapped
    reach_ok = np.stack(reach, axis=1)
    # The 2 pi copies a joint's range allows (only joints reaching past +-pi have any), in
    # the order of `_angle_variants`.
    multi = np.nonzero((limits.upper >= np.pi - 1e-9) | (limits.lower <= -np.pi + 1e-9))[0]
    combos = list(itertools.product((0.0, -2 * np.pi, 2 * np.pi), repeat=len(multi)))
    S = np.zeros((len(combos), Q.shape[-1]))  # (V, 5)
    S[:, multi] = combos
    joints = (Q[:, :, None, :] + S[None, None]).reshape(m, -1, Q.shape[-1])
    valid = (np.repeat(reach_ok, len(S), axis=1)
             & limits.contains_batch(joints))
    return PoseCandidates(joints, valid, projected, angle, exact)

