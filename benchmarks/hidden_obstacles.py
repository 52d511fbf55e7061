"""Collision! on any arm: the learn-and-re-plan loop on seeded cells, per arm.

For each arm (the UR3/5/10, the Panda and Unitree Z1 of example-robot-data at their own
limits; the KUKA, ABB and FANUC arms of the robot catalogue), `--cells` seeded cells: a
table, a wall between two taught poses left and right of the arm, the poses tool-down at
45-65 % of the reach. The session plans the mission (start -> goal); a box of 30-80 mm is
then hidden where the planned transfer's TCP runs farthest from both ends, among the points
where it does not touch the arm where it stands or at a taught pose (only the simulated
robot knows it; if the start posture touches the wall the arm first moves to a free
posture, as the operator would; a pose whose every posture puts the arm in the table is
taught 50 or 100 mm higher), and the mission is executed headless: the simulated robot meets
the box, reports the contact (the self-reporting robot of scripts, standing in for the
operator's Collision!), the session learns and re-plans, until the goal or a reason. Every
run is bounded by the session's budgets and by `--budget-s` of wall time (a run over it
counts as not ending).

A cell whose first plan fails (the arm cannot reach both poses round the wall) is reported
as `unplannable` and counts toward neither side; an arm with no plannable cell fails every
criterion ("nothing is no pass").

    python benchmarks/hidden_obstacles.py [--cells 10] [--arms ur5,kuka] [--budget-s 120]

Criteria (issue 56): >= 95 % of plannable cases reach the goal, every case ends within
`--budget-s`, median re-plan inside a run <= 1 s - over all cases (`all`, the issue's
wording) and, stricter, for every arm on its own (`..._every_arm_...`). The last line is
one JSON object.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: arm key -> (example-robot-data URDF or catalogue key, tool link)
ARMS: dict[str, tuple[str, str]] = {
    "ur3": ("example-robot-data/robots/ur_description/urdf/ur3_robot.urdf", "tool0"),
    "ur5": ("example-robot-data/robots/ur_description/urdf/ur5_robot.urdf", "tool0"),
    "ur10": ("example-robot-data/robots/ur_description/urdf/ur10_robot.urdf", "tool0"),
    "panda": ("example-robot-data/robots/panda_description/urdf/panda.urdf", "panda_hand"),
    "z1": ("example-robot-data/robots/z1_description/urdf/z1.urdf", "link06"),
    "kuka": ("catalog:kuka_kr6_r900_sixx", "tool0"),
    "abb": ("catalog:abb_irb1200_5_09", "tool0"),
    "fanuc": ("catalog:fanuc_lrmate200id", "tool0"),
}


def _spec(arm: str) -> Any:
    from assistant.robots.catalog import RobotSpec, installed_robot_urdf

    where, tool = ARMS[arm]
    if where.startswith("catalog:"):
        return RobotSpec(kind=where.split(":", 1)[1])
    urdf, share = installed_robot_urdf(where)
    return RobotSpec(kind="urdf", urdf_path=str(urdf), package_dirs=(str(share),),
                     tool_link=tool)


def _reach(robot: Any) -> float:
    rng = np.random.default_rng(0)
    Q = rng.uniform(robot.limits.lower, robot.limits.upper, (400, robot.dof))
    return float(max(np.linalg.norm(robot.fk(q)[:2, 3]) for q in Q))


def _layout(seed: int, reach: float) -> tuple[float, float, float, float]:
    """Seed's (pose radius, pose height, half the angle between the poses, wall height)."""
    rng = np.random.default_rng(seed)
    r = reach * rng.uniform(0.45, 0.65)
    z = reach * rng.uniform(0.12, 0.25)
    half = rng.uniform(0.35, 0.6)  # half the angle between the poses (rad)
    return r, z, half, z * rng.uniform(0.6, 1.1)


def _cell(s: Any, seed: int) -> bool:
    """Table, wall, start and goal for seed; False if the arm cannot hold both poses."""
    reach = _reach(s.robot)
    r, z, half, wall_h = _layout(seed, reach)
    s.next()  # set up -> import CAD
    s.add_primitive("box", (2.0 * reach, 2.0 * reach, 0.02), name="table",
                    T_world_object=_T((0.0, 0.0, -0.011)))
    s.add_primitive("box", (reach * 0.3, 0.02, wall_h), name="wall",
                    T_world_object=_T((r, 0.0, wall_h / 2.0)))
    s.goto("teach.locations")
    return _teach_poses(s, seed, 0.0)


