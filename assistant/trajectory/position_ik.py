"""Seeded, local position IK for many particles at once (the net's way back to joints).

The net moves TCP points by a few millimetres per iteration; what it needs back is the joint
configuration *next to the previous one* for each moved point, so the arm never jumps branch.
Damped least squares (Newton on the TCP position, numeric Jacobian from `batch_fk`) does
exactly that for any `Robot` and is vectorised over particles. The joints left free by a
position-only target (the tool pitch and roll of the 5-axis RV-2AJ; the whole orientation of
a 6-axis arm) are pulled in the Jacobian's null space towards a reference configuration, which
the net sets to its neighbours' mean: the tool pitch stays smooth along the path. Particles the
local method cannot place fall back to the robot's own analytic position-only IK, accepted
only when it lands next to the seed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.robots.model import Robot

Array = np.ndarray


@dataclass(frozen=True)
class PositionIKParams:
    #: Newton iteration budget per call; a few suffice for millimetre moves.
    max_iterations: int = 8
    #: Stop when every TCP is within this distance of its target (m).
    tolerance: float = 1e-7
    #: Damping (m) of the least-squares step: bounded steps near singularities.
    damping: float = 1e-3
    #: Largest joint change per Newton step (rad).
    max_step: float = 0.2
    #: Largest accepted distance from the seed (rad, per joint): beyond it a move is a jump.
    max_joint_jump: float = 0.25
    #: Fraction of the way (first order, once per call) the joints a position leaves free
    #: are pulled towards the reference configuration (0 = none).
    nullspace_gain: float = 0.5
    #: Finite-difference step for the Jacobian (rad).
    fd_step: float = 1e-7


@dataclass(frozen=True)
class PositionIKResult:
    joints: Array  # (N, dof); rows where `ok` is False hold the seed
    ok: Array  # (N,) bool
    residual: Array  # (N,) TCP position error (m)
    #: TCP positions of `joints` where `ok` (FK, computed anyway for the residual; the net
    #: reuses them instead of running FK again). None if not computed.
    points: Array | None = None


class BatchPositionIK:
    """`solve(targets, seeds, reference)`: joints next to the seeds that put the TCP on targets."""

    def __init__(self, robot: Robot, params: PositionIKParams | None = None):
        self.robot = robot
        self.params = params or PositionIKParams()

    def jacobians(self, Q: Array) -> tuple[Array, Array]:
        """TCP positions (N, 3) and position Jacobians (N, 3, dof) by forward differences."""
        n, dof = Q.shape
        h = self.params.fd_step
        stacked = np.repeat(Q[:, None, :], dof + 1, axis=1)
        stacked[:, 1:, :] += h * np.eye(dof)[None]
        P = np.asarray(self.robot.batch_fk(stacked.reshape(-1, dof)).positions, dtype=float)
        P = P.reshape(n, dof + 1, 3)
        J = (P[:, 1:, :] - P[:, :1, :]).transpose(0, 2, 1) / h
        return P[:, 0, :].copy(), J

    def solve(self, targets: Array, seeds: Array, reference: Array | None = None,
              ) -> PositionIKResult:
        p = self.params
        targets = np.atleast_2d(np.asarray(targets, dtype=float))
        seeds = np.atleast_2d(np.asarray(seeds, dtype=float))
        Q = seeds.copy()
        n, dof = Q.shape
        if n == 0:
            return PositionIKResult(Q, np.zeros(0, dtype=bool), np.zeros(0))
        fast = getattr(self.robot, "batch_position_ik", None)
        if fast is not None:
            out = fast(targets, seeds, reference, gain=p.nullspace_gain,
                       max_jump=p.max_joint_jump)
            if out is not None:
                Q, ok = out
                P = np.array(self.robot.batch_fk(Q).positions, dtype=float)
                err = np.linalg.norm(targets - P, axis=1)
                ok &= err <= p.tolerance * 10.0
                Q[~ok] = seeds[~ok]
                return PositionIKResult(Q, ok, err, P)
        lam2 = p.damping ** 2
        err = np.full(n, np.inf)
        active = np.ones(n, dtype=bool)
        pull = reference is not None and p.nullspace_gain > 0.0
        for it in range(p.max_iterations):
            idx = np.nonzero(active)[0]
            P, J = self.jacobians(Q[idx])
            e = targets[idx] - P
            err[idx] = np.linalg.norm(e, axis=1)
            # The first step always runs with a reference: it carries the null-space pull
            # (once per call), even for points already on target.
            done = err[idx] <= p.tolerance
            if it == 0 and pull:
                done[:] = False
            active[idx[done]] = False
            if not active.any():
                break
            keep = ~done
            idx, J, e = idx[keep], J[keep], e[keep]
            JJt = J @ J.transpose(0, 2, 1) + lam2 * np.eye(3)[None]
            Jt = J.transpose(0, 2, 1)
            dq = np.einsum("nij,nj->ni", Jt, np.linalg.solve(JJt, e[..., None])[..., 0])
            if it == 0 and pull:
                z = p.nullspace_gain * (reference[idx] - Q[idx])
                Jz = np.einsum("nij,nj->ni", J, z)
                z -= np.einsum("nij,nj->ni", Jt, np.linalg.solve(JJt, Jz[..., None])[..., 0])
                dq += z
            scale = np.maximum(1.0, np.abs(dq).max(axis=1) / p.max_step)
            Q[idx] += dq / scale[:, None]
        else:
            idx = np.nonzero(active)[0]
            if len(idx):
                P = np.asarray(self.robot.batch_fk(Q[idx]).positions, dtype=float)
                err[idx] = np.linalg.norm(targets[idx] - P, axis=1)
        ok = (err <= p.tolerance * 10.0) & (np.abs(Q - seeds).max(axis=1) <= p.max_joint_jump)
        ok &= self.robot.limits.contains_batch(Q)
        for i in np.nonzero(~ok)[0]:
            q = self._analytic(targets[i], seeds[i])
            if q is not None:
                Q[i], ok[i], err[i] = q, True, 0.0
        Q[~ok] = seeds[~ok]
        return PositionIKResult(Q, ok, err)

    def _analytic(self, target: Array, seed: Array) -> Array | None:
        """The robot's own position-only IK, if it lands within the jump limit of the seed."""
        T = np.eye(4)
        T[:3, 3] = target
        res = self.robot.ik(T, seed, position_only=True)
        if not res.ok:
            return None
        q = res.best(seed)
        if np.abs(q - seed).max() > self.params.max_joint_jump:
            return None
        return np.asarray(q, dtype=float)
