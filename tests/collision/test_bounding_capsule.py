"""Mesh links get a capsule around their vertices (`bounding_capsule`): every vertex lies
inside it, the broad phase prunes a UR5's mesh pairs with it, and the checks still equal
brute-force FCL - also for postures a hair from contact."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from contact_bisect import bisect_to_contact

from assistant.collision.bounding_capsule import capsule_around, mesh_capsule
from assistant.collision.broad_phase import prune_round_pairs
from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import Obstacle
from assistant.robots.catalog import installed_robot_urdf
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.robots.urdf_robot import URDFRobot
from assistant.transforms import make_T, rot_z

UR5 = "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"


def _segment_distances(V, a, b):
    d = b - a
    L2 = float(d @ d)
    t = np.zeros(len(V)) if L2 == 0.0 else np.clip((V - a) @ d / L2, 0.0, 1.0)
    return np.linalg.norm(V - (a + t[:, None] * d), axis=1)


@pytest.mark.parametrize("seed", range(8))
def test_every_vertex_is_inside_the_capsule(seed):
    rng = np.random.default_rng(seed)
    stretch = np.diag(rng.uniform(0.01, 0.4, 3))
    V = rng.normal(size=(int(rng.integers(1, 400)), 3)) @ stretch @ rot_z(rng.uniform(0, 6))
    Vs = V + rng.uniform(-1, 1, 3)
    a, b, r = capsule_around(Vs)
    assert np.all(_segment_distances(Vs, a, b) <= r)
    # tighter than the sphere around the points' centre for elongated sets
    assert r <= np.linalg.norm(Vs - Vs.mean(axis=0), axis=1).max() * (1 + 1e-9)


def test_a_mesh_shape_gets_its_capsule_in_the_link_frame():
    box = trimesh.creation.box((0.4, 0.1, 0.1))
    T = make_T(p=[0.1, 0.2, 0.3]) @ np.block([[rot_z(0.7), np.zeros((3, 1))],
                                                [np.zeros((1, 3)), np.ones((1, 1))]])
    shape = CollisionShape(ShapeKind.MESH, (), T, box)
    a, b, r = mesh_capsule(shape)
    V = box.vertices @ T[:3, :3].T + T[:3, 3]
    assert np.all(_segment_distances(V, a, b) <= r)
    assert r == pytest.approx(np.sqrt(0.05 ** 2 * 2), rel=1e-6)  # the box's cross-section
    assert mesh_capsule(CollisionShape(ShapeKind.BOX, (0.1, 0.1, 0.1))) is None


def test_a_ur5s_mesh_pairs_are_pruned_and_the_checks_stay_fcls():
    urdf, share = installed_robot_urdf(UR5)
    ur5 = URDFRobot.from_file(urdf, package_dirs=[share])
    rng = np.random.default_rng(4)
    boxes = [Obstacle(f"b{i}", make_T(p=rng.uniform([-0.6, -0.6, 0.0], [0.6, 0.6, 0.7])),
                      (CollisionShape(ShapeKind.BOX, tuple(rng.uniform(0.05, 0.3, 3))),))
             for i in range(6)]
    checker = CollisionChecker(ur5, boxes)
    meshes = [i for i, rs in enumerate(checker._rshapes) if rs.shape.kind == ShapeKind.MESH]
    assert meshes and not np.isnan(checker._seg_r[meshes]).any()
    Q = rng.uniform(ur5.limits.lower * 0.5, ur5.limits.upper * 0.5, size=(600, 6))
    frames = ur5.batch_link_poses(Q)
    env_c, self_c, _ = checker._candidates(frames)
    before = int(env_c.sum() + self_c.sum())
    prune_round_pairs(frames, np.arange(len(Q)), env_c, self_c, checker._shape_link,
                      checker._seg_a, checker._seg_b, checker._seg_r, checker._env_R,
                      checker._env_c, checker._env_h, checker._pair_a, checker._pair_b,
                      checker.PRUNE_APART)
    assert int(env_c.sum() + self_c.sum()) < 0.8 * before  # the capsules prune
    fast = checker.in_collision_batch(Q)
    naive = np.array([checker.in_collision_naive(q) for q in Q])
    assert np.array_equal(fast, naive) and 0.05 < fast.mean() < 0.95
    near = bisect_to_contact(checker, Q[~fast][:30], Q[fast][:30])
    assert np.array_equal(checker.in_collision_batch(near),
                          np.array([checker.in_collision_naive(q) for q in near]))