def _teach_poses(s: Any, seed: int, lift: float) -> bool:
    """Teach A and B (`lift` m above the seed's height); False if the arm cannot hold one."""
    from assistant.robots.model import UnreachableError
    from assistant.session.types import SessionError

    r, z, half, _ = _layout(seed, _reach(s.robot))
    try:
        for name, sign in (("A", 1.0), ("B", -1.0)):
            a = sign * half
            T = _T((r * np.cos(a), r * np.sin(a), z + lift))
            for R in _orientations(a):  # tool down, else tilted out, else level: what the
                T[:3, :3] = R           # operator would teach where the wrist allows it
                try:
                    s.teach(name, T)
                    break
                except UnreachableError:
                    continue
            else:
                return False
        s.set_start("A")
        s.set_goal("B")
    except (SessionError, UnreachableError):
        return False
    return True


#: Heights (m) a pose is raised by, in turn, when every posture that holds it puts the arm
#: in the table (the Z1's level wrist at 0.1 m: its flange housing reaches below the TCP);
#: the operator would teach it higher.
LIFTS = (0.05, 0.10)


def _orientations(azimuth: float) -> list[np.ndarray]:
    """Tool z pointing down, then 45 deg out from the arm's base, then level and out (a
    smaller arm's wrist - the Z1's joint 4 spans +-87 deg - reaches no tool-down pose at
    half its reach)."""
    out = [np.diag([1.0, -1.0, -1.0])]
    for tilt in (np.pi / 4, np.pi / 2):
        z = np.array([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth),
                      -np.cos(tilt)])
        y = np.array([-np.sin(azimuth), np.cos(azimuth), 0.0])
        x = np.cross(y, z)
        out.append(np.column_stack([x, y, z]))
    return out


