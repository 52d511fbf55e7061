"""Robot-vs-cell collision checks per second: our batched exact checker vs naive per-call FCL.

Same robot, same obstacles, same FCL narrow phase, one process. The naive peer poses every
link shape and calls `fcl.collide` against every obstacle and self pair for each configuration
(what a straightforward python-fcl integration does). Agreement must be 100 %.

    python benchmarks/collision.py [--quick]

The last line is one JSON object with the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import Obstacle  # noqa: E402
from assistant.robots.model import CollisionShape, ShapeKind, Tool  # noqa: E402
from assistant.robots.rv2aj import RV2AJ, RV2AJConfig  # noqa: E402
from assistant.transforms import make_T  # noqa: E402


def thesis_like_obstacles() -> list[Obstacle]:
    """The thesis scenario's known obstacles O1, O2 and the table, as boxes."""

    def box(name, c, s):
        return Obstacle(name, make_T(p=c), (CollisionShape(ShapeKind.BOX, tuple(s)),))

    return [
        box("O1", [0.28, -0.12, 0.10], [0.10, 0.12, 0.20]),
        box("O2", [0.22, 0.18, 0.06], [0.16, 0.08, 0.12]),
        box("table", [0.0, 0.0, -0.011], [1.5, 1.5, 0.02]),
    ]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    n = 5_000 if args.quick else 50_000
    robot = RV2AJ(RV2AJConfig(tool=Tool.straight(0.1)))
    t0 = time.perf_counter()
    chk = CollisionChecker(robot, thesis_like_obstacles())
    build_s = time.perf_counter() - t0
    rng = np.random.default_rng(1)
    Q = rng.uniform(robot.limits.lower, robot.limits.upper, size=(n, robot.dof))

    chk.in_collision_batch(Q[:100])  # warm up
    t0 = time.perf_counter()
    fast = chk.in_collision_batch(Q)
    t_fast = time.perf_counter() - t0

    n_single = min(n, 2_000)
    t0 = time.perf_counter()
    single = np.array([not chk.is_valid(q) for q in Q[:n_single]])
    t_single = time.perf_counter() - t0

    t0 = time.perf_counter()
    naive = np.array([chk.in_collision_naive(q) for q in Q])
    t_naive = time.perf_counter() - t0

    agree = float(np.mean(fast == naive))
    agree_single = float(np.mean(single == naive[:n_single]))
    figures = {
        "configurations": n,
        "colliding_fraction": round(float(naive.mean()), 4),
        "checker_build_s": round(build_s, 3),
        "batch_checks_per_s": round(n / t_fast),
        "single_call_checks_per_s": round(n_single / t_single),
        "naive_fcl_checks_per_s": round(n / t_naive),
        "agreement_batch": agree,
        "agreement_single": agree_single,
        "ratio_batch_vs_naive": round((n / t_fast) / (n / t_naive), 2),
        "target_checks_per_s": 20_000,
    }
    print(f"{'method':<28}{'checks/s':>12}")
    print(f"{'batched broad phase + FCL':<28}{figures['batch_checks_per_s']:>12}")
    print(f"{'single is_valid calls':<28}{figures['single_call_checks_per_s']:>12}")
    print(f"{'naive per-call FCL':<28}{figures['naive_fcl_checks_per_s']:>12}")
    print(f"agreement with brute force: {agree * 100:.2f} % (batch), "
          f"{agree_single * 100:.2f} % (single)")
    print(json.dumps(figures))
    if agree < 1.0 or agree_single < 1.0:
        raise SystemExit("disagreement with brute-force FCL")


if __name__ == "__main__":
    main()
