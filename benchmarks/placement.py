"""Placement study: 200 candidate robot bases on the thesis cell and the pick-and-place cell,
run in one process, in a pool of 2 local worker processes, and on a local Ray instance with
2 workers - wall time, speed-ups, agreement of the results, and where the time goes; the best
candidate's score against the sample cell's own placement.

    python benchmarks/placement.py [--quick] [--no-ray]

Candidates: x -200..250 mm x y -100..100 mm every 50 mm, 4 yaws (0, 90, 180, -90 deg) = 200,
the sample's own base (0, 0, 0) among them; the 16 best screened ones (and the sample's own
placement) are planned fully. Ray's start (`ray.init` and its workers' first import and
store load) is reported apart: a cluster is normally up already. The last line is one JSON
object with the figures. On a machine shared with other work the wall times say little;
`cpu_speedup_2_vs_1` (the one process's task CPU over the busiest worker's) is what two idle
cores would give, scheduling aside.
"""

from __future__ import annotations

import argparse
import json
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

from assistant.session import Session  # noqa: E402
from assistant.study import Region, StudySettings, run_study  # noqa: E402
from assistant.study.engines import Engine  # noqa: E402

CELLS = ("thesis_rv2aj", "pick_and_place")


def _region(quick: bool) -> Region:
    if quick:
        return Region(-0.1, -0.05, 0.15, 0.05, 0.05, 2)  # 6 x 3 x 2 = 36
    return Region(-0.2, -0.1, 0.25, 0.1, 0.05, 4)  # 10 x 5 x 4 = 200


def _agreement(a, b) -> dict:
    """Same statuses, ranks and reasons; the largest cost difference (m)."""
    ra, rb = a.ranked(), b.ranked()
    same = [(r.candidate.index, r.status, r.rank, r.reason) for r in ra] == \
        [(r.candidate.index, r.status, r.rank, r.reason) for r in rb]
    dc = max((abs(x.cost - y.cost) for x, y in zip(ra, rb, strict=True)
              if x.cost is not None and y.cost is not None), default=0.0)
    return {"same_ranking": same, "max_cost_diff_m": dc}


def _summary(res, wall: float) -> dict:
    t = res.timings
    return {"wall_s": round(wall, 2), "screen_s": round(t["screen_s"], 2),
            "plan_s": round(t["plan_s"], 2), "shared_s": round(t["shared_s"], 2),
            "screen_cpu_s": round(t["screen_cpu_s"], 2), "plan_cpu_s": round(t["plan_cpu_s"], 2),
            "world_build_task_s": round(t["world_build_tasks_s"], 2),
            "mission_plan_task_s": round(t["plan_tasks_s"], 2),
            "task_cpu_s": round(t["task_cpu_s"], 2),
            "busiest_process_cpu_s": round(t["busiest_process_cpu_s"], 2), **res.counts}


def _run(problem, region, settings, engine: Engine | None = None):
    t0 = time.perf_counter()
    res = run_study(problem, region, settings, engine=engine)
    return res, time.perf_counter() - t0


def bench_cell(name: str, region: Region, plan_top: int, ray_engine) -> dict:
    session = Session.from_sample(name, None)
    problem = session.study_problem()
    out: dict = {"cell": name, "candidates": region.count()}
    one, w1 = _run(problem, region, StudySettings(plan_top=plan_top, engine="inline"))
    two, w2 = _run(problem, region, StudySettings(plan_top=plan_top, workers=2))
    out["one_process"] = _summary(one, w1)
    out["two_processes"] = _summary(two, w2)
    out["speedup_2_vs_1"] = round(w1 / w2, 2)
    # On a loaded machine wall time says little: the CPU of the busiest worker against the
    # one process's total is the speed-up two idle cores would give (scheduling aside).
    out["cpu_speedup_2_vs_1"] = round(one.timings["task_cpu_s"] /
                                      max(1e-9, two.timings["busiest_process_cpu_s"]), 2)
    out["agree_1_vs_2"] = _agreement(one, two)
    if ray_engine is not None:
        # warm the Ray workers on this problem (import, store load), then measure
        t0 = time.perf_counter()
        run_study(problem, Region(0.0, 0.0, 0.0, 0.0, 0.05, 2),
                  StudySettings(plan_top=0, include_current=False), engine=ray_engine)
        out["ray_warmup_s"] = round(time.perf_counter() - t0, 2)
        ray, w3 = _run(problem, region, StudySettings(plan_top=plan_top, engine="ray"),
                       ray_engine)
        out["ray_2_workers"] = _summary(ray, w3)
        out["ray_vs_local_pool"] = round(w3 / w2, 2)
        out["cpu_ray_vs_local_pool"] = round(ray.timings["busiest_process_cpu_s"] /
                                             max(1e-9, two.timings["busiest_process_cpu_s"]), 2)
        out["agree_ray_vs_1"] = _agreement(one, ray)
    best, cur = two.best(), two.current
    out["best"] = None if best is None else {**best.candidate.to_json(),
                                             "cost_m": round(best.cost, 4),
                                             "min_clearance_mm": _mm(best.plan.min_clearance)}
    out["own_placement"] = None if cur is None else {
        **cur.candidate.to_json(), "status": cur.status, "reason": cur.reason,
        "cost_m": None if cur.cost is None else round(cur.cost, 4),
        "min_clearance_mm": None if cur.plan is None or not cur.plan.ok
        else _mm(cur.plan.min_clearance)}
    if best is not None and cur is not None and cur.cost is not None:
        out["best_vs_own_cost"] = round(best.cost / cur.cost, 3)
    session.close()
    return out


def _mm(v: float | None) -> float | None:
    return None if v is None else round(v * 1000, 1)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--no-ray", action="store_true")
    ap.add_argument("--plan-top", type=int, default=None)
    args = ap.parse_args()
    region = _region(args.quick)
    plan_top = args.plan_top if args.plan_top is not None else (4 if args.quick else 16)
    ray_engine, ray_note = None, ""
    t_ray = None
    if not args.no_ray:
        try:
            from assistant.study.engines import RayEngine

            t0 = time.perf_counter()
            ray_engine = RayEngine("local", 2)
            t_ray = time.perf_counter() - t0
        except RuntimeError as exc:
            ray_note = str(exc)
    figures: dict = {"plan_top": plan_top, "cores": os.cpu_count(),
                     "load_avg_at_start": round(os.getloadavg()[0], 2), "cells": []}
    try:
        for name in CELLS:
            res = bench_cell(name, region, plan_top, ray_engine)
            figures["cells"].append(res)
            print(f"{name}: {res['candidates']} candidates - 1 process "
                  f"{res['one_process']['wall_s']} s, 2 processes "
                  f"{res['two_processes']['wall_s']} s (x{res['speedup_2_vs_1']}, CPU "
                  f"x{res['cpu_speedup_2_vs_1']})"
                  + (f", Ray 2 workers {res['ray_2_workers']['wall_s']} s"
                     if "ray_2_workers" in res else "")
                  + f"; best {res['best']} vs own {res['own_placement']}", flush=True)
    finally:
        if ray_engine is not None:
            ray_engine.close()
    figures["ray_init_s"] = None if t_ray is None else round(t_ray, 2)
    if ray_note:
        figures["ray"] = ray_note
    figures["load_avg_at_end"] = round(os.getloadavg()[0], 2)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
