"""The fast conservative collision model against the real shapes and FCL.

What must hold for every arm the project ships or tests with (UR5, UR10, Panda from
example-robot-data, the RV-2AJ, the KUKA KR 6 R900 sixx of the robot catalogue):

* the capsule cover contains every vertex of every link's shape (meshes: their vertices and
  points sampled on their faces; primitives: dense points of their surfaces) with the stated
  padding `capsule_cover.PAD`;
* on uniform random postures in a cell, every posture the fast model calls free is free for
  brute-force FCL on the robot's own shapes and forward kinematics (`in_collision_naive`),
  and so is every posture within its margin of arm travel;
* its clearance is a lower bound of the exact one.

How tight it is (volume ratio, false collisions) is reported by `benchmarks/fast_model.py`.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from assistant.collision.broad_phase import _segment_segment_distance
from assistant.collision.capsule_cover import PAD
from assistant.collision.checker import CollisionChecker
from assistant.collision.fast_model import fast_robot
from assistant.collision.reports import Obstacle
from assistant.robots.catalog import RobotSpec, installed_robot_urdf
from assistant.robots.model import CollisionShape, ShapeKind, Tool
from assistant.robots.rv2aj import RV2AJ, RV2AJConfig
from assistant.robots.urdf_robot import URDFRobot
from assistant.transforms import make_T, rot_z

URDFS = {
    "UR5": ("example-robot-data/robots/ur_description/urdf/ur5_robot.urdf", "tool0"),
    "UR10": ("example-robot-data/robots/ur_description/urdf/ur10_robot.urdf", "tool0"),
    "Panda": ("example-robot-data/robots/panda_description/urdf/panda.urdf", "panda_hand"),
}
ARMS = ("UR5", "UR10", "Panda", "RV-2AJ", "KUKA KR 6")
#: Distances here are a few 4x4 products and a square root of metre-sized coordinates:
#: rounding stays below 1e-15 m per operation, so 1e-12 m is a thousandfold allowance and
#: still ten million times smaller than the padding it checks.
ROUNDING = 1e-12


def _arm(name: str):
    if name == "RV-2AJ":
        return RV2AJ(RV2AJConfig(tool=Tool.straight(0.1)))
    if name == "KUKA KR 6":
        return RobotSpec(kind="kuka_kr6_r900_sixx").build().with_tool(Tool.straight(0.1))
    rel, tip = URDFS[name]
    path, share = installed_robot_urdf(rel)
    return URDFRobot.from_file(path, package_dirs=[share], tool_link=tip,
                               load_visual=False).with_tool(Tool.straight(0.1))


@pytest.fixture(scope="module", params=ARMS)
def arm(request):
    return _arm(request.param)


def _surface_points(shape: CollisionShape, rng: np.random.Generator) -> np.ndarray:
    """Points of the shape's surface in its link frame: a mesh's vertices and points
    sampled on its faces; a primitive's surface, densely (every point of a polygonal
    approximation whose vertices lie on the surface)."""
    k = shape.kind
    if k == ShapeKind.MESH:
        m = shape.mesh
        assert m is not None
        P = np.concatenate([np.asarray(m.vertices, dtype=float),
                            trimesh.sample.sample_surface(m, 3000, seed=int(rng.integers(1e9)))[0]])
    elif k == ShapeKind.BOX:
        s = np.asarray(shape.size, dtype=float) / 2.0
        P = np.array([[x, y, z] for x in (-s[0], s[0]) for y in (-s[1], s[1])
                      for z in (-s[2], s[2])])
    elif k == ShapeKind.CYLINDER:
        P = trimesh.creation.cylinder(radius=shape.size[0], height=shape.size[1],
                                      sections=720).vertices
    elif k == ShapeKind.CAPSULE:
        P = trimesh.creation.capsule(height=shape.size[1], radius=shape.size[0],
                                     count=[128, 64]).vertices
    else:
        P = trimesh.creation.icosphere(subdivisions=4, radius=shape.size[0]).vertices
    T = np.asarray(shape.T_link_shape, dtype=float)
    return np.asarray(P, dtype=float) @ T[:3, :3].T + T[:3, 3]


def test_capsule_cover_contains_every_vertex_with_the_padding(arm):
    fr = fast_robot(arm)
    assert fr is not None, f"{arm.name}: no fast model"
    rng = np.random.default_rng(3)
    i = 0
    checked = 0
    for k, link in enumerate(arm.links):
        to_fast = fr.to_fast[k]
        for shape in link.collision:
            caps = [fr.capsules[f] for f in np.flatnonzero(fr.owner == i).tolist()]
            assert caps, f"{arm.name} {link.name}: a shape without capsules"
            P = _surface_points(shape, rng) @ to_fast[:3, :3].T + to_fast[:3, 3]
            # every point: inside some capsule by at least the padding
            depth = np.full(len(P), -np.inf)
            for c in caps:
                d = np.array([_segment_segment_distance(p, p, c.a, c.b) for p in P])
                depth = np.maximum(depth, c.r - d)
            worst = int(np.argmin(depth))
            assert depth[worst] >= PAD - ROUNDING, (
                f"{arm.name} {link.name}: a surface point {depth[worst] * 1000:.4f} mm inside "
                f"its capsules (at least {PAD * 1000:.4f} mm stated)")
            checked += len(P)
            i += 1
    assert set(fr.owner.tolist()) == set(range(i)) and checked > 0


def _cell(arm) -> list[Obstacle]:
    """A table under the base and boxes within reach, standing where uniform postures
    pass them closely; two of the boxes with a margin (`CollisionShape.margin`: everything
    within it counts as the obstacle)."""
    from assistant.world.model import tcp_reach

    reach = tcp_reach(arm)
    rng = np.random.default_rng(11)
    obs = [Obstacle("table", make_T(p=(0.0, 0.0, -0.011)),
                    (CollisionShape(ShapeKind.BOX, (3.0, 3.0, 0.02)),))]
    for k in range(6):
        r, a = rng.uniform(0.35, 0.8) * reach, rng.uniform(-np.pi, np.pi)
        size = tuple(rng.uniform(0.05, 0.2, 3) * [1.0, 1.0, 2.0])
        obs.append(Obstacle(f"B{k + 1}", make_T(rot_z(rng.uniform(0, np.pi)),
                                                 (r * np.cos(a), r * np.sin(a), size[2] / 2)),
                            (CollisionShape(ShapeKind.BOX, size,
                                            margin=0.03 if k in (1, 4) else 0.0),)))
    return obs


@pytest.fixture(scope="module")
def checkers(arm):
    exact = CollisionChecker(arm, _cell(arm))
    fast = exact.fast
    assert fast is not None
    return exact, fast


def _uniform_postures(arm, exact, rng, free: int = 30, most: int = 4000):
    """Uniform postures within the limits, 400 at a time until `free` of them are free
    (the KUKA's upper arm meets the table in ~97 % of its range), and brute-force FCL's
    answer for each."""
    lim = arm.limits
    Qs, hits = [], []
    while sum(len(h) - h.sum() for h in hits) < free and sum(map(len, hits)) < most:
        Q = rng.uniform(lim.lower, lim.upper, size=(400, arm.dof))
        Qs.append(Q)
        hits.append(np.array([exact.in_collision_naive(q) for q in Q]))
    Q, truth = np.concatenate(Qs), np.concatenate(hits)
    # both outcomes must be there in number, or the comparison proves little
    assert (~truth).sum() >= free and truth.sum() >= free, truth.mean()
    return Q, truth


def test_every_posture_the_fast_model_calls_free_is_free_for_fcl(arm, checkers):
    exact, fast = checkers
    rng = np.random.default_rng(5)
    lim = arm.limits
    Q, truth = _uniform_postures(arm, exact, rng)
    said_free = ~fast.in_collision_batch(Q)
    assert not (said_free & truth).any(), np.flatnonzero(said_free & truth)
    ok, margin = fast.is_valid_batch_margin(Q)
    assert not (ok & truth).any()
    assert np.array_equal(ok, said_free)  # the same model behind both questions
    # the samples of motions (the planners' question) likewise
    Q1 = np.clip(Q + rng.normal(scale=0.3, size=Q.shape), lim.lower, lim.upper)
    f = (np.arange(9) / 8)[None, :, None]
    rows = (Q[:60, None] + f * (Q1 - Q)[:60, None]).reshape(-1, arm.dof)
    groups = np.repeat(np.arange(60), 9)
    ok_rows = fast.is_valid_samples(rows, groups)
    for r in np.flatnonzero(ok_rows).tolist():
        assert not exact.in_collision_naive(rows[r]), r
    # a posture within its margin of arm travel of a free one is free: move every free
    # posture of the batch by 90 % of its margin in a random direction of joint space
    free = np.flatnonzero(ok & np.isfinite(margin) & (margin > 0))
    # (the KUKA's upper arm and forearm stay within millimetres of each other near the
    # elbow: its free postures are FCL's answers, with no margin to certify neighbours)
    assert len(free) > 20 or not exact._has_mesh
    d = rng.normal(size=(len(free), arm.dof))
    t = fast.travel(np.zeros((len(free), arm.dof)), d)
    Qm = Q[free] + d * (0.9 * margin[free] / t)[:, None]
    inside = lim.contains_batch(Qm)
    for q in Qm[inside]:
        assert not exact.in_collision_naive(q)
    # how often the model calls a free posture a collision (reported, not a target here;
    # benchmarks/fast_model.py gives it per arm)
    assert (~said_free & ~truth).sum() <= (~truth).sum()


def _free_postures(arm, exact, *, seed: int, most: int, least: int) -> np.ndarray:
    """Up to `most` free postures among 2000 uniform ones (at least `least`)."""
    lim = arm.limits
    Q = np.random.default_rng(seed).uniform(lim.lower, lim.upper, size=(2000, arm.dof))
    Q = Q[exact.is_valid_batch(Q)][:most]
    assert len(Q) >= least
    return Q


def test_the_fast_clearance_is_a_lower_bound_of_the_exact_one(arm, checkers):
    exact, fast = checkers
    for q in _free_postures(arm, exact, seed=9, most=25, least=10):
        lb = fast.min_clearance_along(q[None])
        true = exact.min_clearance_along(q[None])
        # FCL's distances between a mesh and a box are exact up to its GJK tolerance,
        # 1e-6 m; ours are closed forms (rounding ~1e-15 m)
        assert lb <= true + 1e-6, (lb, true)


def test_keeps_clearance_is_the_exact_clearance_decision(arm, checkers):
    """`keeps_clearance` (face planes, capsule bounds, then FCL) decides as the exact
    clearance of the real shapes does, for targets on either side of it - so the face-plane
    shortcut never passes a pair that is nearer than the target. Above the proven floor of
    the links the model leaves out of its obstacle checks it refuses, and an arm of round
    shapes is decided by its capsules' lower bound (both conservative: never a pass)."""
    exact, fast = checkers
    Q = _free_postures(arm, exact, seed=11, most=80, least=20)
    trues = np.array([exact.min_clearance_along(q[None]) for q in Q])
    order = np.argsort(trues)  # the 12 nearest (refusals below the floor) and 8 others
    decided = []
    for i in np.concatenate([order[:12], order[12::9][:8]]).tolist():
        q, true = Q[i], float(trues[i])
        # FCL's mesh-box distances are exact to its GJK tolerance (1e-6 m): targets 1 mm
        # either side of the true clearance are decided the same by any exact method
        for target in (true - 1e-3, true + 1e-3, 0.01, 0.05):
            if target <= 0.0 or abs(target - true) < 1e-5:
                continue
            got = fast.keeps_clearance(q[None], target)
            if target > fast._env_floor:
                assert not got, (q, true, target)
                continue
            if not fast.exact._has_mesh:  # round shapes: the capsules' own lower bound
                assert not got or true >= target, (q, true, target)
                decided.append(true >= target)
                continue
            assert got == (true >= target), (q, true, target)
            decided.append(got)
    assert any(decided) and not all(decided)  # both answers were asked for


def test_the_exact_view_never_asks_the_fast_model(arm, checkers, monkeypatch):
    """What certifies a path (`CollisionChecker.exact_only`) answers by FCL on the robot's
    own kinematics even when the fast model is wrong."""
    exact, fast = checkers
    view = exact.exact_only()
    rng = np.random.default_rng(13)
    lim = arm.limits
    Q = rng.uniform(lim.lower, lim.upper, size=(120, arm.dof))
    truth = np.array([exact.in_collision_naive(q) for q in Q])
    assert truth.any()
    monkeypatch.setattr(type(fast), "in_collision_batch",
                        lambda self, Q: np.zeros(len(np.atleast_2d(Q)), dtype=bool))
    monkeypatch.setattr(type(fast), "is_valid_samples",
                        lambda self, Q, groups=None, **k: np.ones(len(Q), dtype=bool))
    assert np.array_equal(view.in_collision_batch(Q), truth)
    assert np.array_equal(~view.is_valid_samples(Q, np.arange(len(Q))) & lim.contains_batch(Q),
                          truth & lim.contains_batch(Q))


def test_the_compiled_frames_are_the_robots_own(arm, checkers):
    """The checker of a mesh arm poses its shapes from the fast model's compiled chain
    (`CollisionChecker._link_frames`); they are the robot's own frames."""
    exact, _ = checkers
    rng = np.random.default_rng(17)
    Q = rng.uniform(arm.limits.lower, arm.limits.upper, size=(200, arm.dof))
    # seven or eight 4x4 products of metre-sized transforms, composed in another order
    # (URDF joint frames turned so each axis is z): ~1e-11 m seen; 1e-9 m allowed, a
    # thousandth of FCL's own tolerance
    assert np.abs(exact._link_frames(Q) - arm.batch_link_poses(Q)).max() <= 1e-9
