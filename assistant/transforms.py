"""Rigid transforms as 4x4 numpy arrays, named ``T_parent_child`` at every call site.

Internal units are metres and radians; `pose_from_mm_deg` / `pose_to_mm_deg` are the only
places where millimetres and degrees cross into the core. Operator-facing Euler angles follow
KUKA's convention (A, B, C = rotations about Z, Y', X'', i.e. R = Rz(A) @ Ry(B) @ Rx(C)).
Each program dialect converts to its controller's own convention (MELFA's A is about X and C
about Z: R = Rz(C) Ry(B) Rx(A); see `assistant/export/melfa.py`).
"""

from __future__ import annotations

import numpy as np

Array = np.ndarray


def rot_x(angle: float) -> Array:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> Array:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> Array:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_y_batch(angles: Array) -> Array:
    """`rot_y` for each angle: (N, 3, 3)."""
    c, s = np.cos(angles), np.sin(angles)
    R = np.zeros((len(c), 3, 3))
    R[:, 0, 0], R[:, 0, 2], R[:, 1, 1], R[:, 2, 0], R[:, 2, 2] = c, s, 1.0, -s, c
    return R


def rot_z_batch(angles: Array) -> Array:
    """`rot_z` for each angle: (N, 3, 3)."""
    c, s = np.cos(angles), np.sin(angles)
    R = np.zeros((len(c), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


def make_T(R: Array | None = None, p: Array | None = None) -> Array:
    """Homogeneous transform from a rotation matrix and a translation."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if p is not None:
        T[:3, 3] = p
    return T


def inv_T(T: Array) -> Array:
    """Inverse of a rigid transform (cheaper and exacter than np.linalg.inv)."""
    Ti = np.eye(4)
    R = T[:3, :3]
    Ti[:3, :3] = R.T
    Ti[:3, 3] = -R.T @ T[:3, 3]
    return Ti


def rpy_to_matrix(a: float, b: float, c: float) -> Array:
    """R = Rz(a) Ry(b) Rx(c): KUKA's A, B, C (the UI's angles)."""
    return rot_z(a) @ rot_y(b) @ rot_x(c)


def matrix_to_rpy(R: Array) -> tuple[float, float, float]:
    """Inverse of `rpy_to_matrix`; at the singularity (|b| = 90 deg) c is set to 0."""
    sb = -R[2, 0]
    sb = float(np.clip(sb, -1.0, 1.0))
    # atan2 of sin and cos, not arcsin: near |b| = 90 deg arcsin turns the last bit of sb
    # into ~1e-8 rad, atan2 keeps the error at the inputs' rounding
    b = float(np.arctan2(sb, np.hypot(R[0, 0], R[1, 0])))
    if abs(sb) > 1.0 - 1e-12:
        a = float(np.arctan2(-R[0, 1], R[1, 1]))
        return a, b, 0.0
    a = float(np.arctan2(R[1, 0], R[0, 0]))
    c = float(np.arctan2(R[2, 1], R[2, 2]))
    return a, b, c


def pose_from_xyz_rpy(xyz: Array, rpy: Array) -> Array:
    return make_T(rpy_to_matrix(*rpy), np.asarray(xyz, dtype=float))


def pose_from_mm_deg(values: Array) -> Array:
    """(x, y, z [mm], a, b, c [deg]) as typed by an operator -> T in metres/radians."""
    v = np.asarray(values, dtype=float)
    if v.shape != (6,):
        raise ValueError(f"a pose needs 6 numbers (x, y, z, a, b, c), got {v.shape}")
    return pose_from_xyz_rpy(v[:3] / 1000.0, np.radians(v[3:]))


def pose_to_mm_deg(T: Array) -> Array:
    """T in metres/radians -> (x, y, z [mm], a, b, c [deg]) for display and programs."""
    a, b, c = matrix_to_rpy(T[:3, :3])
    return np.concatenate([T[:3, 3] * 1000.0, np.degrees([a, b, c])])


def axis_angle(axis: Array, angle: float) -> Array:
    """Rotation matrix for a rotation of `angle` about the unit vector `axis` (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    n = np.linalg.norm(k)
    if n < 1e-15:
        return np.eye(3)
    k = k / n
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


def axis_angle_batch(axes: Array, angles: Array) -> Array:
    """`axis_angle` for each row of axes (N, 3) (not necessarily unit) and angle: (N, 3, 3)."""
    axes = np.asarray(axes, dtype=float)
    n = np.linalg.norm(axes, axis=1)
    k = axes / np.where(n < 1e-15, 1.0, n)[:, None]
    K = np.zeros((len(k), 3, 3))
    K[:, 0, 1], K[:, 0, 2] = -k[:, 2], k[:, 1]
    K[:, 1, 0], K[:, 1, 2] = k[:, 2], -k[:, 0]
    K[:, 2, 0], K[:, 2, 1] = -k[:, 1], k[:, 0]
    angles = np.asarray(angles, dtype=float)
    R = (np.eye(3)[None] + np.sin(angles)[:, None, None] * K
         + (1.0 - np.cos(angles))[:, None, None] * (K @ K))
    R[n < 1e-15] = np.eye(3)
    return R


def rotation_vector(R: Array) -> Array:
    """Axis*angle vector of a rotation matrix (URScript's pose orientation), stable near pi."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_rotvec()


def rotation_angle(R: Array) -> float:
    """Angle of the rotation R in [0, pi]: atan2(sin, cos), with 2 sin the norm of R's skew
    part and 2 cos its trace - 1. arccos of the trace alone turns one rounding of a small
    angle's trace into ~1e-8 rad (sqrt(2 eps)); this keeps it at the inputs' rounding."""
    R = np.asarray(R, dtype=float)
    s = np.hypot(np.hypot(R[2, 1] - R[1, 2], R[0, 2] - R[2, 0]), R[1, 0] - R[0, 1])
    return float(np.arctan2(s, R[0, 0] + R[1, 1] + R[2, 2] - 1.0))


def angle_between(a: Array, b: Array) -> float:
    """Angle in [0, pi] between two vectors (any lengths, not zero): atan2(|a x b|, a . b),
    well conditioned everywhere, where arccos of the normalised dot product loses half the
    digits near 0 and pi (one rounding of the dot becomes ~1.5e-8 rad)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.shape == (2,):  # a plane's vectors: the cross product's one component
        return float(np.arctan2(abs(a[0] * b[1] - a[1] * b[0]), float(a @ b)))
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), float(a @ b)))