def _T(p: tuple[float, float, float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _hidden_at(s: Any, size: float) -> np.ndarray | None:
    """World TCP of the transfer farthest from its two ends (middle half) where a box of
    `size` does not touch the arm where it stands nor at the plan's taught postures: a box
    the arm already stands in is no hidden obstacle on the transfer (the operator would see
    the contact before the run, or when teaching)."""
    from assistant.collision.checker import CollisionChecker
    from assistant.collision.reports import Obstacle
    from assistant.robots.model import CollisionShape, ShapeKind
    from assistant.transforms import inv_T

    Tw = s.T_world_base()
    cands: list[tuple[float, np.ndarray]] = []
    for m in s.trajectory.motions:
        if "->" not in m.label or m.joint_path is None or len(m.joint_path) < 3:
            continue
        P = np.array([(Tw @ s.robot.fk(q))[:3, 3] for q in m.joint_path])
        ends = P[[0, -1]]
        mid = P[len(P) // 4: 3 * len(P) // 4 + 1]
        d = np.linalg.norm(mid[:, None] - ends[None], axis=2).min(axis=1)
        cands += [(float(d[i]), mid[i]) for i in np.argsort(-d)[:40]]
    # where the arm stands, and the taught postures (a box the arm touches at A or B would
    # have been seen when they were taught; no run could reach such a goal)
    moves = [m for m in s.trajectory.motions if "->" in m.label and m.joint_path is not None
             and len(m.joint_path)]
    stands = [s.current_joints()] + ([moves[0].joint_path[0], moves[-1].joint_path[-1]]
                                     if moves else [])
    for _, p in sorted(cands, key=lambda c: -c[0]):
        T = np.eye(4)
        T[:3, 3] = p
        box = Obstacle("hidden", inv_T(Tw) @ T, (CollisionShape(ShapeKind.BOX, (size,) * 3),))
        checker = CollisionChecker(s.robot, [box])
        if all(checker.check(q).valid for q in stands):
            return p
    return None


def run_case(arm: str, seed: int) -> dict:
    from assistant.session import Session, SessionError
    from assistant.session.types import HiddenObstacle
    from assistant.transforms import pose_from_mm_deg

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        s = Session(folder=Path(tmp) / "s")
        try:
            s.choose_robot(_spec(arm))
            if not _cell(s, seed):
                return {"arm": arm, "seed": seed, "outcome": "unplannable",
                        "why": "a pose out of reach"}
            first = _world_and_plan(s)
            for lift in LIFTS:
                if first.get("ok") or "every arm configuration collides" not in \
                        first.get("reason", ""):
                    break
                s.goto("teach.locations")
                if not _teach_poses(s, seed, lift):
                    break
                first = _world_and_plan(s)
            if not first.get("ok"):
                return {"arm": arm, "seed": seed, "outcome": "unplannable",
                        "why": first.get("reason", "")[:120]}
            size = float(np.random.default_rng(seed + 1).uniform(0.03, 0.08))
            p = _hidden_at(s, size)
            if p is None:
                return {"arm": arm, "seed": seed, "outcome": "unplannable",
                        "why": "no transfer"}
            s.set_hidden_obstacles([HiddenObstacle(
                "hidden", "box", (size,) * 3, pose_from_mm_deg([*(p * 1000.0), 0, 0, 0]))])
            try:
                rep = s.execute()
                ok, why = bool(rep.get("ok")), str(rep.get("reason", ""))
            except SessionError as exc:  # the run ended without the goal, with its reason
                ok, why = False, str(exc)
            return {"arm": arm, "seed": seed, "outcome": "goal" if ok else "failed",
                    "why": why[:160], "indications": s.counters.collision_indications,
                    "replans_s": list(s.counters.replan_times_s),
                    "wall_s": time.perf_counter() - t0, "box_mm": size * 1000.0}
        except Exception as exc:  # noqa: BLE001 - a case that raises is a failed case
            return {"arm": arm, "seed": seed, "outcome": "failed",
                    "why": f"{type(exc).__name__}: {exc}"[:160],
                    "wall_s": time.perf_counter() - t0}
        finally:
            s.close()


def _world_and_plan(s: Any) -> dict:
    """Build the world and plan the mission, as the operator's explore and plan steps."""
    from assistant.session import SessionError

    s.goto("explore")
    s.build_world()
    s.goto("plan")
    if s.start_posture_links():  # as the operator does: Move to a free posture
        s.move_to_free_posture()
    try:
        return s.plan()
    except SessionError as exc:  # e.g. a pose whose every posture touches the table
        return {"ok": False, "reason": str(exc)}


def _case_in_child(arm: str, seed: int, budget_s: float) -> dict:
    """One case in its own process, killed at the budget (a run that does not end)."""
    ctx = mp.get_context("spawn")
    with ctx.Pool(1) as pool:
        res = pool.apply_async(run_case, (arm, seed))
        try:
            return res.get(budget_s)
        except mp.TimeoutError:
            pool.terminate()
            return {"arm": arm, "seed": seed, "outcome": "did_not_end",
                    "why": f"still running after {budget_s:.0f} s", "wall_s": budget_s}


def summarise(cases: list[dict], budget_s: float) -> dict:
    out: dict[str, Any] = {}
    for arm in sorted({c["arm"] for c in cases}):
        mine = [c for c in cases if c["arm"] == arm]
        valid = [c for c in mine if c["outcome"] != "unplannable"]
        reached = [c for c in valid if c["outcome"] == "goal"]
        replans = [t for c in valid for t in c.get("replans_s", [])]
        out[arm] = {
            "cases": len(mine), "plannable": len(valid), "reached": len(reached),
            "success": len(reached) / len(valid) if valid else None,
            "ended_in_budget": all(c["outcome"] != "did_not_end" for c in valid)
            if valid else None,
            "indications_median": statistics.median([c.get("indications", 0) for c in valid])
            if valid else None,
            "replan_median_s": statistics.median(replans) if replans else None,
            "replan_max_s": max(replans) if replans else None,
            "replans": len(replans),
            "wall_max_s": max((c.get("wall_s", 0.0) for c in valid), default=None),
            "failures": [f"seed {c['seed']}: {c['outcome']} - {c['why']}" for c in valid
                         if c["outcome"] != "goal"],
        }
    arms = list(out.values())
    valid = [c for c in cases if c["outcome"] != "unplannable"]
    replans = [t for c in valid for t in c.get("replans_s", [])]
    out["all"] = {
        "plannable": len(valid), "reached": sum(c["outcome"] == "goal" for c in valid),
        "success": sum(c["outcome"] == "goal" for c in valid) / len(valid) if valid else None,
        "replan_median_s": statistics.median(replans) if replans else None,
    }
    out["criteria"] = {
        # the wording: of all cases; and the stricter reading, every arm on its own
        "success_ge_95pct": bool(valid) and out["all"]["success"] >= 0.95 and
        all(a["success"] is not None for a in arms),
        "success_every_arm_ge_95pct": bool(arms) and all(a["success"] is not None and
                                                         a["success"] >= 0.95 for a in arms),
        "every_case_ends": bool(arms) and all(a["ended_in_budget"] for a in arms),
        "replan_median_le_1s": bool(replans) and out["all"]["replan_median_s"] <= 1.0,
        "replan_median_every_arm_le_1s": bool(arms) and all(
            a["replan_median_s"] is not None and a["replan_median_s"] <= 1.0 for a in arms),
        "budget_s": budget_s,
    }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=10)
    ap.add_argument("--arms", default=",".join(ARMS))
    ap.add_argument("--budget-s", type=float, default=120.0)
    args = ap.parse_args()
    arms = [a.strip() for a in args.arms.split(",") if a.strip()]
    unknown = set(arms) - set(ARMS)
    if unknown:
        ap.error(f"unknown arms {sorted(unknown)}; known: {', '.join(ARMS)}")
    cases = []
    for arm in arms:
        for seed in range(args.cells):
            c = _case_in_child(arm, seed, args.budget_s)
            print(f"{arm} seed {seed}: {c['outcome']} ({c.get('wall_s', 0):.1f} s, "
                  f"{c.get('indications', '-')} indications) {c.get('why', '')}", flush=True)
            cases.append(c)
    print(json.dumps(summarise(cases, args.budget_s)))


if __name__ == "__main__":
    main()
