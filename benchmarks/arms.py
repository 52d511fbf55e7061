"""6- and 7-axis arms at their own joint limits: our world model and planner vs two peers.

    python benchmarks/arms.py [--quick] [--cells N] [--seed S]

Robots: UR5 and UR10 (6 axes, +-360 deg) and Franka Panda (7 axes) from example-robot-data,
each with a 100 mm tool, at the limits their URDFs state. Cells (fixed seeds): a table, 3-8
boxes within the arm's reach, and a wall between the start side and the goal side. Queries as
an operator would teach them: TCP points above the table, tool pointing down, solved by IK
from the robot's home posture; valid, at least 25 cm apart. The taught postures are the
world's anchors, as the session passes them (`WorldModel.anchors`).

The compiled kernels are loaded before any timing (once per process; the first plan of a new
process is `cold_start.py`'s figure). Per robot: world build time (joint samples from the
disk cache after the first build of a robot) and peak memory growth, success, median / p95
query time (ours: roadmap + smoothing + verification, `MissionPlanner.plan_transfer`; OMPL:
RRTConnect + simplifySolution on the same checker; roboplan: RRT-Connect + its shortcutting
on its own scene of the same cell, see `roboplan_peer`), TCP length, primitives, min
clearance, re-plan after one indication in the middle of our path (until a collision-free
joint path exists). Every peer path is checked again with our checker; roboplan's paths that
it refuses count as failures ("refused"). Without roboplan installed the run says so in one
line and compares ours with OMPL only. For scale: VAMP (Thomason et al. 2024) publishes a 35
us median for a Panda on one desktop core, geometric planning with sphere models and no mesh
verification.

The final line is one JSON object with the figures, the targets and which were met
(`arms_criteria`: a robot whose cells gave no valid query fails every query criterion and
is reported as "no queries", never counted as a pass). Figures measured with it are in
docs/benchmarks.md with the command and date of the run.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import resource
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
import roboplan_peer  # noqa: E402
from arms_criteria import TARGETS, met  # noqa: E402
from planning import OmplPlanner, Result, med, run_ours, synthetic_replan  # noqa: E402

from assistant.collision.checker import CollisionChecker  # noqa: E402
from assistant.collision.reports import Obstacle  # noqa: E402
from assistant.planning import MissionPlanner  # noqa: E402
from assistant.roadmap.planner import RoadmapPlanner  # noqa: E402
from assistant.robots.catalog import installed_robot_urdf  # noqa: E402
from assistant.robots.model import CollisionShape, Robot, ShapeKind, Tool  # noqa: E402
from assistant.robots.urdf_robot import URDFRobot  # noqa: E402
from assistant.session.home import raised_posture  # noqa: E402
from assistant.transforms import make_T, rot_x, rot_z  # noqa: E402
from assistant.world.model import WorldConfig, WorldModel, tcp_reach  # noqa: E402

ROBOTS = {
    "UR5": ("example-robot-data/robots/ur_description/urdf/ur5_robot.urdf", "tool0"),
    "UR10": ("example-robot-data/robots/ur_description/urdf/ur10_robot.urdf", "tool0"),
    "Panda": ("example-robot-data/robots/panda_description/urdf/panda.urdf", "panda_hand"),
}
VAMP_PANDA_MEDIAN_S = 35e-6


def load_robot(name: str) -> Robot:
    rel, tip = ROBOTS[name]
    path, share = installed_robot_urdf(rel)
    return URDFRobot.from_file(path, package_dirs=[share], tool_link=tip).with_tool(
        Tool.straight(0.1))


def box(name: str, c, size, yaw: float = 0.0) -> Obstacle:
    return Obstacle(name, make_T(rot_z(yaw), np.asarray(c, float)),
                    (CollisionShape(ShapeKind.BOX, tuple(size)),))


def cell(robot: Robot, reach: float, seed: int, n_queries: int):
    rng = np.random.default_rng(seed)
    obstacles = [box("table", (0.0, 0.0, -0.011), (3.0, 3.0, 0.02)),
                 box("wall", (0.55 * reach, 0.0, 0.15 * reach), (0.25 * reach, 0.03, 0.3 * reach))]
    for k in range(int(rng.integers(3, 9))):
        r, a = rng.uniform(0.35, 0.8) * reach, rng.uniform(-np.pi, np.pi)
        size = (rng.uniform(0.05, 0.15), rng.uniform(0.05, 0.15), rng.uniform(0.06, 0.3))
        obstacles.append(box(f"B{k + 1}", (r * np.cos(a), r * np.sin(a), size[2] / 2.0), size,
                             rng.uniform(0, np.pi)))
    checker = CollisionChecker(robot, obstacles)
    home = raised_posture(robot)
    poses = []
    for _ in range(400):
        if len(poses) >= 2 * n_queries:
            break
        r, a = rng.uniform(0.35, 0.75) * reach, rng.uniform(-np.radians(150), np.radians(150))
        p = np.array([r * np.cos(a), r * np.sin(a), rng.uniform(0.1, 0.45) * reach])
        res = robot.ik(make_T(rot_x(np.pi) @ rot_z(a), p), home)
        if not res.ok:
            continue
        q = np.asarray(res.best(home), float)
        if checker.is_valid(q):
            poses.append(q)
    queries = []
    for qa, qb in zip(poses[0::2], poses[1::2], strict=False):
        P = robot.batch_fk(np.array([qa, qb])).positions
        if np.linalg.norm(P[0] - P[1]) >= 0.25:
            queries.append((qa, qb))
    return obstacles, checker, queries


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def p95(v: list[float]) -> float:
    v = [x for x in v if np.isfinite(x)]
    return float(np.percentile(v, 95)) if v else float("nan")


def peer_figures(peer: list[Result], ours: list[Result]) -> dict:
    """Success and times over all queries; path figures where ours and the peer both
    succeeded (the same queries for both, as for OMPL)."""
    both = [b for a, b in zip(ours, peer, strict=True) if a.ok and b.ok]
    times = [r.seconds for r in peer if r.ok]
    return {"success": sum(r.ok for r in peer) / max(1, len(peer)),
            "median_query_s": med(times), "p95_query_s": p95(times),
            "median_tcp_m": med([b.tcp_length for b in both]),
            "median_primitives": med([float(b.primitives) for b in both]),
            "median_min_clearance_mm": med([b.clearance * 1000 for b in both])}


def fmt(r: Result) -> str:
    return (f"{'yes' if r.ok else 'NO':4s} {r.seconds:6.2f} s {r.tcp_length:6.3f} m "
            f"{r.primitives:3d} prim {r.clearance * 1000:6.1f} mm")


def run_robot(name: str, n_cells: int, n_queries: int, seed: int, ompl_limit: float) -> dict:
    robot = load_robot(name)
    reach = tcp_reach(robot)
    builds, peaks, ours, ompl, replans, rows = [], [], [], [], [], []
    rplan: list[Result] = []
    rplan_default: list[Result] = []  # the same at roboplan's default edge-check step
    agreement: list[float] = []
    scene_parts: dict = {}
    use_rp = roboplan_peer.available()
    for c in range(n_cells):
        obstacles, checker, queries = cell(robot, reach, seed + c, n_queries)
        world = WorldModel(robot, obstacles, WorldConfig.for_robot(robot))
        world.anchors = np.array([q for pair in queries for q in pair]) if queries else None
        rp = RoadmapPlanner(robot, checker, world)
        m0 = peak_mb()
        t0 = time.perf_counter()
        rp.build()
        builds.append(time.perf_counter() - t0)
        peaks.append(peak_mb() - m0)
        mp = MissionPlanner(robot, obstacles, world, rp, checker)
        peer = OmplPlanner(robot, checker, ompl_limit)
        rpp = (roboplan_peer.RoboplanPlanner(robot, obstacles, checker, ompl_limit, seed + c)
               if use_rp else None)
        rpd = None
        if rpp is not None:
            agreement.append(rpp.agreement(300, seed + c))
            scene_parts = dataclasses.asdict(rpp.report)
            rpd = roboplan_peer.RoboplanPlanner(robot, obstacles, checker, ompl_limit, seed + c,
                                                step=roboplan_peer.default_step())
        done = []
        for qa, qb in queries:
            a = run_ours(mp, qa, qb)
            b = peer.plan(qa, qb)
            r = rpp.plan(qa, qb) if rpp is not None else None
            ours.append(a)
            ompl.append(b)
            if r is not None and rpd is not None:
                rplan.append(r)
                rplan_default.append(rpd.plan(qa, qb))
            rows.append((name, c, a, b, r))
            done.append((qb, a))
        for qb, a in done:
            if a.ok and len(a.extra["dense"]) > 8:
                r = synthetic_replan(mp, a.extra["dense"], qb, smooth=False)
                if r is not None:
                    replans.append(r[0])
    both = [(a, b) for a, b in zip(ours, ompl, strict=True) if a.ok and b.ok]
    times = [r.seconds for r in ours if r.ok]
    for robot_name, c, a, b, r in rows:
        why = "" if a.ok else f"  ({a.extra.get('reason', '')})"
        third = "" if r is None else f" | roboplan {fmt(r)}"
        if r is not None and not r.ok:
            why += f"  (roboplan: {r.extra.get('status', '')})"
        print(f"{robot_name:6s} cell {c} | ours {fmt(a)} | OMPL {fmt(b)}{third}{why}")
    so = sum(r.ok for r in ours) / max(1, len(ours))
    sp = sum(r.ok for r in ompl) / max(1, len(ompl))
    rp_fig: dict = {"installed": False, "reason": roboplan_peer.IMPORT_ERROR}
    if use_rp:
        rp_fig = {"installed": True, "version": roboplan_peer.version(),
                  **peer_figures(rplan, ours),
                  "refused_by_our_checker": sum(bool(r.extra.get("refused")) for r in rplan),
                  "returned_paths": sum(r.ok or bool(r.extra.get("refused")) for r in rplan),
                  "scene_agreement": min(agreement, default=float("nan")),
                  "scene_last_cell": scene_parts,
                  "edge_check_step_rad": roboplan_peer.STEP,
                  "at_default_step": {
                      "edge_check_step_rad": roboplan_peer.default_step(),
                      "success": sum(r.ok for r in rplan_default) / max(1, len(rplan_default)),
                      "median_query_s": med([r.seconds for r in rplan_default if r.ok]),
                      "refused_by_our_checker": sum(bool(r.extra.get("refused"))
                                                    for r in rplan_default)}}
    summary = [("ours", {"success": so, "median_query_s": med(times), "p95_query_s": p95(times),
                         "median_tcp_m": med([a.tcp_length for a, _ in both]),
                         "median_min_clearance_mm": med([a.clearance * 1000 for a, _ in both])}),
               ("OMPL", peer_figures(ompl, ours))]
    if use_rp:
        summary.append(("roboplan", rp_fig))
    for who, s in summary:
        extra = ""
        if who == "roboplan":
            extra = (f", {s['refused_by_our_checker']} of {s['returned_paths']} returned paths "
                     f"refused by our checker, scene agrees with ours on "
                     f"{100 * s['scene_agreement']:.1f} % of postures; at its default "
                     f"step {s['at_default_step']['edge_check_step_rad']:g} rad: success "
                     f"{100 * s['at_default_step']['success']:.1f} %, "
                     f"{s['at_default_step']['refused_by_our_checker']} refused")
        print(f"{name:6s} {who:9s} success {100 * s['success']:5.1f} %  median "
              f"{s['median_query_s'] * 1000:8.1f} ms  p95 {s['p95_query_s'] * 1000:8.1f} ms  "
              f"TCP {s['median_tcp_m']:6.3f} m  min clearance "
              f"{s['median_min_clearance_mm']:6.1f} mm{extra}")
    return {
        "dof": robot.dof, "queries": len(ours), "world_build_s": med(builds),
        "world_build_max_s": max(builds, default=float("nan")),
        "world_peak_mb": max(peaks, default=float("nan")),
        "ours": {"success": so, "median_query_s": med(times),
                 "p95_query_s": p95(times),
                 "median_tcp_m": med([a.tcp_length for a, _ in both]),
                 "median_primitives": med([float(a.primitives) for a, _ in both]),
                 "median_min_clearance_mm": med([a.clearance * 1000 for a, _ in both]),
                 "replan_median_s": med(replans), "replans": len(replans)},
        "ompl_rrtconnect_simplified": {
            "success": sp, "median_query_s": med([r.seconds for r in ompl if r.ok]),
            "p95_query_s": p95([r.seconds for r in ompl if r.ok]),
            "median_tcp_m": med([b.tcp_length for _, b in both]),
            "median_primitives": med([float(b.primitives) for _, b in both]),
            "median_min_clearance_mm": med([b.clearance * 1000 for _, b in both])},
        "roboplan": rp_fig,
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="1 cell, 2 queries per robot")
    ap.add_argument("--cells", type=int, default=None, help="cells per robot (default 3)")
    ap.add_argument("--seed", type=int, default=300)
    ap.add_argument("--robots", default=",".join(ROBOTS))
    args = ap.parse_args()
    n_cells = args.cells if args.cells is not None else (1 if args.quick else 3)
    n_queries = 2 if args.quick else 4

    from ompl import util as ou

    ou.setLogLevel(ou.LOG_NONE)
    ou.RNG.setSeed(args.seed)
    if roboplan_peer.available():
        print(f"roboplan peer: roboplan {roboplan_peer.version()}, RRT-Connect + shortcutting "
              "on its own scene of the same cell, paths checked again by ours")
    else:
        print(f"roboplan peer: not installed ({roboplan_peer.IMPORT_ERROR}); "
              "`pip install roboplan` to compare with it - running ours and OMPL only")
    # The compiled kernels load from numba's disk cache on their first call (0.1-0.3 s in
    # all, once per process: `benchmarks/cold_start.py` measures that first plan); loaded
    # here, so the first query of the first robot times planning, as every later one does.
    from assistant.warmup.steps import warm_up

    warm_s = warm_up()
    print(f"kernels loaded in {warm_s:.2f} s (once per process, before any timing)")
    t0 = time.perf_counter()
    per = {name: run_robot(name, n_cells, n_queries, args.seed, 5.0 if args.quick else 10.0)
           for name in args.robots.split(",")}
    judged = {n: met(r) for n, r in per.items()}
    for n, (_, problems) in judged.items():
        for p in problems:
            print(f"{n:6s} {p}")
    figures = {"benchmark": "arms", "quick": bool(args.quick), "robots": per,
               "vamp_panda_median_s": VAMP_PANDA_MEDIAN_S, "targets": TARGETS,
               "met": {n: m for n, (m, _) in judged.items()},
               "problems": {n: p for n, (_, p) in judged.items() if p},
               "wall_s": time.perf_counter() - t0, "kernel_warm_up_s": warm_s}
    sys.stdout.write(json.dumps(figures, sort_keys=True, default=float) + "\n")
    sys.stdout.flush()
    os._exit(0)  # the ompl wheel reports "leaked" references at exit (see planning.py)


if __name__ == "__main__":
    main()
