"""Our `CollisionShape` -> python-fcl geometry, and the conservative bounds the broad phase uses.

FCL objects are created once per shape and only re-posed afterwards; meshes become BVH models
(OBBRSS) built once and shared by every object that uses the same trimesh.
"""

from __future__ import annotations

import fcl
import numpy as np
import trimesh

from assistant.robots.model import CollisionShape, ShapeKind

Array = np.ndarray


#: No collision geometry reaches farther than this (m): FCL's tolerances are absolute, so
#: coordinates like 1e27 m make every test silently answer "free".
MAX_COORDINATE_M = 10_000.0


def _check_finite(values: Array, what: str) -> None:
    v = np.asarray(values, dtype=np.float64)
    if v.size and not np.isfinite(v).all():
        raise ValueError(f"{what} has NaN or infinite coordinates: it cannot be "
                         "collision-checked; import or define it again")
    if v.size and float(np.abs(v).max()) > MAX_COORDINATE_M:
        raise ValueError(f"{what} reaches {float(np.abs(v).max()):.3g} m, beyond the "
                         f"{MAX_COORDINATE_M:g} m a collision check is exact for; check its "
                         "units or remove the stray geometry")


def fcl_geometry(shape: CollisionShape) -> fcl.CollisionGeometry:
    """FCL geometry of a shape; a shape with NaN/inf or absurd sizes raises ValueError
    (FCL would accept it and then miss every collision)."""
    if shape.kind != ShapeKind.MESH:
        _check_finite(np.asarray(shape.size, dtype=float), f"a {shape.kind.value} shape")
    if shape.kind == ShapeKind.CAPSULE:
        return fcl.Capsule(float(shape.size[0]), float(shape.size[1]))
    if shape.kind == ShapeKind.CYLINDER:
        return fcl.Cylinder(float(shape.size[0]), float(shape.size[1]))
    if shape.kind == ShapeKind.BOX:
        return fcl.Box(*(float(v) for v in shape.size))
    if shape.kind == ShapeKind.SPHERE:
        return fcl.Sphere(float(shape.size[0]))
    if shape.mesh is None:
        raise ValueError("a mesh collision shape without a mesh")
    m = fcl.BVHModel()
    verts = np.asarray(shape.mesh.vertices, dtype=np.float64)
    _check_finite(verts, "a collision mesh")
    faces = np.asarray(shape.mesh.faces, dtype=np.int64)
    m.beginModel(len(verts), len(faces))
    m.addSubModel(verts, faces)
    m.endModel()
    return m


def inflated_geometry(shape: CollisionShape, margin: float) -> fcl.CollisionGeometry:
    """FCL geometry holding every point within `margin` of the shape (its frame unchanged).

    What lets an obstacle's margin (`CollisionShape.margin`) cost one FCL collision test
    instead of a distance query (about 30 times slower on a 20 000-triangle proxy): a robot
    shape grown by the margin touches the obstacle exactly when the shape comes within the
    margin of it. Exact for spheres and capsules (their radius grows); a cylinder or box
    grows by the margin along every axis and a mesh becomes its convex hull with every face
    pushed out by the margin (an FCL convex solid) - both hold the exact grown shape, so they
    may only answer "touching" up to ~0.4 margin early at corners, never late."""
    m = float(margin)
    if m <= 0.0:
        return fcl_geometry(shape)
    if shape.kind == ShapeKind.SPHERE:
        return fcl.Sphere(float(shape.size[0]) + m)
    if shape.kind == ShapeKind.CAPSULE:
        return fcl.Capsule(float(shape.size[0]) + m, float(shape.size[1]))
    if shape.kind == ShapeKind.CYLINDER:
        return fcl.Cylinder(float(shape.size[0]) + m, float(shape.size[1]) + 2.0 * m)
    if shape.kind == ShapeKind.BOX:
        return fcl.Box(*(float(v) + 2.0 * m for v in shape.size))
    assert shape.mesh is not None
    corners = _grown_hull_corners(np.asarray(shape.mesh.vertices, dtype=np.float64), m)
    hull = trimesh.convex.convex_hull(corners)
    _check_finite(hull.vertices, "a grown collision mesh")
    faces = np.column_stack([np.full(len(hull.faces), 3), hull.faces]).ravel()
    return fcl.Convex(np.asarray(hull.vertices, dtype=np.float64), len(hull.faces), faces)


