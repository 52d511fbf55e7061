"""Numeric IK of a `URDFRobot`: damped least squares on pinocchio's frame Jacobian, with
restarts, joint limits and wrapping into them; distinct solutions or a reason (mixed into
`URDFRobot`)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from assistant.robots.model import (
    IKFailure,
    IKResult,
)
from assistant.transforms import orthonormalized, rotation_angle

Array = np.ndarray


class DLSInverseKinematics:
    """The IK of `URDFRobot` (its methods run on the robot's pinocchio model and data)."""

    # ------------------------------------------------------------------ inverse kinematics
    def ik(
        self,
        T_base_tool: Array,
        seed: Array | None = None,
        *,
        position_only: bool = False,
        max_solutions: int | None = None,
    ) -> IKResult:
        """Damped least squares from the seed, then seeded random restarts; distinct solutions.

        Every iterate is clamped into the joint limits, so each solution is within limits.
        Failure reasons: REACH (farther than the summed link lengths), JOINT_LIMIT (solvable
        only with a joint outside its range), ORIENTATION (fewer than 6 joints: the position
        is reachable but not with this orientation), NO_CONVERGENCE. The best pose reached
        is offered in `nearest_T_base_tool`.
        """
        T = np.asarray(T_base_tool, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"{self.name}: T_base_tool must be a finite 4x4 transform")
        if not position_only:
            try:
                T = orthonormalized(T)
            except ValueError as exc:
                raise ValueError(f"{self.name}: {exc}") from None
        st = self.ik_settings
        want = max_solutions or st.max_solutions
        T_root_target = T if self._base_is_root else self.T_root_base @ T
        lo, hi = self.limits.lower, self.limits.upper
        home = np.clip(np.zeros(self.dof), lo, hi)
        first = np.clip(self._check_q(seed), lo, hi) if seed is not None else home
        rng = np.random.default_rng(st.rng_seed)
        starts = [first] + [rng.uniform(lo, hi) for _ in range(st.restarts)]
        if self.dof > 6:
            # redundant: the middle of the ranges before random restarts (they find
            # contorted postures a 7-axis arm has plenty of)
            starts.insert(1, 0.5 * (lo + hi))
        dist = float(np.linalg.norm(T[:3, 3] - self._reach_centre))
        out_of_reach = dist > self._reach + st.position_tolerance
        if out_of_reach:
            starts = starts[:2]

        sols: list[Array] = []
        best_q, best_err = first, np.inf
        k = 0
        while k < len(starts):
            q, ok, err = self._dls(T_root_target, starts[k], position_only, clamp=True)
            k += 1
            if ok:
                q = self._nearest_turns(q, first)
            if err < best_err:
                best_q, best_err = q, err
            if ok and all(np.linalg.norm(q - s) > st.distinct for s in sols):
                sols.append(q)
                if len(sols) >= want:
                    break
            if k == len(starts) and not sols and not out_of_reach and \
                    len(starts) == 1 + st.restarts:
                starts += [rng.uniform(lo, hi) for _ in range(st.extra_restarts)]
        ref = first if seed is not None else home
        if sols:
            sols.sort(key=lambda s: float(np.linalg.norm(s - ref)))
            return IKResult(sols)
        nearest = self.fk(best_q)
        target = "point" if position_only else "pose"
        if out_of_reach:
            return IKResult([], IKFailure.REACH,
                            f"{target} at {dist * 1000:.0f} mm from the first joint is beyond "
                            f"the arm's reach ({self._reach * 1000:.0f} mm)", nearest)
        inside, free = self._solve_unlimited(T_root_target, starts[:1 + st.restarts],
                                             position_only)
        if inside is not None:
            return IKResult([inside])
        if free is not None:
            return IKResult([], IKFailure.JOINT_LIMIT,
                            f"no solution within the joint limits was found for this {target}; "
                            "without limits it is reachable with "
                            + ", ".join(self.limits.violations(free, self.joint_names)),
                            nearest)
        if not position_only and self.dof < 6:
            for q0 in starts[:4]:
                if self._dls(T_root_target, q0, True, clamp=True)[1]:
                    return IKResult([], IKFailure.ORIENTATION,
                                    f"the {self.dof}-axis arm reaches this point but not with "
                                    "this orientation; the nearest pose found is offered",
                                    nearest)
        return IKResult([], IKFailure.NO_CONVERGENCE,
                        f"no joint configuration found for this {target} after "
                        f"{len(starts)} starts; the nearest pose found is offered", nearest)

    def ik_near(self, T_base_tool: Array, seed: Array) -> Array | None:
        """The solution the damped least squares reaches from `seed` (within the limits), or
        None if it does not converge. Why: a Cartesian line walked in small steps needs the
        solution next to the previous one, not `ik`'s distinct solutions from a dozen
        restarts (9x the time on a UR5)."""
        T = np.asarray(T_base_tool, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            return None
        T_root_target = T if self._base_is_root else self.T_root_base @ T
        lo, hi = self.limits.lower, self.limits.upper
        q, ok, _ = self._dls(T_root_target, np.clip(self._check_q(seed), lo, hi), False,
                             clamp=True)
        return q if ok else None

    def _solve_unlimited(self, T_root_target: Array, starts: list[Array],
                         position_only: bool) -> tuple[Array | None, Array | None]:
        """Solve ignoring limits: (a solution that is inside after 2 pi shifts, or else the
        first solution found outside them); (None, None) if none converges."""
        outside = None
        for q0 in starts:
            q, ok, _ = self._dls(T_root_target, q0, position_only, clamp=False)
            if ok:
                q = self._wrap_into_limits(q)
                if self.limits.contains(q):
                    return q, None  # reachable after all: the clamped runs were unlucky
                if outside is None:
                    outside = q
        return None, outside

    def _nearest_turns(self, q: Array, ref: Array) -> Array:
        """q with each revolute joint turned by whole turns (within its limits) to the value
        nearest `ref`: the same pose. Why: a UR joint spans two turns, and a solution the
        search reached from a random start could sit a turn away from the seed - a taught
        location the arm then winds 240 degrees round to reach from where it stands."""
        q = q.copy()
        lo, hi = self.limits.lower, self.limits.upper
        for k, j in enumerate(self._chain_joints):
            if j.type == "prismatic":
                continue
            turns = np.round((ref[k] - q[k]) / (2 * np.pi))
            for t in (turns, turns - np.sign(turns)):
                v = q[k] + 2 * np.pi * t
                if t != 0 and lo[k] - 1e-9 <= v <= hi[k] + 1e-9:
                    q[k] = min(max(v, lo[k]), hi[k])
                    break
        return q

    def _wrap_into_limits(self, q: Array) -> Array:
        q = q.copy()
        for k, j in enumerate(self._chain_joints):
            if j.type == "prismatic":
                continue
            for shift in (0.0, -2 * np.pi, 2 * np.pi, -4 * np.pi, 4 * np.pi):
                v = q[k] + shift
                if self.limits.lower[k] - 1e-9 <= v <= self.limits.upper[k] + 1e-9:
                    q[k] = v
                    break
        return q

    def _dls(self, T_root_target: Array, q0: Array, position_only: bool, *, clamp: bool
             ) -> tuple[Array, bool, float]:
        """One damped-least-squares run: (q, converged, weighted error of the best iterate)."""
        st = self.ik_settings
        model, data, fid = self._model, self._data(), self._tcp_fid
        lam2 = st.damping ** 2
        oMdes = pin.SE3(T_root_target[:3, :3], T_root_target[:3, 3])
        q = q0.copy()
        best_q, best_err = q.copy(), np.inf
        lo, hi = self.limits.lower, self.limits.upper
        eye = np.eye(3 if position_only else 6)
        stall = 0
        for _ in range(st.max_iterations):
            qp = self.to_pinocchio_q(q)
            pin.computeJointJacobians(model, data, qp)
            pin.updateFramePlacement(model, data, fid)
            oMf = data.oMf[fid]
            dp = oMdes.translation - oMf.translation
            pos_err = float(np.linalg.norm(dp))
            if position_only:
                rot_err = 0.0
                J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
                e = dp
            else:
                iMd = oMf.actInv(oMdes)
                rot_err = rotation_angle(iMd.rotation)
                # e = log6(T_tcp^-1 T_target) in the TCP frame; de/dq = -Jlog6(iMd^-1) J_local
                # (pinocchio's own IK example), so dq = +J^T (J J^T + lambda^2)^-1 e below.
                e = pin.log6(iMd).vector
                J = pin.Jlog6(iMd.inverse()) @ pin.getFrameJacobian(model, data, fid, pin.LOCAL)
            err = pos_err + 0.1 * rot_err
            if err < best_err - 1e-12:
                best_q, best_err, stall = q.copy(), err, 0
            else:
                stall += 1
                if stall > 20:
                    break
            if pos_err < st.position_tolerance and rot_err < st.orientation_tolerance:
                return q, True, err
            # Active set: a joint on a limit that the step would push further out is taken
            # out of the solve, so the others make the progress (plain clamping stalls).
            damp = min(1.0, float(np.linalg.norm(e)) / st.damping_error)
            free = np.ones(self.dof, dtype=bool)
            for _ in range(3):
                Jf = J * free
                dq = Jf.T @ np.linalg.solve(Jf @ Jf.T + lam2 * damp * eye, e)
                if not clamp:
                    break
                blocked = ((q <= lo) & (dq < 0)) | ((q >= hi) & (dq > 0))
                if not np.any(blocked & free):
                    break
                free &= ~blocked
            if self.dof > e.shape[0] and clamp:
                # redundant arm, in the Jacobian's null space: stay near the start (a seeded
                # solve answers next to its seed) and push out of the outer 3 % of each
                # range (the 7th axis of a Panda keeps away from its limits instead of
                # wandering into them along a Cartesian line)
                N = np.eye(self.dof) - np.linalg.pinv(J, rcond=1e-4) @ J
                margin = 0.03 * (hi - lo)
                push = np.maximum(lo + margin - q, 0.0) - np.maximum(q - (hi - margin), 0.0)
                dq = dq + N @ (0.1 * (q0 - q) + 0.3 * push)
            step = float(np.max(np.abs(dq)))
            if step > st.max_step:
                dq *= st.max_step / step
            q = q + dq
            if clamp:
                q = np.clip(q, lo, hi)
        return best_q, False, best_err
