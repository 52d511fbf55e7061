"""Which of `arms.py`'s targets a robot met: a criterion measured over nothing is not met.

A robot whose cells gave no valid query (no pair of collision-free taught postures) has no
success rate and no query times: "0 of 0 >= 0 of 0" is not a pass. Such a robot fails every
criterion about queries and is reported as "no queries"; world-model criteria (build time,
memory) still count, they were measured. Kept apart from `arms.py` (which puts benchmarks/
on sys.path and imports the planners) so the tests can check the rule on its own.
"""

from __future__ import annotations

import math

#: What each target asks (the benchmark's final JSON line repeats them).
TARGETS = {"world_build_s": "<= 10", "world_peak_mb": "<= 1536", "success_vs_ompl": ">= 1.0",
           "median_query_s": "<= 0.05", "replan_median_s": "<= 0.1",
           "min_clearance_mm": ">= 10 where a peer's path shows the cell allows it"}


def _le(x: float, bound: float) -> bool:
    """x <= bound for a measured x; NaN (nothing measured) is not met."""
    return not math.isnan(x) and x <= bound


def met(r: dict) -> tuple[dict[str, bool], list[str]]:
    """({criterion: met}, problems) for one robot's figures (`arms.run_robot`)."""
    queries = int(r.get("queries", 0))
    problems = [] if queries else ["no queries: the cells gave no valid query, so nothing "
                                   "about planning was measured"]
    ours = r["ours"]
    out = {"queries": queries > 0,
           "world_build_s": _le(r["world_build_s"], 10.0),
           "world_peak_mb": _le(r["world_peak_mb"], 1536.0),
           "success_vs_ompl": queries > 0 and ours["success"]
           >= r["ompl_rrtconnect_simplified"]["success"],
           "median_query_s": queries > 0 and _le(ours["median_query_s"], 0.05),
           "replan_median_s": queries > 0 and _le(ours["replan_median_s"], 0.1)}
    if r["roboplan"].get("installed"):
        out["success_vs_roboplan"] = queries > 0 and ours["success"] >= r["roboplan"]["success"]
    return out, problems