def wrap_angle(a: Array | float) -> Array | float:
    """Wrap to (-pi, pi]."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


#: Largest |R^T R - I| entry accepted as a rounded rotation (values typed in mm/deg and
#: stored with a few decimals); anything further off is not a rotation.
ROTATION_TOLERANCE = 1e-3


def orthonormalized(T: Array, tol: float = ROTATION_TOLERANCE) -> Array:
    """The transform with its rotation projected onto the nearest proper rotation (SVD).

    A pose read back from a file or a rounded display is a rotation only to a few decimals;
    iterative IK would chase the impossible remainder and refuse it. Raises ValueError when the
    matrix is not a rounded rotation at all.
    """
    T = np.array(T, dtype=float)
    R = T[:3, :3]
    dev = float(np.max(np.abs(R.T @ R - np.eye(3))))
    if dev <= 1e-12 and np.linalg.det(R) > 0:
        return T
    if dev > tol or np.linalg.det(R) <= 0:
        raise ValueError(f"the pose's rotation is not a rotation matrix (off by {dev:.2g})")
    U, _, Vt = np.linalg.svd(R)
    T[:3, :3] = U @ Vt
    return T


def stored_pose(T: Array, decimals: int = 9) -> Array:
    """A pose (e.g. from forward kinematics) as written to a file: rounded, so the file does
    not depend on the last bits of the kinematics, then the rotation made orthonormal again
    (a rounded rotation is off by ~1e-9, and numeric IK refuses such a target)."""
    T = np.round(np.asarray(T, dtype=float), decimals)
    x = T[:3, 0] / np.sqrt(T[:3, 0] @ T[:3, 0])
    z = np.cross(x, T[:3, 1])
    z = z / np.sqrt(z @ z)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    return T
