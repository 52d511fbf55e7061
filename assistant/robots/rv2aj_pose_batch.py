"""The RV-2AJ's closed-form IK for many tool poses at once (every branch, no choice made).

Why: a LINEAR or CIRCULAR move is turned into joints pose by pose, each solution taken
nearest the previous one (`cartesian_follow.follow_poses`). The choice is sequential, but
the candidates are not: computing every branch of every pose in one vectorised pass leaves
only a cheap nearest-neighbour pick per pose. The arithmetic is that of `RV2AJ.ik` and
`RV2AJ.nearest_reachable_orientation` (for a tool on the flange axis, where the projection
into the arm plane is one exact rotation); rows it cannot answer the same way (on the J1
axis, or a projection that does not settle in one step) are flagged for the scalar IK.

Serves (the user-felt figure): the Cartesian moves' IK: 0.3 s in Python in the thesis run.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from assistant.kernels.helpers import axis_angle3_into, mm3_into, within_limits, wrap_pi
from assistant.kernels.lazy import kernel
from assistant.robots.model import JointLimits

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
    #: Per arm configuration (J1 side x elbow, 4 per pose): the wrist centre is in reach.
    reach: Array  # (M, 4)

    def answers(self, i: int, project_orientation: bool = True) -> bool:
        """Whether pose i has a solution here that `ik` would give (turned into the arm
        plane first only if allowed); otherwise ask `ik`, also for its reason."""
        return bool(self.exact[i] and self.valid[i].any()
                    and (project_orientation or not self.projected[i]))

    def reason(self, i: int, T_base_tool: Array, limits: JointLimits,
               names: list[str]) -> str:
        """Why pose i (exact, no valid solution) has no IK solution, in `ik`'s words
        (its reach failure, or each arm configuration's broken limits for the first two):
        the scalar IK would only repeat the batch's arithmetic to say it."""
        if not self.reach[i].any():
            return out_of_reach_message(T_base_tool)
        per = self.joints.shape[1] // 4  # the 2 pi copies of each configuration
        # `RV2AJ._ik_flange_all`'s configurations in its order, a straight elbow once
        configs = [self.joints[i, b * per] for b in range(4) if self.reach[i, b]
                   and not (b % 2 and self.joints[i, b * per, 2] == 0.0)]
        return joint_limit_message(configs, limits, names)

    def nearest(self, i: int, q: Array) -> Array:
        """The solution of pose i nearest q (as `IKResult.best`)."""
        C = self.joints[i][self.valid[i]]
        return C[int(np.argmin(np.linalg.norm(C - q, axis=1)))]


def out_of_reach_message(T_base_tool: Array) -> str:
    """`RV2AJ.ik`'s reason when the wrist cannot reach the pose (the batch gives the same)."""
    return (f"target at {np.linalg.norm(T_base_tool[:3, 3]) * 1000:.0f} mm from the base "
            "is out of the arm's reach for this orientation")


def joint_limit_message(configs: list[Array], limits: JointLimits, names: list[str]) -> str:
    """`RV2AJ.ik`'s reason when every arm configuration (`configs`, in its order) breaks a
    limit: the limits the first two break."""
    detail = "; ".join(", ".join(limits.violations(q, names)) for q in configs[:2])
    return f"every arm configuration for this pose breaks a joint limit ({detail})"


@dataclass(frozen=True)
class PoseBatchModel:
    """The constants of `pose_candidates` for one robot, laid out once: a LINEAR or CIRCULAR
    move asks for its poses' candidates, and building these per call (the 2 pi copies'
    table among them) would cost ~8 us of Python each time, a third of the compiled pass."""

    R_ft: Array  # the tool's rotation on the flange (3, 3)
    T_tf: Array  # its inverse pose, as the robot holds it (4, 4)
    lower: Array
    upper: Array
    plane_tolerance: float
    lengths: Array  # L1, L2, L3, L6 (m)
    R0: Array  # flange orientation at q = 0
    #: The 2 pi copies a joint's range allows (only joints reaching past +-pi have any),
    #: in the order of `_angle_variants` (V, 5).
    S: Array


def pose_batch_model(T_flange_tool: Array, T_tool_flange: Array, limits: JointLimits,
                     plane_tolerance: float, lengths: tuple[float, float, float, float],
                     R0: Array) -> PoseBatchModel | None:
    """`pose_candidates`' constants; None for a tool off the flange axis.

    Args:
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
    multi = np.nonzero((limits.upper >= np.pi - 1e-9) | (limits.lower <= -np.pi + 1e-9))[0]
    combos = list(itertools.product((0.0, -2 * np.pi, 2 * np.pi), repeat=len(multi)))
    S = np.zeros((len(combos), 5))  # (V, 5)
    S[:, multi] = combos
    return PoseBatchModel(np.ascontiguousarray(T_flange_tool[:3, :3], dtype=float),
                          np.ascontiguousarray(T_tool_flange, dtype=float),
                          np.ascontiguousarray(limits.lower, dtype=float),
                          np.ascontiguousarray(limits.upper, dtype=float),
                          float(plane_tolerance), np.array(lengths, dtype=float),
                          np.ascontiguousarray(R0, dtype=float), S)


def pose_candidates(T_base_tool: Array, model: PoseBatchModel) -> PoseCandidates:
    """All IK branches of the RV-2AJ for the tool poses T_base_tool (M, 4, 4), in the base
    frame (`model`: `pose_batch_model`)."""
    joints, valid, projected, angle, exact, reach = _candidates(
        np.ascontiguousarray(T_base_tool, dtype=float), model.R_ft, model.T_tf, model.lower,
        model.upper, model.plane_tolerance, model.lengths, model.R0, model.S)
    return PoseCandidates(joints, valid, projected, angle, exact, reach)


@kernel(cache=True)
def _candidates(T: Array, R_ft: Array, T_tf: Array, lower: Array, upper: Array, tol: float,
                lengths: Array, R0: Array, S: Array) -> tuple:
    """`pose_candidates` pose by pose, one compiled loop: (joints (M, 4 V, 5), valid,
    projected, angle, exact, reach (M, 4)). As numpy the ~60 array expressions cost ~0.4 ms
    per LINEAR or CIRCULAR move whatever its length; the arithmetic is a few microseconds."""
    L1, L2, L3, L6 = lengths[0], lengths[1], lengths[2], lengths[3]
    m = T.shape[0]
    V = S.shape[0]
    joints = np.empty((m, 4 * V, 5))
    valid = np.zeros((m, 4 * V), dtype=np.bool_)
    projected = np.zeros(m, dtype=np.bool_)
    angle = np.zeros(m)
    exact = np.zeros(m, dtype=np.bool_)
    reach = np.zeros((m, 4), dtype=np.bool_)
    R_tf = T_tf[:3, :3]
    # scratch, filled per pose (new small arrays per pose would be ~20 allocations each)
    Rf, R_tool, R = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    Rz, Ry, RzRy, A = np.zeros((3, 3)), np.zeros((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    axis, K, KK, R_fix, M = (np.empty(3), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)),
                             np.empty((3, 3)))
    q = np.empty(5)
    for i in range(m):
        Rt = T[i, :3, :3]
        px, py, pz = T[i, 0, 3], T[i, 1, 3], T[i, 2, 3]
        rxy = np.hypot(px, py)
        ex = rxy >= 1e-9
        # Orientation into the vertical plane through J1 and the TCP (one minimal rotation).
        mm3_into(Rt, R_tf, Rf)
        R_tool[:] = Rt
        if ex:
            n0, n1 = -py / rxy, px / rxy
            off = Rf[0, 2] * n0 + Rf[1, 2] * n1 + Rf[2, 2] * 0.0
            if abs(off) > tol:
                projected[i] = True
                # the turn, element for element as vectors: a_proj = a - off n (n's z is
                # 0), normalised; axis = a x a_proj (np.cross's products)
                a0, a1, a2 = Rf[0, 2], Rf[1, 2], Rf[2, 2]
                p0, p1, p2 = a0 - off * n0, a1 - off * n1, a2 - off * 0.0
                na = np.sqrt(p0 ** 2 + p1 ** 2 + p2 ** 2)
                if na < 1e-9:
                    p0, p1, p2 = 0.0, 0.0, -1.0
                    na = 1.0
                p0, p1, p2 = p0 / na, p1 / na, p2 / na
                axis[0], axis[1], axis[2] = a1 * p2 - a2 * p1, a2 * p0 - a0 * p2, a0 * p1 - a1 * p0
                s = np.sqrt(axis[0] ** 2 + axis[1] ** 2 + axis[2] ** 2)
                axis_angle3_into(axis, s, np.arcsin(min(max(s, -1.0), 1.0)), K, KK, R_fix)
                mm3_into(R_fix, Rf, M)
                mm3_into(M, R_ft, R_tool)
                # The scalar version checks the plane again and would turn once more
                # (`mm3(R_tool, R_tf)`'s third column).
                t0, t1, t2 = R_tf[0, 2], R_tf[1, 2], R_tf[2, 2]
                c0 = R_tool[0, 0] * t0 + R_tool[0, 1] * t1 + R_tool[0, 2] * t2
                c1 = R_tool[1, 0] * t0 + R_tool[1, 1] * t1 + R_tool[1, 2] * t2
                c2 = R_tool[2, 0] * t0 + R_tool[2, 1] * t1 + R_tool[2, 2] * t2
                if not abs(c0 * n0 + c1 * n1 + c2 * 0.0) <= tol:
                    ex = False
                # M = R_tool^T Rt: angle = atan2(|axis part|, trace - 1), not arccos of
                # the trace (which loses half the digits at small angles)
                tr = 0.0
                for r in range(3):
                    tr += R_tool[0, r] * Rt[0, r] + R_tool[1, r] * Rt[1, r] + \
                        R_tool[2, r] * Rt[2, r]
                v0 = v1 = v2 = 0.0
                for r in range(3):
                    v0 += R_tool[r, 2] * Rt[r, 1] - R_tool[r, 1] * Rt[r, 2]
                    v1 += R_tool[r, 0] * Rt[r, 2] - R_tool[r, 2] * Rt[r, 0]
                    v2 += R_tool[r, 1] * Rt[r, 0] - R_tool[r, 0] * Rt[r, 1]
                angle[i] = np.arctan2(np.sqrt(v0 * v0 + v1 * v1 + v2 * v2), tr - 1.0)
        # Flange pose and the branches of `RV2AJ._ik_flange_all`.
        p0 = px + (R_tool[0, 0] * T_tf[0, 3] + R_tool[0, 1] * T_tf[1, 3]
                   + R_tool[0, 2] * T_tf[2, 3])
        p1 = py + (R_tool[1, 0] * T_tf[0, 3] + R_tool[1, 1] * T_tf[1, 3]
                   + R_tool[1, 2] * T_tf[2, 3])
        p2 = pz + (R_tool[2, 0] * T_tf[0, 3] + R_tool[2, 1] * T_tf[1, 3]
                   + R_tool[2, 2] * T_tf[2, 3])
        mm3_into(R_tool, R_tf, R)
        a0, a1, a2 = R[0, 2], R[1, 2], R[2, 2]
        exact[i] = ex and np.hypot(p0, p1) >= 1e-9
        base = np.arctan2(p1, p0)
        w0, w1, w2 = p0 - L6 * a0, p1 - L6 * a1, p2 - L6 * a2
        b = 0
        for q1 in (base, base + np.pi):
            c1, s1 = np.cos(q1), np.sin(q1)
            s_pitch = np.arctan2(a0 * c1 + a1 * s1, a2)
            rw = w0 * c1 + w1 * s1
            zw = w2 - L1
            D = (rw * rw + zw * zw - L2 * L2 - L3 * L3) / (2.0 * L2 * L3)
            ok = D <= 1.0 + 1e-12 and D >= -1.0 - 1e-12
            D = min(max(D, -1.0), 1.0)
            # q6 from A = Rz(q1) Ry(s) R0 and A^T R (A's columns 0 and 1 against R's 0).
            cs, ss = np.cos(s_pitch), np.sin(s_pitch)
            Rz[0, 0], Rz[0, 1], Rz[1, 0], Rz[1, 1], Rz[2, 2] = c1, -s1, s1, c1, 1.0
            Ry[0, 0], Ry[0, 2], Ry[1, 1], Ry[2, 0], Ry[2, 2] = cs, ss, 1.0, -ss, cs
            mm3_into(Rz, Ry, RzRy)
            mm3_into(RzRy, R0, A)
            q6 = np.arctan2(A[0, 1] * R[0, 0] + A[1, 1] * R[1, 0] + A[2, 1] * R[2, 0],
                            A[0, 0] * R[0, 0] + A[1, 0] * R[1, 0] + A[2, 0] * R[2, 0])
            elbow = np.arctan2(np.sqrt(max(0.0, (1.0 - D) * (1.0 + D))), D)  # not arccos
            for sign in (1.0, -1.0):
                q3 = sign * elbow
                q2 = np.arctan2(rw, zw) - np.arctan2(L3 * np.sin(q3), L2 + L3 * np.cos(q3))
                q5 = s_pitch - q2 - q3
                q[0], q[1], q[2], q[3], q[4] = q1, q2, q3, q5, q6
                reach[i, b] = ok
                for j in range(5):
                    q[j] = wrap_pi(q[j])
                for v in range(V):
                    k = b * V + v
                    for j in range(5):
                        joints[i, k, j] = q[j] + S[v, j]
                    valid[i, k] = ok and within_limits(joints[i, k], lower, upper)
                b += 1
    return joints, valid, projected, angle, exact, reach
