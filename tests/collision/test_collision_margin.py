"""An obstacle's margin counts as the obstacle (issue 54): a big CAD part's proxy carries the
distance by which the part may lie outside it, and every check - single, batch, motion,
brute force, clearance, octree - must treat everything within that margin as touching."""

from __future__ import annotations

import fcl
import numpy as np
import pytest
import trimesh

from assistant.collision.checker import CollisionChecker
from assistant.collision.fcl_shapes import fcl_geometry, inflated_geometry
from assistant.collision.reports import Obstacle
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.transforms import make_T
from assistant.world.octree import OctreeGrid
from assistant.world.rasterise import obstacle_cells

#: FCL answers contact and distance to ~1e-6 m on these shapes; margins are set this far
#: (0.5 mm) either side of a measured distance, far above FCL's tolerance and far below
#: any feature of the scene, so the expected answer is unambiguous.
SIDE = 5e-4


def _ball_obstacle(margin: float, centre) -> Obstacle:
    """A 2 cm ball as a mesh (a proxy is a mesh), carrying `margin`."""
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.02)
    return Obstacle("part", make_T(p=np.asarray(centre, float)),
                    (CollisionShape(ShapeKind.MESH, mesh=ball, margin=margin),))


@pytest.fixture(scope="module")
def near_posture(rv2aj):
    """A posture and a ball placed so that the arm passes `gap` from the ball, not touching:
    the ball sits beside the TCP, measured with FCL's distance."""
    q = np.array([0.3, 0.4, 1.2, 0.5, 0.0])
    tcp = rv2aj.fk(q)[:3, 3]
    centre = tcp + np.array([0.0, 0.0, -0.06])  # below the tool
    gap = CollisionChecker(rv2aj, [_ball_obstacle(0.0, centre)]).clearance(q).distance
    assert 0.005 < gap < 0.05, gap  # near, not touching: the margin decides
    return q, centre, gap


def test_margin_below_the_gap_is_free_above_it_is_a_contact(rv2aj, near_posture):
    q, centre, gap = near_posture
    free = CollisionChecker(rv2aj, [_ball_obstacle(gap - SIDE, centre)])
    hit = CollisionChecker(rv2aj, [_ball_obstacle(gap + SIDE, centre)])
    assert free.is_valid(q) and not free.in_collision_naive(q)
    assert not hit.is_valid(q) and hit.in_collision_naive(q)
    assert [c.other for c in hit.check(q).contacts] == ["part"]
    # the batch, margin and sampled paths give the same answers
    Q = np.repeat(q[None], 3, axis=0)
    assert free.is_valid_batch(Q).all() and not hit.is_valid_batch(Q).any()
    assert not hit.is_valid_batch_margin(Q)[0].any()
    assert not hit.is_valid_samples(Q).any()
    # clearance is measured to everything within the margin: the gap less the margin
    assert free.clearance(q).distance == pytest.approx(SIDE, abs=1e-5)
    assert free.min_clearance_along([q, q]) == pytest.approx(SIDE, abs=1e-5)


def test_a_motion_through_the_margin_is_stopped_in_it(rv2aj, near_posture):
    q, centre, gap = near_posture
    checker = CollisionChecker(rv2aj, [_ball_obstacle(gap + SIDE, centre)])
    bare = CollisionChecker(rv2aj, [_ball_obstacle(0.0, centre)])
    step = np.array([0.3, 0.0, 0.0, 0.0, 0.0])
    a, b = q - step, q + step  # swings through q, where only the margin is reached
    assert checker.is_valid(a) and checker.is_valid(b)
    assert bare.check_motion(a, b).valid
    check = checker.check_motion(a, b)
    assert not check.valid and 0.0 < check.first_invalid_fraction <= 0.5
    assert [c.other for c in check.report.contacts] == ["part"]


def test_margin_checks_agree_with_brute_force_on_random_postures(rv2aj):
    """The compiled broad phase grows the obstacle's bounds by the margin: its answers equal
    the brute-force FCL ones (with the grown robot shapes) posture for posture."""
    ring = trimesh.creation.torus(0.12, 0.03, major_sections=40, minor_sections=16)
    part = Obstacle("ring", make_T(p=[0.25, 0.0, 0.2]),
                    (CollisionShape(ShapeKind.MESH, mesh=ring, margin=0.02),))
    checker = CollisionChecker(rv2aj, [part])
    rng = np.random.default_rng(54)
    Q = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, size=(600, 5))
    fast = checker.in_collision_batch(Q)
    naive = np.array([checker.in_collision_naive(q) for q in Q])
    # Booleans of random postures: only one within ~1e-15 m of the margin could differ.
    assert np.array_equal(fast, naive)
    bare = CollisionChecker(rv2aj, [Obstacle("ring", part.T_base_object,
                                             (CollisionShape(ShapeKind.MESH, mesh=ring),))])
    touching = bare.in_collision_batch(Q)
    assert np.all(fast >= touching)  # the margin only adds contacts
    assert fast.sum() > touching.sum()  # and it does add some


@pytest.mark.parametrize("shape", [
    CollisionShape(ShapeKind.SPHERE, (0.03,)),
    CollisionShape(ShapeKind.CAPSULE, (0.02, 0.1)),
    CollisionShape(ShapeKind.CYLINDER, (0.02, 0.1)),
    CollisionShape(ShapeKind.BOX, (0.04, 0.06, 0.1)),
    CollisionShape(ShapeKind.MESH, mesh=trimesh.creation.annulus(0.02, 0.05, 0.04)),
], ids=lambda s: s.kind.value)
def test_a_grown_shape_holds_every_point_within_the_margin(shape):
    """Points just inside distance m of the shape (its surface moved out along the normals
    by 0.98 m) all lie in the grown geometry: a robot shape grown by the margin touches
    whatever the margin reaches."""
    m = 0.01
    grown = fcl.CollisionObject(inflated_geometry(shape, m))
    probe = fcl.CollisionObject(fcl.Sphere(1e-6))
    surface = shape.to_trimesh()  # inscribed in the true shape for the round kinds
    pts, faces = trimesh.sample.sample_surface(surface, 400, seed=3)
    pts = np.vstack([pts + 0.98 * m * surface.face_normals[faces],
                     surface.vertices + 0.98 * m * surface.vertex_normals])
    req = fcl.CollisionRequest()
    outside = [p for p in pts
               if not _touches(probe, grown, p, req)]
    assert outside == []
    # ... and not by much more: along a face normal of the box, 1.02 m out is free
    if shape.kind == ShapeKind.BOX:
        centre = np.array([0.0, 0.0, shape.size[2] / 2 + 1.02 * m])
        assert not _touches(probe, grown, centre, req)
        assert _touches(probe, fcl.CollisionObject(fcl_geometry(shape)), [0, 0, 0.049], req)


def _touches(probe, obj, p, req) -> bool:
    probe.setTranslation(np.asarray(p, float))
    return bool(fcl.collide(probe, obj, req, fcl.CollisionResult()))


def test_the_octree_marks_the_leaves_the_margin_reaches(rv2aj):
    grid = OctreeGrid.for_leaf(size=0.8, leaf=0.05)
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.02)

    def cells(margin):
        ob = Obstacle("b", make_T(p=[0.1, 0.1, 0.1]),
                      (CollisionShape(ShapeKind.MESH, mesh=ball, margin=margin),))
        return set(obstacle_cells(grid, ob).tolist())

    bare, grown = cells(0.0), cells(0.03)
    assert bare < grown  # more leaves, and every leaf of the bare ball still
