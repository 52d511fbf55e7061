"""Segment-to-box distances and the clearance search they tighten."""

from __future__ import annotations

import numpy as np
import trimesh

from assistant.collision import CollisionChecker, Obstacle
from assistant.robot_catalog import installed_robot_urdf
from assistant.robot_model import CollisionShape, ShapeKind
from assistant.segment_box import oriented_bounds, scan_tight_bounds, segment_box_distance
from assistant.transforms import make_T, pose_from_xyz_rpy, rot_z
from assistant.urdf_robot import URDFRobot


def _ternary_distance(a, b, half, iterations=120):
    """Reference: ternary search on the squared distance along the segment, which is
    convex (a convex function of the point, composed with an affine map)."""
    def f(t):
        P = a + t[:, None] * (b - a)
        q = np.maximum(np.abs(P) - half, 0.0)
        return (q ** 2).sum(axis=1)

    lo, hi = np.zeros(len(a)), np.ones(len(a))
    for _ in range(iterations):
        m1, m2 = lo + (hi - lo) / 3, hi - (hi - lo) / 3
        left = f(m1) <= f(m2)
        hi, lo = np.where(left, m2, hi), np.where(left, lo, m1)
    return np.sqrt(f(0.5 * (lo + hi)))


def test_segment_box_distance_is_the_minimum_along_the_segment():
    """Exact - for points, axis-parallel segments, segments that cross the box."""
    rng = np.random.default_rng(3)
    n = 1500
    a = rng.uniform(-0.5, 0.5, (n, 3))
    b = a + rng.uniform(-0.4, 0.4, (n, 3))
    b[:100] = a[:100]  # points
    b[100:200, 1:] = a[100:200, 1:]  # parallel to x
    half = rng.uniform(0.02, 0.2, (n, 3))
    d = segment_box_distance(a, b, half)
    ref = _ternary_distance(a, b, half)
    assert np.all(np.abs(d - ref) < 1e-9)
    assert 20 < int((d == 0.0).sum()) < n - 20  # some segments meet their box, most do not


def test_oriented_bounds_contain_a_turned_mesh():
    mesh = trimesh.creation.icosphere(radius=0.05)
    mesh.apply_translation([0.01, -0.02, 0.03])
    shape = CollisionShape(ShapeKind.MESH, (1.0, 1.0, 1.0), mesh=mesh)
    T = pose_from_xyz_rpy([0.2, 0.1, 0.3], [0.3, -0.2, 1.1])
    box = oriented_bounds(shape, T)
    world = mesh.vertices @ T[:3, :3].T + T[:3, 3]
    local = (world - box.centre) @ box.R
    assert np.all(np.abs(local) <= box.half + 1e-12)
    assert np.allclose(np.abs(local).max(axis=0), box.half)  # and no larger


def _turned_box(name, centre, size, yaw):
    return Obstacle(name, make_T(rot_z(yaw), centre),
                    (CollisionShape(ShapeKind.BOX, tuple(size)),))


def test_clearance_near_turned_boxes_and_a_mesh_is_exact_with_few_fcl_calls(rv2aj,
                                                                         monkeypatch):
    """Paths that run along turned boxes and a mesh: the search still returns the minimum
    over every sample (exact where FCL's own answer is up to ~0.1 mm high), and the tight
    bounds leave FCL only a few pairs to measure (the covering spheres alone left hundreds
    on such paths)."""
    mesh = trimesh.creation.box(extents=[0.08, 0.08, 0.2])
    obstacles = [
        _turned_box("B1", [0.30, 0.12, 0.12], [0.06, 0.14, 0.24], 0.6),
        _turned_box("B2", [0.05, 0.32, 0.08], [0.12, 0.05, 0.16], -0.9),
        Obstacle("M", make_T(rot_z(0.4), [0.25, -0.25, 0.10]),
                 (CollisionShape(ShapeKind.MESH, (1.0, 1.0, 1.0), mesh=mesh),)),
    ]
    checker = CollisionChecker(rv2aj, obstacles)
    calls = []
    measured = checker._pair_distance

    def counting(a, b):
        calls.append(1)
        return measured(a, b)

    rng = np.random.default_rng(5)
    found = []
    for _ in range(12):
        path = rng.uniform(rv2aj.limits.lower * 0.6, rv2aj.limits.upper * 0.6, size=(3, 5))
        monkeypatch.setattr(checker, "_pair_distance", counting)
        calls.clear()
        fast = checker.min_clearance_along(list(path))
        n_fast = len(calls)
        monkeypatch.undo()
        ref = min(checker.clearance(q).distance for q in _samples(checker, path))
        assert ref - 1e-4 < fast <= ref + 1e-12  # FCL's GJK: up to ~0.1 mm above
        if fast > 0.0:  # (a penetration depth has no bound: every overlapping pair is measured)
            assert n_fast <= 10, (fast, n_fast)
        found.append(fast)
    assert min(v for v in found if v > 0.0) < 0.05  # some clear paths pass near an obstacle


