"""Millimetres and degrees in the page, metres and radians in the session: the edge."""

from __future__ import annotations

import numpy as np
import viser.transforms as vtf

from assistant.transforms import pose_from_mm_deg, pose_to_mm_deg

Array = np.ndarray


def pose_fields(T: Array) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """T (m, rad) -> ((x, y, z) mm, (A, B, C) deg) rounded for number fields."""
    v = pose_to_mm_deg(np.asarray(T, float))
    xyz = tuple(round(float(x), 3) + 0.0 for x in v[:3])  # + 0.0: no "-0" on screen
    abc = tuple(round(float(x), 3) + 0.0 for x in v[3:])
    return xyz, abc  # type: ignore[return-value]


def pose_from_fields(xyz_mm: tuple[float, ...], abc_deg: tuple[float, ...]) -> Array:
    return pose_from_mm_deg(np.array([*xyz_mm, *abc_deg], dtype=float))


def point_from_mm(xyz_mm: tuple[float, ...]) -> Array:
    p = np.asarray(xyz_mm, dtype=float)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError("a point needs three finite numbers (mm)")
    return p / 1000.0


def point_or_name(text: str, names: set[str]) -> Array | str:
    """A taught location's name, or "x y z" / "x, y, z" in mm (-> metres)."""
    t = text.strip()
    if t in names:
        return t
    parts = t.replace(",", " ").replace(";", " ").split()
    try:
        return point_from_mm(tuple(float(v) for v in parts))
    except ValueError:
        known = ", ".join(sorted(names)) or "none yet"
        raise ValueError(f"{t!r} is neither a taught location ({known}) nor three numbers "
                         "in mm") from None


def wxyz_position(T: Array) -> tuple[Array, Array]:
    """A viser node pose (quaternion w, x, y, z and position) from a 4x4 transform."""
    T = np.asarray(T, float)
    return vtf.SO3.from_matrix(T[:3, :3]).wxyz, T[:3, 3].copy()


def T_from_wxyz_position(wxyz: tuple[float, ...] | Array, position: tuple[float, ...] | Array
                         ) -> Array:
    T = np.eye(4)
    T[:3, :3] = vtf.SO3(np.asarray(wxyz, float)).as_matrix()
    T[:3, 3] = np.asarray(position, float)
    return T


def fmt_mm(p: Array) -> str:
    p = np.asarray(p, float) * 1000.0
    return f"({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f})"


#: The angle convention of every typed pose, named once where poses are typed.
ABC_CONVENTION = "A, B, C turn the tool about Z, then the turned Y', then X'' (degrees, " \
    "KUKA's convention). (0, 0, 180) points the tool down."


def abc_shown(T: Array, typed: tuple[float, ...] | None) -> tuple[float, float, float]:
    """A pose's A, B, C in degrees: as the operator typed them when they give the same
    rotation (0, 0, 180 is also -180, 0, 0), else the ones read back from the pose."""
    computed = pose_fields(T)[1]
    if typed is not None:
        R_typed = pose_from_mm_deg(np.array([0.0, 0.0, 0.0, *typed], dtype=float))[:3, :3]
        if np.allclose(R_typed, np.asarray(T, float)[:3, :3], atol=1e-6):
            return tuple(float(v) + 0.0 for v in typed)  # type: ignore[return-value]
    return tuple(v + 0.0 if abs(v) > 5e-4 else 0.0 for v in computed)  # type: ignore
