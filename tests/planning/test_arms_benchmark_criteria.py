"""benchmarks/arms.py judges its targets with `arms_criteria.met`: a robot whose cells gave
no valid query has measured nothing about planning, so it fails those criteria and is
reported as "no queries" (it used to pass success_vs_ompl as 0 >= 0)."""

from __future__ import annotations

from bench_modules import load_benchmark

NAN = float("nan")


def figures(queries: int, ours_success: float, ompl_success: float, median: float,
            replan: float, roboplan: dict | None = None) -> dict:
    return {"queries": queries, "world_build_s": 4.0, "world_peak_mb": 300.0,
            "ours": {"success": ours_success, "median_query_s": median,
                     "replan_median_s": replan},
            "ompl_rrtconnect_simplified": {"success": ompl_success},
            "roboplan": roboplan or {"installed": False}}


def test_no_queries_is_a_failure_not_a_pass():
    met = load_benchmark("arms_criteria").met
    got, problems = met(figures(0, 0.0, 0.0, NAN, NAN,
                                {"installed": True, "success": 0.0}))
    assert got["queries"] is False and got["success_vs_ompl"] is False
    assert got["success_vs_roboplan"] is False
    assert got["median_query_s"] is False and got["replan_median_s"] is False
    assert got["world_build_s"] and got["world_peak_mb"]  # those were measured
    assert problems and problems[0].startswith("no queries")


def test_measured_queries_are_judged_on_their_figures():
    met = load_benchmark("arms_criteria").met
    got, problems = met(figures(4, 1.0, 1.0, 0.03, 0.08))
    assert not problems and all(got.values())
    got, _ = met(figures(4, 0.75, 1.0, 0.2, NAN))
    assert got == {"queries": True, "world_build_s": True, "world_peak_mb": True,
                   "success_vs_ompl": False, "median_query_s": False, "replan_median_s": False}
