"""The arm as capsules against a learnt region's spheres (compiled, numba).

Why: a re-plan asks "does the arm at this posture come near a learnt region?" for thousands
of postures; FCL on a mesh arm against a few hundred small spheres answered that in ~25 ms a
batch (a joint-space search spent 7 s of a re-plan there). The fast model's capsules
(`collision.fast_model`: each contains its link's shapes, padded) against sphere centres
is a point-to-segment distance per pair: conservative - what it calls clear is clear of the
real shapes too - and one compiled pass. Learning (`contact_region`) and checking use the
same capsules, so a region learnt clear of a posture is checked clear of it.
"""

from __future__ import annotations

import numpy as np

from assistant.collision.fast_model import fast_robot
from assistant.kernels.lazy import kernel
from assistant.robots.model import Robot, ShapeKind

Array = np.ndarray


class CapsuleArm:
    """The moving links' capsules of one robot, posed in its base frame per posture."""

    def __init__(self, robot: Robot):
        fast = fast_robot(robot)
        if fast is None:
            raise ValueError(f"{robot.name}: no capsule model (no revolute chain)")
        self.fast = fast
        a, b, r, link = [], [], [], []
        for k, lk in enumerate(fast.links):
            if k < 1:  # the fixed base: never checked against obstacles (as `checker`)
                continue
            for s in lk.collision:
                h = s.size[1] / 2.0 if s.kind == ShapeKind.CAPSULE else 0.0
                T = s.T_link_shape
                a.append(T @ np.array([0.0, 0.0, -h, 1.0]))
                b.append(T @ np.array([0.0, 0.0, h, 1.0]))
                r.append(float(s.size[0]))
                link.append(k)
        self._a = np.array(a)  # (C, 4) in the link's frame
        self._b = np.array(b)
        self.radii = np.ascontiguousarray(r, dtype=float)
        self._link = np.array(link, dtype=np.int64)
        self._G = np.asarray(fast.G, dtype=float)

    def segments(self, Q: Array) -> tuple[Array, Array]:
        """Capsule axis ends (N, C, 3) each, in the robot base frame."""
        F = self.fast.batch_link_poses(np.atleast_2d(np.asarray(Q, dtype=float)))
        F = np.matmul(self._G, F[:, self._link])  # (N, C, 4, 4)
        R, t = F[..., :3, :3], F[..., :3, 3]
        A = np.matmul(R, self._a[:, :3, None])[..., 0] + t
        B = np.matmul(R, self._b[:, :3, None])[..., 0] + t
        return np.ascontiguousarray(A), np.ascontiguousarray(B)

    def near_rows(self, Q: Array, centres: Array, reach: float) -> Array:
        """Bool per row of Q: some capsule within `reach` of some centre (beyond its radius)."""
        if not len(centres) or not len(np.atleast_2d(Q)):
            return np.zeros(len(np.atleast_2d(Q)), dtype=bool)
        A, B = self.segments(Q)
        return rows_near(A, B, self.radii, np.ascontiguousarray(centres, dtype=float),
                         float(reach))

    def near_centres(self, Q: Array, centres: Array, reach: float) -> Array:
        """Bool per centre: within `reach` of some capsule at some row of Q."""
        if not len(centres) or not len(np.atleast_2d(Q)):
            return np.zeros(len(centres), dtype=bool)
        A, B = self.segments(Q)
        return centres_near(A, B, self.radii, np.ascontiguousarray(centres, dtype=float),
                            float(reach))


@kernel(cache=True, inline="always")
def _gap(ax: float, ay: float, az: float, bx: float, by: float, bz: float,
         px: float, py: float, pz: float) -> float:
    """Distance from p to the segment a-b."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    uu = ux * ux + uy * uy + uz * uz
    t = 0.0
    if uu > 1e-18:
        t = (wx * ux + wy * uy + wz * uz) / uu
        t = min(1.0, max(0.0, t))
    dx, dy, dz = wx - t * ux, wy - t * uy, wz - t * uz
    return np.sqrt(dx * dx + dy * dy + dz * dz)


@kernel(cache=True)
def rows_near(A: Array, B: Array, radii: Array, centres: Array, reach: float) -> Array:
    """Per row: some capsule (A, B, radii) within `reach` of some centre."""
    n, c = A.shape[0], A.shape[1]
    m = centres.shape[0]
    lo = centres[0].copy()
    hi = centres[0].copy()
    for j in range(m):
        for d in range(3):
            lo[d] = min(lo[d], centres[j, d])
            hi[d] = max(hi[d], centres[j, d])
    mid = (lo + hi) / 2.0
    half = np.sqrt(((hi - lo) ** 2).sum()) / 2.0
    out = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        for k in range(c):
            lim = radii[k] + reach
            g = _gap(A[i, k, 0], A[i, k, 1], A[i, k, 2], B[i, k, 0], B[i, k, 1], B[i, k, 2],
                     mid[0], mid[1], mid[2])
            if g > lim + half:
                continue
            for j in range(m):
                if _gap(A[i, k, 0], A[i, k, 1], A[i, k, 2], B[i, k, 0], B[i, k, 1],
                        B[i, k, 2], centres[j, 0], centres[j, 1], centres[j, 2]) < lim:
                    out[i] = True
                    break
            if out[i]:
                break
    return out


@kernel(cache=True)
def centres_near(A: Array, B: Array, radii: Array, centres: Array, reach: float) -> Array:
    """Per centre: some capsule at some row within `reach` of it."""
    n, c = A.shape[0], A.shape[1]
    out = np.zeros(centres.shape[0], dtype=np.bool_)
    for j in range(centres.shape[0]):
        for i in range(n):
            for k in range(c):
                if _gap(A[i, k, 0], A[i, k, 1], A[i, k, 2], B[i, k, 0], B[i, k, 1],
                        B[i, k, 2], centres[j, 0], centres[j, 1],
                        centres[j, 2]) < radii[k] + reach:
                    out[j] = True
                    break
            if out[j]:
                break
    return out