def _samples(checker, path, max_step=0.01):
    for a, b in zip(path[:-1], path[1:], strict=True):
        n = checker.motion_samples(a, b, max_step)
        for f in np.arange(0, n + 1) / n:
            yield a + f * (b - a)


def test_clearance_of_a_robot_with_mesh_and_box_links_is_the_fcl_minimum():
    """Link shapes that are not round (the UR5's meshes, its tool box) get no tight bound:
    their pairs are measured with FCL, and the answer is FCL's brute-force minimum."""
    urdf, share = installed_robot_urdf(
        "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    ur5 = URDFRobot.from_file(urdf, package_dirs=[share])
    checker = CollisionChecker(ur5, [
        _turned_box("B1", [0.45, 0.10, 0.20], [0.08, 0.20, 0.40], 0.5),
        _turned_box("B2", [-0.10, 0.45, 0.10], [0.20, 0.06, 0.20], -0.7),
    ])
    rng = np.random.default_rng(8)
    for _ in range(2):
        path = rng.uniform(ur5.limits.lower * 0.3, ur5.limits.upper * 0.3, size=(2, 6))
        fast = checker.min_clearance_along(list(path), max_step=0.03)
        ref = min(checker.clearance(q).distance for q in _samples(checker, path, 0.03))
        assert abs(fast - ref) < 1e-12


def test_scan_of_tight_bounds_equals_bounding_every_row(rv2aj):
    """The clearance report's compiled pass (`scan_tight_bounds`) gives the exact rows'
    minimum and, for the rows it leaves to FCL, the bits of the vectorised capsule-to-box
    bounds it replaced (turned boxes: their own frames; a mesh: never exact)."""
    mesh = trimesh.creation.box(extents=[0.08, 0.08, 0.2])
    checker = CollisionChecker(rv2aj, [
        _turned_box("B1", [0.30, 0.12, 0.12], [0.06, 0.14, 0.24], 0.6),
        _turned_box("B2", [0.05, 0.32, 0.08], [0.12, 0.05, 0.16], -0.9),
        Obstacle("M", make_T(rot_z(0.4), [0.25, -0.25, 0.10]),
                 (CollisionShape(ShapeKind.MESH, (1.0, 1.0, 1.0), mesh=mesh),))])
    Q = np.random.default_rng(8).uniform(rv2aj.limits.lower, rv2aj.limits.upper, (400, 5))
    frames = rv2aj.batch_link_poses(Q)
    movable = np.array([i for i, rs in enumerate(checker._rshapes) if rs.link > 0])
    lb = np.ascontiguousarray(checker._clearance_bounds(frames)[:, movable, :])
    c = checker
    best, rows, bounds = scan_tight_bounds(  # every row: nothing found yet
        np.ascontiguousarray(frames), lb, movable, -1, np.inf, c._shape_link, c._seg_a,
        c._seg_b, c._seg_r, c._seg_exact, c._env_R, c._env_c, c._env_h, c._env_exact)
    k, r, e = np.unravel_index(np.arange(lb.size), lb.shape)
    every = np.stack([k, movable[r], e], axis=1)
    tight = c._segment_bounds(frames, every)
    exact = c._is_exact(every, tight)
    assert exact.any() and (~exact).any()
    assert best == tight[exact].min()
    # the rows left for FCL: non-exact ones, with the vectorised bound to the bit; every
    # one whose sphere bound is below the result among them (the rest could not matter)
    assert not exact[rows].any()
    assert np.array_equal(bounds, np.maximum(lb.reshape(-1), tight)[rows])
    must = np.flatnonzero(~exact & (lb.reshape(-1) < best))
    assert np.isin(must, rows).all() and len(must) > 0