def _grown_hull_corners(v: Array, margin: float) -> Array:
    """Corners of the convex hull of `v` with each facet plane moved out by `margin`; a flat
    or degenerate point set falls back to its bounding box grown by the margin."""
    from scipy.spatial import ConvexHull, HalfspaceIntersection, QhullError

    try:
        hull = ConvexHull(v)
        eq = hull.equations.copy()  # n . x + d <= 0 inside, |n| = 1
        eq[:, 3] -= margin
        inner = v[hull.vertices].mean(axis=0)
        return HalfspaceIntersection(eq, inner).intersections
    except (QhullError, ValueError):
        lo, hi = v.min(axis=0) - margin, v.max(axis=0) + margin
        return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                         for z in (lo[2], hi[2])])


def fcl_transform(T: Array) -> fcl.Transform:
    return fcl.Transform(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))


def covering_spheres(shape: CollisionShape, max_count: int = 6) -> tuple[Array, Array]:
    """Spheres (centres in the link frame, radii) whose union contains the shape.

    A capsule/cylinder of length L is split into k pieces, each covered by a sphere of radius
    r + L/(2k) (cylinders: the corner distance), which is far tighter than one sphere for the
    long upper arm. Everything else gets one sphere around its bounding box.
    """
    T = shape.T_link_shape
    if shape.kind in (ShapeKind.CAPSULE, ShapeKind.CYLINDER):
        r, length = float(shape.size[0]), float(shape.size[1])
        k = int(np.clip(np.ceil(length / max(r, 1e-6)), 1, max_count))
        half = length / (2 * k)
        rad = (r + half) if shape.kind == ShapeKind.CAPSULE else float(np.hypot(r, half))
        t = -length / 2 + length * (np.arange(k) + 0.5) / k
        local = np.zeros((k, 3))
        local[:, 2] = t
        centres = local @ T[:3, :3].T + T[:3, 3]
        return centres, np.full(k, rad)
    if shape.kind == ShapeKind.SPHERE:
        return T[:3, 3][None, :].copy(), np.array([float(shape.size[0])])
    if shape.kind == ShapeKind.BOX:
        return T[:3, 3][None, :].copy(), np.array([float(np.linalg.norm(shape.size) / 2)])
    assert shape.mesh is not None
    lo, hi = shape.mesh.bounds
    c_local = (lo + hi) / 2
    rad = float(np.max(np.linalg.norm(shape.mesh.vertices - c_local, axis=1)))
    return (T[:3, :3] @ c_local + T[:3, 3])[None, :], np.array([rad])


def world_aabb(shape: CollisionShape, T_base_owner: Array) -> tuple[Array, Array]:
    """Axis-aligned box (in the base frame) that contains the shape placed by T_base_owner,
    grown by the shape's margin."""
    T = T_base_owner @ shape.T_link_shape
    m = float(shape.margin)
    if shape.kind == ShapeKind.MESH:
        assert shape.mesh is not None
        v = np.asarray(shape.mesh.vertices) @ T[:3, :3].T + T[:3, 3]
        return v.min(axis=0) - m, v.max(axis=0) + m
    if shape.kind == ShapeKind.SPHERE:
        r = float(shape.size[0]) + m
        return T[:3, 3] - r, T[:3, 3] + r
    if shape.kind == ShapeKind.BOX:
        half = np.asarray(shape.size, dtype=float) / 2
    elif shape.kind == ShapeKind.CYLINDER:
        r, length = shape.size
        half = np.array([r, r, length / 2])
    else:  # capsule
        r, length = shape.size
        half = np.array([r, r, length / 2 + r])
    ext = np.abs(T[:3, :3]) @ half + m
    return T[:3, 3] - ext, T[:3, 3] + ext
