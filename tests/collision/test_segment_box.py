"""Segment-to-box distances and the clearance search they tighten."""

from __future__ import annotations

import numpy as np
import trimesh

from assistant.collision.checker import CollisionChecker
from assistant.collision.clearance_scan import pruned_clearance
from assistant.collision.fcl_shapes import fcl_transform
from assistant.collision.reports import Obstacle
from assistant.collision.segment_box import oriented_bounds, segment_box_distance_one
from assistant.robots.catalog import installed_robot_urdf
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.robots.urdf_robot import URDFRobot
from assistant.transforms import make_T, pose_from_xyz_rpy, rot_z


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
    d = np.array([segment_box_distance_one(x, y, h) for x, y, h in zip(a, b, half, strict=True)])
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


def _tight_bounds(c: CollisionChecker, frames, rows):
    """Capsule-to-oriented-box bounds of (sample, robot shape, obstacle) rows as numpy
    expressions (the vectorised form the compiled pass reproduces product for product);
    -inf where they may overlap."""
    k, si, ei = rows.T
    F = frames[k, c._shape_link[si]]
    A = np.einsum("nij,nj->ni", F[:, :3, :3], c._seg_a[si]) + F[:, :3, 3]
    B = np.einsum("nij,nj->ni", F[:, :3, :3], c._seg_b[si]) + F[:, :3, 3]
    R, centre = c._env_R[ei], c._env_c[ei]
    la = np.einsum("nji,nj->ni", R, A - centre)
    lb = np.einsum("nji,nj->ni", R, B - centre)
    with np.errstate(invalid="ignore"):
        gap = np.array([segment_box_distance_one(x, y, h)
                        for x, y, h in zip(la, lb, c._env_h[ei], strict=True)]) - c._seg_r[si]
    return np.where(gap > 0.0, gap, -np.inf)


def _pass(c: CollisionChecker, Q):
    """`pruned_clearance` on the samples Q (frames left to the pass): (best, rows,
    bounds, which samples it posed, frames)."""
    movable = np.array([i for i, rs in enumerate(c._rshapes) if rs.link > 0])
    frames = np.empty((len(Q), len(c._chain_F) + 1, 4, 4))
    ready = np.zeros(len(Q), dtype=bool)
    best, rows, bounds = pruned_clearance(
        Q, frames, ready, c._chain_F, c.travel(Q[:-1], Q[1:]), c.CLEARANCE_STRIDE, movable,
        len(c._rshapes), c._sph_link, c._sph_local, c._sph_r, c._sph_shape, c._env_lo,
        c._env_hi, c._shape_link, c._seg_a, c._seg_b, c._seg_r, c._seg_exact, c._env_R,
        c._env_c, c._env_h, c._env_exact)
    return best, rows, bounds, ready, frames, movable


def _dense_samples(c: CollisionChecker, path):
    return np.ascontiguousarray(np.array(list(_samples(c, path))))


def test_pruned_clearance_is_the_exact_minimum_of_every_sample_and_poses_few(rv2aj):
    """Boxes only, so every pair's distance is the capsule-to-box bound: the pass returns
    the minimum over every (sample, shape, obstacle) of it, to the bit. On a path that
    passes near an obstacle it gave frames to under half of the samples: the rest lay too
    far from every obstacle. (When the best is large, most samples may hold it and are
    visited.)"""
    c = CollisionChecker(rv2aj, [
        _turned_box("B1", [0.30, 0.12, 0.12], [0.06, 0.14, 0.24], 0.6),
        _turned_box("B2", [0.05, 0.32, 0.08], [0.12, 0.05, 0.16], -0.9),
        _turned_box("table", [0.0, 0.0, -0.011], [1.2, 1.2, 0.02], 0.0)])
    rng = np.random.default_rng(21)
    clear = 0
    posed = []
    for _ in range(16):
        path = rng.uniform(rv2aj.limits.lower * 0.7, rv2aj.limits.upper * 0.7, size=(3, 5))
        Q = _dense_samples(c, path)
        best, rows, _, ready, _, movable = _pass(c, Q)
        frames = rv2aj.batch_link_poses(Q)
        k, r, e = np.unravel_index(np.arange(len(Q) * len(movable) * len(c._env)),
                                   (len(Q), len(movable), len(c._env)))
        tight = _tight_bounds(c, frames, np.stack([k, movable[r], e], axis=1))
        if tight.min() > 0.0:  # clear of every box: all pairs exact, none for FCL
            clear += 1
            assert best == tight.min() and len(rows) == 0
            assert c.min_clearance_along(list(path)) == best
            if best < 0.06:  # nearer than the shoulder ever is to the table
                posed.append(ready.mean())
    assert clear >= 8 and posed and max(posed) < 0.5, (clear, posed)


def test_pruned_clearance_leaves_a_meshs_pairs_to_fcl_with_bounds_that_hold(rv2aj):
    """A mesh obstacle is never measured in closed form: its pairs come back with lower
    bounds (never above FCL's distance), and every pair nearer than the boxes' best is
    among them - what lets the caller stop at the first bound above the best."""
    mesh = trimesh.creation.box(extents=[0.08, 0.08, 0.2])
    c = CollisionChecker(rv2aj, [
        _turned_box("B1", [0.30, 0.12, 0.12], [0.06, 0.14, 0.24], 0.6),
        Obstacle("M", make_T(rot_z(0.4), [0.25, -0.25, 0.10]),
                 (CollisionShape(ShapeKind.MESH, (1.0, 1.0, 1.0), mesh=mesh),))])
    rng = np.random.default_rng(8)
    returned = 0
    for _ in range(8):
        path = rng.uniform(rv2aj.limits.lower * 0.6, rv2aj.limits.upper * 0.6, size=(3, 5))
        Q = _dense_samples(c, path)
        best, rows, bounds, ready, frames, movable = _pass(c, Q)
        n_mov, n_env = len(movable), len(c._env)
        k, r, e = rows // (n_mov * n_env), (rows // n_env) % n_mov, rows % n_env
        assert np.all(e == 1) and ready[k].all()  # the mesh's pairs, from posed samples
        for kk, rr, ee, b in zip(k, r, e, bounds, strict=True):
            rs = c._rshapes[movable[rr]]
            rs.obj.setTransform(fcl_transform(frames[kk][rs.link] @ rs.shape.T_link_shape))
            d, _ = c._pair_distance(rs.obj, c._env[ee].obj)
            assert b <= d + 1e-12
        returned += len(rows)
        ref = min(c.clearance(q).distance for q in Q)
        fcl_best = min([best] + [c.clearance(q).distance for q in Q[np.unique(k)]])
        assert abs(c.min_clearance_along(list(path)) - min(ref, fcl_best)) < 1e-4
    assert returned > 0
