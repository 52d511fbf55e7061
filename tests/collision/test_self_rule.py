"""The one self-collision rule per robot model (`collision.self_rule`)."""

from __future__ import annotations

import fcl
import numpy as np
import pytest

from assistant.collision.checker import CollisionChecker
from assistant.collision.fcl_shapes import fcl_geometry, fcl_transform
from assistant.collision.self_rule import (
    PairReason,
    SelfCollisionRule,
    compute_rule,
    link_words,
    self_collision_rule,
)
from assistant.robots.catalog import installed_robot_urdf
from assistant.robots.model import Tool
from assistant.robots.urdf_robot import URDFRobot
from assistant.world.chain_levels import LinkSubsetRobot


@pytest.fixture(scope="module")
def ur5() -> URDFRobot:
    urdf, share = installed_robot_urdf("example-robot-data/robots/ur_description/urdf/"
                                       "ur5_robot.urdf")
    return URDFRobot.from_file(urdf, package_dirs=[share], load_visual=False).with_tool(
        Tool.straight(0.1))


def brute_force(robot, n: int, near: float, seed: int) -> set[tuple[int, int, int, int]]:
    """Every candidate shape pair, every sample through FCL: the checked shape pairs."""
    shapes = [(li, k, s) for li, lk in enumerate(robot.links) for k, s in enumerate(lk.collision)]
    rng = np.random.default_rng(seed)
    lim = robot.model_limits
    frames = robot.batch_link_poses(rng.uniform(lim.lower, lim.upper, (n, robot.dof)))
    objs = [fcl.CollisionObject(fcl_geometry(s)) for _, _, s in shapes]
    out = set()
    for i in range(len(shapes)):
        for j in range(i + 1, len(shapes)):
            la, lb = shapes[i][0], shapes[j][0]
            if la == lb or abs(la - lb) == 1:
                continue
            hits, closest = 0, np.inf
            for k in range(n):
                objs[i].setTransform(fcl_transform(frames[k, la] @ shapes[i][2].T_link_shape))
                objs[j].setTransform(fcl_transform(frames[k, lb] @ shapes[j][2].T_link_shape))
                if fcl.collide(objs[i], objs[j], fcl.CollisionRequest(), fcl.CollisionResult()):
                    hits += 1
                    closest = 0.0
                else:
                    closest = min(closest, fcl.distance(objs[i], objs[j], fcl.DistanceRequest(),
                                                        fcl.DistanceResult()))
            if hits < n and closest < near:
                out.add((la, shapes[i][1], lb, shapes[j][1]))
    return out


def test_the_sphere_bounds_give_the_brute_force_pairs(ur5, rv2aj):
    """Skipping the FCL calls the covering spheres rule out changes no decision."""
    for robot in (ur5, rv2aj):
        rule = compute_rule(robot, n=150, seed=7)
        assert set(rule.shape_pairs) == brute_force(robot, 150, rule.near, 7)


def test_narrowing_the_limits_checks_the_same_pairs(ur5):
    """The rule is the model's: an operator's narrower limits (+-30 deg around a posture)
    sample a smaller space where more pairs look 'never', yet the checker keeps them all."""
    q = np.radians([0.0, -60.0, 90.0, -120.0, -90.0, 0.0])
    narrow = ur5.with_limits(np.column_stack([q - np.radians(30), q + np.radians(30)]))
    assert narrow.description_hash() != ur5.description_hash()
    assert narrow.rule_key() == ur5.rule_key()
    assert CollisionChecker(narrow, ()).self_pairs == CollisionChecker(ur5, ()).self_pairs


def test_a_view_of_some_links_checks_the_whole_robots_pairs_among_them(ur5):
    full = CollisionChecker(ur5, ())
    keep = {0, 1, 4, 5, 6}
    view = CollisionChecker(LinkSubsetRobot(ur5, keep, "view"), ())
    names = [lk.name for lk in ur5.links]
    expected = [p for p in full.self_pairs
                if names.index(p[0]) in keep and names.index(p[1]) in keep]
    assert view.self_pairs == expected and expected


def test_the_rule_is_kept_on_disk_and_read_back(ur5, tmp_path):
    from assistant.collision import self_rule

    self_rule._MEMORY.pop(ur5.rule_key(), None)
    rule = self_collision_rule(ur5, cache_dir=tmp_path)
    files = list(tmp_path.glob("rule-*.json"))
    assert len(files) == 1
    import json

    assert SelfCollisionRule.from_json(json.loads(files[0].read_text())) == rule
    files[0].write_text("{not json")  # a damaged file is computed again, not trusted
    self_rule._MEMORY.pop(ur5.rule_key())
    assert self_collision_rule(ur5, cache_dir=tmp_path) == rule


def test_every_pair_has_a_decision_said_in_the_operators_words(ur5):
    rule = self_collision_rule(ur5)
    n = sum(1 for lk in ur5.links if lk.collision)
    assert len(rule.pairs) == n * (n - 1) // 2
    assert rule.reason(1, 2) == PairReason.ADJACENT
    words = link_words(ur5)
    assert words[0].startswith("the base (") and words[3] == "the J3 link (forearm_link)"
    assert words[-1] == "the J6 link and tool (wrist_3_link)"
    text = "\n".join(rule.lines(words))
    assert "joined by a joint: the base (world) - the J1 link (shoulder_link)" in text
    assert f"never within 30 mm in {rule.samples} random postures" in text
