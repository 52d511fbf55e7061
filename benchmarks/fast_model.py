"""How tight the fast conservative collision model is, per arm.

    python benchmarks/fast_model.py [--postures N]

Arms: UR5, UR10, Panda (example-robot-data), the RV-2AJ and the KUKA KR 6 R900 sixx of the
robot catalogue, each with a 100 mm tool. Per arm:

* volume ratio: the volume of each shape's capsules (their union, by Monte Carlo with
  `capsule_cover.union_volumes`) over the shape's own (a closed mesh's volume, else its
  convex hull's; primitives exactly), summed over the arm;
* on N uniform postures within the limits, in a cell of a table and six boxes within reach
  (the shape of `tests/collision/test_fast_model.py`'s): brute-force FCL's answer
  (`in_collision_naive`) against the fast model's - false collisions (free postures the
  model calls collisions, as a share of the free ones) and unsound answers (collisions the
  model calls free: must be 0) - and both checkers' time a posture in batches.

The exact checker of a mesh arm asks the fast model first, so its time here is the one the
planners see; brute force is the reference. The final line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from assistant.collision.capsule_cover import union_volumes  # noqa: E402
from assistant.collision.checker import CollisionChecker  # noqa: E402
from assistant.collision.fast_model import fast_robot  # noqa: E402
from assistant.collision.reports import Obstacle  # noqa: E402
from assistant.robots.catalog import RobotSpec, installed_robot_urdf  # noqa: E402
from assistant.robots.model import CollisionShape, ShapeKind, Tool  # noqa: E402
from assistant.robots.rv2aj import RV2AJ, RV2AJConfig  # noqa: E402
from assistant.robots.urdf_robot import URDFRobot  # noqa: E402
from assistant.transforms import make_T, rot_z  # noqa: E402
from assistant.world.model import tcp_reach  # noqa: E402

URDFS = {
    "UR5": ("example-robot-data/robots/ur_description/urdf/ur5_robot.urdf", "tool0"),
    "UR10": ("example-robot-data/robots/ur_description/urdf/ur10_robot.urdf", "tool0"),
    "Panda": ("example-robot-data/robots/panda_description/urdf/panda.urdf", "panda_hand"),
}
ARMS = ("UR5", "UR10", "Panda", "RV-2AJ", "KUKA KR 6")


def load(name: str):
    if name == "RV-2AJ":
        return RV2AJ(RV2AJConfig(tool=Tool.straight(0.1)))
    if name == "KUKA KR 6":
        return RobotSpec(kind="kuka_kr6_r900_sixx").build().with_tool(Tool.straight(0.1))
    rel, tip = URDFS[name]
    path, share = installed_robot_urdf(rel)
    return URDFRobot.from_file(path, package_dirs=[share], tool_link=tip,
                               load_visual=False).with_tool(Tool.straight(0.1))


def shape_volume(shape: CollisionShape) -> float:
    if shape.kind == ShapeKind.MESH:
        m = shape.mesh
        assert m is not None
        return float(m.volume if m.is_volume else m.convex_hull.volume)
    r = float(shape.size[0])
    if shape.kind == ShapeKind.SPHERE:
        return 4.0 / 3.0 * np.pi * r ** 3
    if shape.kind == ShapeKind.BOX:
        return float(np.prod(shape.size))
    if shape.kind == ShapeKind.CYLINDER:
        return np.pi * r * r * float(shape.size[1])
    return np.pi * r * r * float(shape.size[1]) + 4.0 / 3.0 * np.pi * r ** 3


def cell(robot) -> list[Obstacle]:
    reach = tcp_reach(robot)
    rng = np.random.default_rng(11)
    obs = [Obstacle("table", make_T(p=(0.0, 0.0, -0.011)),
                    (CollisionShape(ShapeKind.BOX, (3.0, 3.0, 0.02)),))]
    for k in range(6):
        r, a = rng.uniform(0.35, 0.8) * reach, rng.uniform(-np.pi, np.pi)
        size = tuple(rng.uniform(0.05, 0.2, 3) * [1.0, 1.0, 2.0])
        obs.append(Obstacle(f"B{k + 1}", make_T(rot_z(rng.uniform(0, np.pi)),
                                                 (r * np.cos(a), r * np.sin(a), size[2] / 2)),
                            (CollisionShape(ShapeKind.BOX, size),)))
    return obs


def measure(name: str, n: int) -> dict:
    robot = load(name)
    t0 = time.perf_counter()
    fr = fast_robot(robot)
    fit_s = time.perf_counter() - t0
    assert fr is not None
    caps_vol = real_vol = 0.0
    i = 0
    for link in robot.links:
        for shape in link.collision:
            caps = [(c.a, c.b, c.r) for c in (fr.capsules[f] for f in
                                              np.flatnonzero(fr.owner == i).tolist())]
            caps_vol += union_volumes([caps])[0]
            real_vol += shape_volume(shape)
            i += 1
    exact = CollisionChecker(robot, cell(robot))
    t0 = time.perf_counter()
    fast = exact.fast
    model_s = time.perf_counter() - t0
    rng = np.random.default_rng(5)
    Q = rng.uniform(robot.limits.lower, robot.limits.upper, size=(n, robot.dof))
    t0 = time.perf_counter()
    truth = np.array([exact.in_collision_naive(q) for q in Q])
    naive_s = (time.perf_counter() - t0) / n
    fast.in_collision_batch(Q[:8])  # tables and kernels warm
    t0 = time.perf_counter()
    said = fast.in_collision_batch(Q)
    fast_s = (time.perf_counter() - t0) / n
    exact_only = exact.exact_only()
    t0 = time.perf_counter()
    exact_only.in_collision_batch(Q)
    exact_s = (time.perf_counter() - t0) / n
    free = ~truth
    return {"shapes": i, "capsules": len(fr.capsules),
            "volume_ratio": caps_vol / real_vol,
            "postures": n, "free_share": float(free.mean()),
            "false_collision_rate": float((said & free).sum() / max(1, free.sum())),
            "unsound": int((~said & truth).sum()),
            "fit_s": fit_s, "model_build_s": model_s,
            "us_per_posture": {"fast_model": fast_s * 1e6, "exact_checker": exact_s * 1e6,
                               "brute_force_fcl": naive_s * 1e6}}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--postures", type=int, default=2000)
    ap.add_argument("--arms", default=",".join(ARMS))
    args = ap.parse_args()
    out = {}
    for name in args.arms.split(","):
        f = measure(name, args.postures)
        out[name] = f
        t = f["us_per_posture"]
        print(f"{name:10s} {f['capsules']:2d} capsules for {f['shapes']:2d} shapes  volume "
              f"x{f['volume_ratio']:.2f}  free {f['free_share']:.0%}  false collisions "
              f"{f['false_collision_rate']:.1%}  unsound {f['unsound']}  | us/posture fast "
              f"{t['fast_model']:.0f}, exact {t['exact_checker']:.0f}, brute force "
              f"{t['brute_force_fcl']:.0f}")
    print(json.dumps({"benchmark": "fast_model", "arms": out,
                      "sound": all(f["unsound"] == 0 for f in out.values())}, sort_keys=True))


if __name__ == "__main__":
    main()
