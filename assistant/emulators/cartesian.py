"""Cartesian straight lines and circular arcs as pose sequences (MVS/MVR, LIN/CIRC).

Positions are interpolated linearly (or on the circle through three points), orientations by
spherical linear interpolation from start to end, at about 2 mm per step; the emulators turn
each pose into joints with the model's inverse kinematics.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

Array = np.ndarray


def line_poses(T0: Array, T1: Array, step_m: float = 0.002, step_rad: float = 0.02,
                ) -> list[Array]:
    d = float(np.linalg.norm(T1[:3, 3] - T0[:3, 3]))
    rots = Rotation.from_matrix(np.stack([T0[:3, :3], T1[:3, :3]]))
    ang = float((rots[0].inv() * rots[1]).magnitude())
    n = max(1, int(np.ceil(max(d / step_m, ang / step_rad))))
    slerp = Slerp([0.0, 1.0], rots)
    out = []
    for f in np.arange(1, n + 1) / n:
        T = np.eye(4)
        T[:3, :3] = slerp([f]).as_matrix()[0]
        T[:3, 3] = T0[:3, 3] + f * (T1[:3, 3] - T0[:3, 3])
        out.append(T)
    return out


def arc_poses(Ta: Array, Tb: Array, Tc: Array, step_m: float = 0.002) -> list[Array]:
    """Poses on the circle through a, b, c (positions); orientation slerped from a to c."""
    a, b, c = Ta[:3, 3], Tb[:3, 3], Tc[:3, 3]
    u, v = b - a, c - a
    n = np.cross(u, v)
    nn = float(n @ n)
    if nn < 1e-14:
        raise ValueError("arc points are collinear")
    centre = a + (np.cross(n, u) * (v @ v) + np.cross(v, n) * (u @ u)) / (2.0 * nn)
    r = float(np.linalg.norm(a - centre))
    e1 = (a - centre) / r
    e2 = np.cross(n / np.sqrt(nn), e1)

    def angle(p: Array) -> float:
        w = p - centre
        return float(np.arctan2(w @ e2, w @ e1)) % (2 * np.pi)

    total = angle(c)
    n_steps = max(2, int(np.ceil(total * r / step_m)))
    rots = Rotation.from_matrix(np.stack([Ta[:3, :3], Tc[:3, :3]]))
    slerp = Slerp([0.0, 1.0], rots)
    out = []
    for f in np.arange(1, n_steps + 1) / n_steps:
        th = f * total
        T = np.eye(4)
        T[:3, :3] = slerp([f]).as_matrix()[0]
        T[:3, 3] = centre + r * (np.cos(th) * e1 + np.sin(th) * e2)
        out.append(T)
    return out
